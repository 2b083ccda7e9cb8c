"""What the master drives: an FMU through fmpy, or a Block called directly.

Both adapters offer the same small interface, so the master runs the very same
schedule on either; the direct route is the check that the FMI wrappers and the
SSP wiring are right (results equal to rounding) and the speed reference.
"""

from __future__ import annotations

import ctypes
import functools
import numbers
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence, Union

import numpy as np

from fmus.common.block import Block
from fmus.common.parameters import Value, exact_boolean, exact_integer, exact_string


class ComponentError(RuntimeError):
    """A component failed: the message names the component, the call, the time and the model's cause."""


def _real(value: object) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, str)):
        raise ValueError(f"{value!r} is not a number")
    return float(value)


#: what a parameter value of each FMI type may be: nothing is truncated or reinterpreted on the way in
#: (the same rules as the blocks' own check, fmus/common/parameters.py, so every route agrees)
_FMI_VALUE = {"Real": _real, "Integer": exact_integer, "Boolean": exact_boolean, "String": exact_string}


class FMUComponent:
    """An FMI 2.0 co-simulation FMU, through fmpy's FMU2Slave.

    The hot calls (set, get, doStep) go straight to the shared library's
    functions with prepared ctypes arrays; a status above fmi2Warning raises
    ComponentError carrying the message the model logged.
    """

    def __init__(self, name: str, fmu: Path, unzip_dir: Path) -> None:
        from fmpy import read_model_description
        from fmpy.fmi2 import (
            FMU2Slave,
            calloc,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
            free,
        )

        self.name = name
        self.messages: list[str] = []
        try:
            self.md = read_model_description(str(fmu))
        except Exception as err:
            raise ComponentError(f"{name}: cannot read FMU {fmu.name}: {err}") from None
        if self.md.coSimulation is None:
            raise ComponentError(f"{name}: {fmu.name} is not a co-simulation FMU")
        self.variables = {v.name: v for v in self.md.modelVariables}
        self.parameter_names = frozenset(v.name for v in self.md.modelVariables if v.causality == "parameter")
        #: the unit each parameter declares (modelDescription), for the unit check of parameter sets
        self.parameter_units = {
            v.name: v.unit or (v.declaredType.unit if v.declaredType else None) or ""
            for v in self.md.modelVariables
            if v.causality == "parameter"
        }
        self._slave = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=str(unzip_dir),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )

        def logger(_env, _instance, status, category, message):
            text = (message or b"").decode(errors="replace")
            self.messages.append(f"[{(category or b'').decode(errors='replace')}] {text}" if category else text)

        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._call("instantiate", lambda: self._slave.instantiate(callbacks=self._callbacks, loggingOn=True))
        self._component = self._slave.component
        self.feedthrough = feedthrough_of(self.md)

    # -- helpers -----------------------------------------------------------------
    def _call(self, what: str, func: Callable, t: float | None = None):
        try:
            return func()
        except Exception as err:
            raise self._error(what, t, err) from None

    def _error(self, what: str, t: float | None, err: object = "") -> ComponentError:
        """The model's own logged error is the cause; pythonfmu's generic 'Fatal py exception' is not."""
        ours = [m for m in self.messages if m.startswith(("[logStatusError]", "[logStatusFatal]"))]
        if ours:  # the model's message already says when (doStep at t=...) and why
            return ComponentError(f"{self.name}: {ours[-1].split('] ', 1)[1]}")
        when = f" at t={t:.6g} s" if t is not None else ""
        cause = self.messages[-1] if self.messages else str(err)
        return ComponentError(f"{self.name}{when}: {what} failed: {cause}")

    def _refs(self, names: Sequence[str], causalities: tuple[str, ...]) -> list[int]:
        refs = []
        for name in names:
            var = self.variables.get(name)
            if var is None or var.causality not in causalities:
                have = sorted(v.name for v in self.md.modelVariables if v.causality in causalities)
                raise ComponentError(
                    f"{self.name}: no {'/'.join(causalities)} variable named '{name}'; it has: {', '.join(have)}"
                )
            refs.append(var.valueReference)
        return refs

    # -- interface -----------------------------------------------------------------
    def enter_initialization(self, start_time: float, stop_time: float, parameters: Mapping[str, Value]) -> None:
        self._call("setupExperiment", lambda: self._slave.setupExperiment(startTime=start_time, stopTime=stop_time))
        self._call("enterInitializationMode", self._slave.enterInitializationMode)
        for name, value in parameters.items():
            var = self.variables.get(name)
            if var is None or var.causality != "parameter":
                have = sorted(v.name for v in self.md.modelVariables if v.causality == "parameter")
                raise ComponentError(f"{self.name}: unknown parameter '{name}'; its parameters are: {', '.join(have)}")
            setter = {
                "Real": self._slave.setReal,
                "Integer": self._slave.setInteger,
                "Boolean": self._slave.setBoolean,
                "String": self._slave.setString,
            }[var.type]
            try:
                converted = _FMI_VALUE[var.type](value)
            except (TypeError, ValueError, OverflowError) as err:
                raise ComponentError(
                    f"{self.name}: parameter '{name}' = {value!r} is not a valid {var.type} ({err})"
                ) from None
            self._call(f"setting parameter {name}", functools.partial(setter, [var.valueReference], [converted]))

    def exit_initialization(self) -> None:
        logged = len(self.messages)
        self._call("exitInitializationMode", self._slave.exitInitializationMode)
        errors = [m for m in self.messages[logged:] if m.startswith("[logStatusError]")]
        if errors:  # the MAST FMUs log a failed start and refuse every step after it: stop here, with the cause
            raise ComponentError(f"{self.name}: {errors[-1].removeprefix('[logStatusError] ')}")

    def start_value(self, name: str) -> float:
        start = self.variables[name].start
        return float(start) if start is not None else 0.0

    #: pythonfmu FMUs: call set/get/doStep through prototypes that keep the GIL (their functions take it
    #: straight back to run Python) and, for set/get, convert nothing (prepared ctypes arguments):
    #: about 0.3 us less per call (docs/batch.md, benchmark). False: fmpy's prototypes for every FMU.
    fast_calls = True

    @property
    def runs_python(self) -> bool:
        """A pythonfmu FMU (its calls take the GIL to run Python), called through the fast prototypes."""
        return self.fast_calls and (self.md.generationTool or "").startswith("PythonFMU")

    def _hot(self, name: str, *argtypes):
        """The library function ``name`` for the hot loop, and how to pass the component pointer."""
        func = getattr(self._slave.dll, name)
        if not self.runs_python:
            return func, self._component
        proto = ctypes.PYFUNCTYPE(ctypes.c_int, *argtypes) if argtypes else ctypes.PYFUNCTYPE(ctypes.c_int)
        return proto(ctypes.cast(func, ctypes.c_void_p).value), ctypes.c_void_p(self._component)

    def c_functions(self) -> tuple[int, int, int, int]:
        """(instance, fmi2SetReal, fmi2GetReal, fmi2DoStep) as C addresses, for the compiled exchange loop."""
        dll = self._slave.dll
        return (
            self._component,
            *(
                ctypes.cast(getattr(dll, name), ctypes.c_void_p).value
                for name in ("fmi2SetReal", "fmi2GetReal", "fmi2DoStep")
            ),
        )

    def input_references(self, names: Sequence[str]) -> list[int]:
        return self._refs(names, ("input", "parameter"))

    def output_references(self, names: Sequence[str]) -> list[int]:
        return self._refs(names, ("output", "input", "parameter", "calculatedParameter", "local"))

    def setter(self, names: Sequence[str]) -> Callable[[Sequence[float]], None]:
        refs = self.input_references(names)
        n = len(refs)
        vr = (ctypes.c_uint * n)(*refs)
        buf = (ctypes.c_double * n)()
        (raw, comp), size = self._hot("fmi2SetReal"), ctypes.c_size_t(n)

        def set_values(values: Sequence[float]) -> None:
            buf[:] = values
            if raw(comp, vr, size, buf) > 1:
                raise self._error("setReal", None)

        return set_values

    def getter(self, names: Sequence[str]) -> Callable[[], list[float]]:
        refs = self.output_references(names)
        n = len(refs)
        vr = (ctypes.c_uint * n)(*refs)
        buf = (ctypes.c_double * n)()
        (raw, comp), size = self._hot("fmi2GetReal"), ctypes.c_size_t(n)

        def get_values() -> list[float]:
            if raw(comp, vr, size, buf) > 1:
                raise self._error("getReal", None)
            return buf[:]

        return get_values

    def stepper(self) -> Callable[[float, float], None]:
        raw, comp = self._hot("fmi2DoStep", ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int)

        def do_step(t: float, h: float) -> None:
            if raw(comp, t, h, 1) > 1:
                raise self._error("doStep", t)

        return do_step

    def reset(self) -> None:
        """Back to the instantiated state for another run (fmi2Reset): the same loaded library and instance.

        pythonfmu 0.7.0 answers fmi2Reset by creating a new Python slave object, so the parameters
        go back to the FMU's start values; the master sets them again in ``enter_initialization``.
        """
        self._call("terminate", self._slave.terminate)
        self._call("reset", self._slave.reset)
        self.messages.clear()

    def close(self) -> None:
        try:
            self._slave.terminate()
        except Exception:  # an instance that failed may refuse to terminate; free it all the same
            pass
        self._slave.freeInstance()


def feedthrough_of(md) -> dict[str, frozenset[str]]:
    """Direct feedthrough an FMI 2.0 modelDescription declares: output -> the inputs it depends on
    (ModelStructure/Outputs/Unknown ``dependencies``, those that are inputs).

    An output without a ``dependencies`` attribute counts as having none: the standard reads it as
    "depends on everything", but the usual co-simulation FMU (pythonfmu writes no attribute) changes
    its outputs only in doStep, and every co-simulation master treats it so."""
    out: dict[str, frozenset[str]] = {}
    for unknown in md.outputs:
        inputs = frozenset(v.name for v in unknown.dependencies or () if v.causality == "input")
        if inputs:
            out[unknown.variable.name] = inputs
    return out


class BlockComponent:
    """The same model object as inside the FMU, called directly (no FMI)."""

    def __init__(self, name: str, block_class: type[Block]) -> None:
        self.name = name
        self.block_class = block_class
        self.feedthrough = {out: frozenset(ins) for out, ins in block_class.FEEDTHROUGH.items() if ins}
        self.parameter_names = frozenset(p.name for p in block_class.PARAMETERS)
        self.parameter_units = {p.name: p.unit for p in block_class.PARAMETERS}
        self.block: Block | None = None
        self._in_init = False
        self._dirty = True
        self._t0 = 0.0

    @staticmethod
    def class_for(model_identifier: str, parameters: Optional[Mapping[str, Value]] = None) -> type[Block]:
        """The Block class an FMU of this project wraps (fmus/<package>/fmu.py), with the variables and parameters
        that ``parameters`` (the component's bound set) give it, as the FMU built with them has
        (``Block.for_parameters``: a 3-RPS's mechanism and controller take the 3-RPS's)."""
        from .build import block_class

        try:
            return block_class(model_identifier).for_parameters(parameters or {})
        except ValueError as err:
            raise ComponentError(str(err)) from None

    def _run(self, what: str, func: Callable, t: float | None = None):
        try:
            return func()
        except Exception as err:
            when = f" at t={t:.6g} s" if t is not None else ""
            raise ComponentError(f"{self.name}{when}: {what} failed: {type(err).__name__}: {err}") from None

    def enter_initialization(self, start_time: float, stop_time: float, parameters: Mapping[str, Value]) -> None:
        self._t0 = start_time
        self.block = self._run("parameters", lambda: self.block_class(parameters, name=self.name))
        self._in_init = True

    def exit_initialization(self) -> None:
        self._refresh()
        self._in_init = False

    def _refresh(self) -> None:
        if self._dirty:
            self._run("initialization", lambda: self.block.initialize(self._t0))
            self._dirty = False

    def start_value(self, name: str) -> float:
        return 0.0

    def _indices(self, names: Sequence[str]) -> list[int]:
        return [self._run("variable lookup", lambda n=n: self.block.index(n)) for n in names]

    def setter(self, names: Sequence[str]) -> Callable[[Sequence[float]], None]:
        idx = self._indices(names)
        values = self.block.values
        evaluate = self.block.evaluate if self.feedthrough else None

        def set_values(new: Sequence[float]) -> None:
            for i, v in zip(idx, new):
                values[i] = v
            if self._in_init:
                self._dirty = True
            elif evaluate is not None:  # the feedthrough outputs follow the inputs, as the FMU's do
                try:
                    evaluate()
                except Exception as err:
                    raise ComponentError(f"{self.name}: evaluating the outputs: {type(err).__name__}: {err}") from None

        return set_values

    def getter(self, names: Sequence[str]) -> Callable[[], list[float]]:
        idx = self._indices(names)
        values = self.block.values

        def get_values() -> list[float]:
            if self._in_init:
                self._tentative()
            return [values[i] for i in idx]

        return get_values

    def _tentative(self) -> None:
        """Outputs read during initialization, as the FMU's (slave.BlockWrapper._tentative_outputs): a failure may be
        an input the master has not settled yet (a 3-RPS's leg length 0 before its actuator's start is passed on), so
        the outputs keep their last values and ``exit_initialization`` decides with the settled inputs."""
        try:
            self._refresh()
        except ComponentError:
            pass

    def stepper(self) -> Callable[[float, float], None]:
        step = self.block.do_step

        def do_step(t: float, h: float) -> None:
            try:
                step(t, h)
            except Exception as err:
                raise ComponentError(f"{self.name}: doStep at t={t:.6g} s: {type(err).__name__}: {err}") from None

        return do_step

    def reset(self) -> None:
        """Nothing to keep: ``enter_initialization`` builds a new block for every run."""
        self.block = None

    def close(self) -> None:
        self.block = None


def fmu_variables(fmu: Union[str, Path]) -> list[str]:
    """The names of an FMU's variables (its modelDescription's, checked as ``fmu_parameters`` checks it)."""
    from fmpy import read_model_description

    from .ssp import check_archive

    check_archive(fmu)
    return [v.name for v in read_model_description(str(fmu)).modelVariables]


def fmu_parameters(fmu: Union[str, Path]) -> dict[str, Value]:
    """Default (start) values of an FMU's parameters, typed."""
    from fmpy import read_model_description

    from .ssp import check_archive

    check_archive(fmu)  # a file the user gave: no zip bomb in its modelDescription.xml
    md = read_model_description(str(fmu))
    convert = {
        "Real": float,
        "Integer": int,
        "Enumeration": int,
        "String": str,
        "Boolean": lambda s: str(s).strip().lower() in ("true", "1"),
    }
    out: dict[str, Value] = {}
    for v in md.modelVariables:
        if v.causality == "parameter" and v.start is not None:
            out[v.name] = convert.get(v.type, str)(v.start)
    return out
