"""What the FMI 2.0 and FMI 3.0 wrappers of a :class:`Block` share (``fmi.py``: pythonfmu, ``fmi3.py``: pythonfmu3).

This module imports neither pythonfmu nor pythonfmu3: an FMU bundles only the one it uses.

Value references: 0..n_in-1 are the block's inputs, n_in..n_in+n_out-1 its
outputs (both straight onto ``Block.values``), then the parameters (FMI 3.0
adds the independent variable ``time`` last). Parameter start values come from
``resources/parameters.json``, written by ``mast build`` from the SSP parameter
sets, so the values live in one place (the .ssv files).

Behaviour hosts rely on:
- parameters are validated when the block is built, at the latest when
  leaving initialization mode: a bad value (or a model that cannot start) is
  logged there with status Error, naming the parameter and the expected
  range, and from then on every doStep returns Discard with that cause.
  exitInitializationMode itself returns OK: pythonfmu can only turn a Python
  exception into Fatal, and libcosim aborts the whole process when a
  component fails exitInitializationMode; a refused step every host handles;
- in initialization mode outputs follow the inputs (the host may iterate to
  a consistent initial point), so get after set recomputes them; while the
  host iterates, inputs that are not consistent yet only log a warning and
  leave the outputs as they were;
- a model failure during doStep is logged (class and message, instance and
  time) and doStep returns Discard: the instance stays usable;
- get/set FMU state: a deep snapshot of the block (``Block.get_state``), so a
  host can roll back and recompute;
- the FMI state machine (FMI 2.0 section 4.3, the same in 3.0 for co-simulation):
  each call is checked against the instance's state (instantiated,
  initialization mode, step mode, terminated), and a set against the
  variable's causality and variability: a fixed parameter only before
  exitInitializationMode, an input until terminate, an output never, an
  unknown value reference, a value of the wrong type or another FMU's state
  never. An illegal call is logged (status Error, naming the call, the state
  or the variable), refused and changes nothing: the call returns fmi2Error
  and the instance stays usable. pythonfmu's (and pythonfmu3's) C layer
  turns every Python exception into Fatal; ``mast build`` puts a small C front
  in front of it (``pythonfmu_shim.c``: FMI 2.0 and 3.0 on Linux) that returns
  fmi2Error (fmi3Error) when the model logged the failed call with status
  Error. Without that front (other platforms, a build without a C compiler)
  the call says Fatal and the instance treats it as one. A failure nobody
  foresaw (an exception other than IllegalCall) is logged with status Fatal
  and the call says Fatal; an instance that answered Fatal refuses every
  later call with Fatal: only reset (a new slave object, in pythonfmu's C
  layer) and freeInstance remain. More lenient than the standard, as hosts need: get
  is allowed in every state, and doStep after a Discard tries again (and is
  refused again while the cause stays);
- a time argument that is not finite and >= 0 (doStep's, setupExperiment's) and a doStep longer than
  ``_largest_step`` are illegal calls (fmi2Error), in the native wrapper's words (``check_time``);
- several instances, and instances that failed, come and go in one process
  (``_survive_pythonfmu_cleanup``, ``_drop_repeated_path``).
"""

from __future__ import annotations

import atexit
import ctypes
import functools
import glob
import json
import math
import os
import struct
import sys
import types
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, List, Mapping, Optional, Union

from .block import Block

PARAMETERS_FILE = "parameters.json"

_GLOBALS_REFERENCES: list = []


def keep_alive(namespace: dict) -> None:
    """Hold a reference to an FMU entry script's globals (see the script mast build writes)."""
    _GLOBALS_REFERENCES.append(namespace)


def load_defaults(resources: Optional[str]) -> dict:
    """Parameter start values baked into the FMU by the build (empty if absent)."""
    if not resources:
        return {}
    path = os.path.join(resources, PARAMETERS_FILE)
    if not os.path.exists(path):
        return {}
    with open(path, encoding="utf-8") as handle:
        return json.load(handle)


@dataclass(frozen=True)
class FmiVocabulary:
    """The names an FMI version's Python package gives to what both versions have."""

    kinds: Mapping[
        type, Callable
    ]  # Python type of a value -> variable class (Real, Integer, ... / Float64, Int32, ...)
    causality: Any  # enumerations: Fmi2Causality / Fmi3Causality, ...
    variability: Any
    initial: Any
    status: Any
    message_is_format: bool  # the host's logger expands the message as a printf format (FMI 2.0, not 3.0)
    set_real: str  # the call that sets floating-point values: setReal / setFloat64
    default_experiment: Callable  # DefaultExperiment(start_time, stop_time, step_size) of the version's package


# the states of an instance (FMI 2.0 co-simulation; FMI 3.0's step mode is "step mode" here too)
INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED = "instantiated", "initialization mode", "step mode", "terminated"
ALIVE = (INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED)


class IllegalCall(RuntimeError):
    """A call the FMI state machine does not allow in the instance's state, or a value reference it cannot take."""


#: the largest step doStep takes, in ticks of the block's cycle time (``Block.CYCLE_TIME``): the drive and the
#: controllers compute every tick, and a million ticks take about 2 s in the Python actuator (0.4 s native), so every
#: accepted step ends in bounded time; the native FMUs take the same numbers (mast_model.h, written by the build)
MAX_STEP_TICKS = 1_000_000
#: the same bound for a block without a cycle time [s]: a million of the MAST systems' 100 us exchange steps
MAX_STEP_SIZE = 100.0


def check_time(name: str, value: float) -> None:
    """Refuse (IllegalCall) a time argument that is not finite and >= 0, naming it and its value, in the words
    of the C glue (``mast_bad_time``, fmus/common/native/mast_guard.h)."""
    if not (math.isfinite(value) and value >= 0.0):
        raise IllegalCall(f"{name} = {value:.6g} s: a time must be finite and >= 0")


class _Refused(IllegalCall):
    """A call to an instance that answered fmi2Fatal before: refused with fmi2Fatal again."""


#: pythonfmu's library in an FMU with the C front (``mast build``): binaries/linux64/<modelIdentifier>.pythonfmu.so
#: (FMI 3.0: binaries/x86_64-linux/...; the same suffix as INNER_SUFFIX in pythonfmu_shim.c)
PYTHONFMU_LIBRARY_SUFFIX = ".pythonfmu"


def fmi_call(*allowed: str) -> Callable:
    """For methods the FMU's C layer calls, allowed in the states ``allowed`` (default: every state).

    An illegal call (IllegalCall) is logged with status Error and raised: the C front
    (``pythonfmu_shim.c``) turns pythonfmu's fmi2Fatal into fmi2Error, and the instance goes on.
    Any other exception is logged with status Fatal and raised (fmi2Fatal); from then on the
    instance refuses every call it is asked (the Python side of fmi2Fatal), and so it does after
    an illegal call when no front is there to say fmi2Error. The instance survives the exception
    for fmi2Reset and fmi2FreeInstance (``_survive_pythonfmu_cleanup``).
    """

    def decorate(method: Callable) -> Callable:
        name = _fmi_name(method.__name__)
        states = allowed or ALIVE

        @functools.wraps(method)
        def call(self, *args):
            try:
                if self._failed is not None:
                    raise _Refused(f"refused: the instance failed earlier ({self._failed}); only reset or free it")
                if self._phase not in states:
                    raise IllegalCall(f"not allowed in {self._phase} (allowed in {', '.join(states)})")
                return method(self, *args)
            except Exception as err:
                illegal = isinstance(err, IllegalCall)
                message = f"{name}: {err}" if illegal else f"{name}: {type(err).__name__}: {err}"
                if illegal and not isinstance(err, _Refused) and self._illegal_is_error:
                    self._log_error(message)  # fmi2Error: nothing changed, the instance goes on
                else:
                    self._log_fatal(message)  # fmi2Fatal: every later call is refused
                    if self._failed is None:
                        self._failed = message
                if self._native:
                    _survive_pythonfmu_cleanup(self)
                raise

        return call

    return decorate


def fast_get(checked: Callable) -> Callable:
    """A get of the Real inputs and outputs (``fmi_call``-decorated ``checked``: FMI 2.0 get_real, 3.0
    get_float64), its common case in one frame: an instance that has not failed, every value reference an
    input or output, no output to recompute first (initialization mode after a set). Then the values straight
    from the block, as ``_get_values`` reads them; otherwise ``checked`` answers, with its checks and messages."""

    @functools.wraps(checked)
    def get(self, vrs):
        try:
            if (
                self._failed is None
                and self._io_refs.issuperset(vrs)
                and not (self._phase == INITIALIZATION and self._dirty)
            ):
                values = self._values
                return [values[vr] for vr in vrs]
        except Exception:  # nothing foreseen fails here; whatever does, ``checked`` meets it and says so
            pass
        return checked(self, vrs)

    return get


def fast_set(checked: Callable) -> Callable:
    """A set of Real inputs in step mode (``checked`` as for ``fast_get``), its common case in one frame: an
    instance that has not failed, every value reference an input. The same as ``_set_values`` then (the
    values into the block, the feedthrough outputs evaluated); otherwise ``checked`` answers."""

    @functools.wraps(checked)
    def set_(self, vrs, values):
        try:
            if self._failed is None and self._phase == STEPPING and self._input_refs.issuperset(vrs):
                target = self._values
                for vr, value in zip(vrs, values):
                    target[vr] = value
                if self.block_class.FEEDTHROUGH and self._init_error is None:
                    self._evaluate()
                return None
        except Exception:  # as in fast_get (the same values written again)
            pass
        return checked(self, vrs, values)

    return set_


def _fmi_name(method: str) -> str:
    """``set_real`` -> ``setReal``, ``_get_fmu_state`` -> ``getFMUstate``: the call as FMI names it."""
    if method.endswith("fmu_state"):
        return method.strip("_").removesuffix("_fmu_state") + "FMUstate"
    first, *rest = method.strip("_").split("_")
    return first + "".join(part.title() for part in rest)


class BlockWrapper:
    """The version-independent part of a slave exposing one Block; subclasses set ``block_class``.

    A concrete slave derives from this class and from pythonfmu's Fmi2Slave or
    pythonfmu3's Fmi3Slave and sets ``fmi`` (its version's types); its __init__
    calls ``_wrap`` and ``_register_block``, and it maps the calls that differ
    between the versions (typed get/set of numbers, setup, doStep) onto
    ``_get_values``/``_set_values``, ``_setup`` and ``_step``.
    """

    block_class: ClassVar[type[Block]]
    fmi: ClassVar[FmiVocabulary]
    _phase = INSTANTIATED
    _failed: Optional[str] = None  # why the instance refuses every call (it answered fmi2Fatal)
    _illegal_is_error = True  # an illegal call reaches the host as fmi2Error (see fmi_call)
    _init_error: Optional[str] = None
    _eval_error: Optional[str] = None  # a failed evaluation of the feedthrough outputs (``_evaluate``)
    #: (start time, stop time, step size) [s] of the modelDescription's DefaultExperiment, set by the build (the
    #: first system that uses the FMU: its DefaultExperiment and the step it gives the component); a block with a
    #: cycle time (``Block.CYCLE_TIME``) proposes that parameter's value as the step size instead
    experiment: ClassVar[Optional[tuple[float, float, float]]] = None

    def _wrap(self, kwargs: dict) -> None:
        """Called by the subclass's __init__ after the pythonfmu base class's."""
        # pythonfmu's C layer passes its logger; the builders and Python callers do not
        self._native = "logger" in kwargs
        _drop_repeated_path(self.resources)
        #: the C front's exchange buffer (``_exchange_buffer``: its inputs' reader and outputs' writer): None until
        #: the first step, False: none
        self._exchange = None
        self._front_exchange = None
        if self._native:
            front = _pythonfmu_behind_front(self.resources, type(self).__name__)
            self._illegal_is_error = front is not None
            _defuse_pythonfmu_teardown(self.resources, front)
            self._front_exchange = _front_exchange(front)
        defaults = load_defaults(self.resources)
        # the variables of the built-in parameters (a mechanism's follow its topology: Block.for_parameters)
        self.block_class = cls = type(self).block_class.for_parameters(defaults)
        self.description = (type(self).__doc__ or cls.__doc__ or "").strip().split("\n")[0] or None
        self._n_in = len(cls.INPUTS)
        self._n_io = len(cls.INPUTS) + len(cls.OUTPUTS)
        #: the inputs' start values (Block.input_starts; the others start at 0)
        self._input_starts = cls.input_starts(defaults) if defaults else {}
        self._values: List[float] = [self._input_starts.get(n, 0.0) for n in cls.INPUTS] + [0.0] * len(cls.OUTPUTS)
        self._block: Optional[Block] = None
        self._dirty = True
        self._t0 = 0.0
        self._params = {p.name: defaults.get(p.name, _neutral(p.kind)) for p in cls.PARAMETERS}
        self.default_experiment = self._default_experiment()
        self._input_refs = frozenset(range(len(cls.INPUTS)))
        self._io_refs = frozenset(range(self._n_io))  # the inputs and outputs: all Real (_register_block)

    def _default_experiment(self):
        """The DefaultExperiment the FMU declares (``experiment``, the step size the block's cycle time); None
        when the build set none."""
        if self.experiment is None:
            return None
        start, stop, step = self.experiment
        if self.block_class.CYCLE_TIME is not None:
            step = float(self._params[self.block_class.CYCLE_TIME])
        return self.fmi.default_experiment(start_time=start, stop_time=stop, step_size=step)

    def _register_block(self, units: Optional[Mapping[str, str]] = None, input_start: Optional[float] = None) -> None:
        """Register the block's inputs, outputs and parameters in value-reference order, with ``units``
        per variable name (FMI 3.0) and the inputs' start value where the version requires one."""
        cls, fmi, units = self.block_class, self.fmi, units or {}
        real, causality, variability = fmi.kinds[float], fmi.causality, fmi.variability

        def unit(name: str) -> dict:
            return {"unit": units[name]} if name in units else {}

        for name in cls.INPUTS:
            start = {} if input_start is None else {"start": self._input_starts.get(name, input_start)}
            self.register_variable(
                real(
                    name,
                    causality=causality.input,
                    variability=variability.continuous,
                    description=cls.DESCRIPTIONS.get(name),
                    **unit(name),
                    **start,
                )
            )
        # outputs: initial="calculated" (no start value): computed in initialization mode from the parameters
        # and the inputs (the mechanism's pose from the carriages' positions ...), as FMI 2.0/3.0 define it
        for name in cls.OUTPUTS:
            self.register_variable(
                real(
                    name,
                    causality=causality.output,
                    variability=variability.continuous,
                    initial=fmi.initial.calculated,
                    description=cls.DESCRIPTIONS.get(name),
                    **unit(name),
                )
            )
        for spec in cls.PARAMETERS:
            self.register_variable(
                fmi.kinds[spec.kind](
                    spec.name,
                    causality=causality.parameter,
                    variability=variability.fixed,
                    description=f"[{spec.unit}] {spec.description}" if spec.unit else spec.description,
                    getter=lambda n=spec.name: self._params[n],
                    setter=lambda v, n=spec.name: self._set_param(n, v),
                    **unit(spec.name),
                )
            )

    def _output_dependencies(self) -> dict[int, list[int]]:
        """ModelStructure's direct feedthrough (``Block.FEEDTHROUGH``), by value reference: every output -> the
        inputs it depends on at a communication point (empty: none, the output changes only in doStep)."""
        refs = {var.name: vr for vr, var in self.vars.items()}
        feedthrough = self.block_class.FEEDTHROUGH
        return {refs[out]: [refs[name] for name in feedthrough.get(out, ())] for out in self.block_class.OUTPUTS}

    # FMI 2.0's logger takes the message as a printf format: a '%' in it must be written '%%' there;
    # FMI 3.0's takes the text as it is (FmiVocabulary.message_is_format)
    def _logged(self, message: str, status, category: str) -> None:
        self.log(
            message.replace("%", "%%") if self.fmi.message_is_format else message, status=status, category=category
        )

    def _log_warning(self, message: str) -> None:
        self._logged(message, self.fmi.status.warning, "logStatusWarning")

    def _log_error(self, message: str) -> None:
        self._logged(message, self.fmi.status.error, "logStatusError")

    def _log_fatal(self, message: str) -> None:
        self._logged(message, self.fmi.status.fatal, "logStatusFatal")

    # -- values ----------------------------------------------------------------------
    def _set_param(self, name: str, value) -> None:
        self._params[name] = value
        self._block = None
        self._dirty = True

    def _ensure_outputs(self) -> None:
        """In initialization mode, (re)build the block and compute outputs from the inputs."""
        if self._block is None:
            self._block = self.block_class(self._params, name=self.instance_name)
            self._block.values[:] = self._values
            self._values = self._block.values
        if self._dirty:
            self._block.initialize(self._t0)
            self._dirty = False

    def _check_refs(self, vrs: List[int], kind: Union[type, str], write: bool) -> None:
        """Refuse (IllegalCall) a value reference that is unknown, of another type, or not settable now.
        ``kind``: the Python type of the values, or the name of an FMI type no variable of a block has."""
        if kind is float:  # the hot paths: reading inputs and outputs in any state, setting inputs during the run
            known = self._io_refs if not write else self._input_refs if self._phase == STEPPING else None
            if known is not None and known.issuperset(vrs):
                return
        variable_class = self.fmi.kinds.get(kind)  # None: a type none of the blocks' variables has (Boolean, ...)
        wanted = variable_class.__name__ if variable_class is not None else "Boolean" if kind is bool else kind
        causality = self.fmi.causality
        for vr in vrs:
            var = self.vars.get(vr)
            if var is None:
                raise IllegalCall(
                    f"value reference {vr} is not a variable of {type(self).__name__} "
                    f"(it has {min(self.vars)}..{max(self.vars)})"
                )
            if variable_class is None or not isinstance(var, variable_class):
                raise IllegalCall(f"'{var.name}' (value reference {vr}) is of type {type(var).__name__}, not {wanted}")
            if not write:
                continue
            if var.causality == causality.parameter:
                if self._phase not in (INSTANTIATED, INITIALIZATION):
                    raise IllegalCall(
                        f"parameter '{var.name}' is fixed: it can be set before exitInitializationMode, "
                        f"not in {self._phase}"
                    )
            elif var.causality == causality.input:
                if self._phase == TERMINATED:
                    raise IllegalCall(f"input '{var.name}' cannot be set in {self._phase}")
            else:
                raise IllegalCall(f"'{var.name}' is {var.causality.name}: only inputs and parameters can be set")

    def _get_values(self, vrs: List[int]) -> List[float]:
        self._check_refs(vrs, float, write=False)
        n = self._n_io
        if self._phase == INITIALIZATION and self._dirty and any(len(self.block_class.INPUTS) <= vr < n for vr in vrs):
            self._tentative_outputs()
        values = self._values
        return [values[vr] if vr < n else float(self.vars[vr].getter()) for vr in vrs]

    def _set_values(self, vrs: List[int], values: List[float]) -> None:
        self._check_refs(vrs, float, write=True)
        n = self._n_io
        target = self._values
        for vr, value in zip(vrs, values):
            if vr < n:
                target[vr] = value
            else:
                self.vars[vr].setter(value)
        if self._phase == INITIALIZATION:
            self._dirty = True
        elif self._phase == STEPPING and self.block_class.FEEDTHROUGH and self._init_error is None:
            self._evaluate()

    def _evaluate(self) -> None:
        """Direct feedthrough (``Block.FEEDTHROUGH``): the outputs follow the inputs just set. A model
        failure is logged and the next doStep refuses with it, as a failure in doStep would."""
        try:
            self._block.evaluate()
            self._eval_error = None
        except Exception as err:
            self._eval_error = f"{type(err).__name__}: {err}"
            self._log_error(f"{self.fmi.set_real}: evaluating the outputs: {self._eval_error}")

    def _tentative_outputs(self) -> None:
        """Outputs read during initialization: a failure may be an input the host has not set yet."""
        try:
            self._ensure_outputs()
        except Exception as err:  # exitInitializationMode decides, with the inputs the host settled on
            self._log_warning(f"initialization mode, outputs kept at their last values: {type(err).__name__}: {err}")

    # -- life cycle ------------------------------------------------------------------
    def _setup(self, start_time: float) -> None:
        self._t0 = start_time

    # the calls that are the same in FMI 2.0 and 3.0 (the others map onto the helpers here in fmi.py, fmi3.py)
    @fmi_call()
    def get_string(self, vrs: List[int]) -> List[str]:
        self._check_refs(vrs, str, write=False)
        return super().get_string(vrs)

    @fmi_call()
    def set_string(self, vrs: List[int], values: List[str]) -> None:
        self._check_refs(vrs, str, write=True)
        super().set_string(vrs, values)

    @fmi_call()
    def get_boolean(self, vrs: List[int]) -> List[bool]:
        self._check_refs(vrs, bool, write=False)
        return super().get_boolean(vrs)

    @fmi_call()
    def set_boolean(self, vrs: List[int], values: List[bool]) -> None:
        self._check_refs(vrs, bool, write=True)
        super().set_boolean(vrs, values)

    @fmi_call(INSTANTIATED)
    def enter_initialization_mode(self) -> None:
        self._phase = INITIALIZATION

    @fmi_call(STEPPING)
    def terminate(self) -> None:
        self._phase = TERMINATED

    @fmi_call(INITIALIZATION)
    def exit_initialization_mode(self) -> None:
        """Build the block and compute the outputs at the start; a failure is logged, then refuses every step."""
        try:
            self._ensure_outputs()
            self._init_error = None
        except Exception as err:  # see the module docstring: a refused step, not an exception, reaches the host
            self._init_error = f"{type(err).__name__}: {err}"
            self._log_error(f"exitInitializationMode: {self._init_error}")
        self._phase = STEPPING

    def _exchange_buffer(self):
        """The C front's buffer of the inputs and outputs (``pythonfmu_shim.c``, FMI 2.0), taken at the first step
        and filled with the values here, as (read, write): ``read()`` the inputs (a tuple of n_in floats),
        ``write(*outputs)`` the outputs into it (struct over the buffer's bytes: no ctypes slice per step);
        False without a front that offers one, or for a block with direct feedthrough (its outputs follow a set:
        the front forwards every call)."""
        take = self._front_exchange
        if take is None or self.block_class.FEEDTHROUGH:
            return False
        fresh = ctypes.c_int(0)
        address = take(self._n_in, self._n_io, self._front_step, ctypes.byref(fresh))
        if not address:
            return False
        buffer = (ctypes.c_double * self._n_io).from_address(address)
        if fresh.value:  # else it holds the inputs set since this object's initialisation (after fmi2Reset)
            buffer[:] = self._values
        view = memoryview(buffer).cast("B")  # keeps the buffer object alive
        n_in = self._n_in
        read = functools.partial(struct.Struct(f"{n_in}d").unpack_from, view)
        write = functools.partial(
            struct.Struct(f"{self._n_io - n_in}d").pack_into, view, n_in * ctypes.sizeof(ctypes.c_double)
        )
        return read, write

    def _largest_step(self) -> float:
        """The largest step doStep takes [s] (MAX_STEP_TICKS of the cycle time, else MAX_STEP_SIZE)."""
        cycle = self.block_class.CYCLE_TIME
        return MAX_STEP_TICKS * float(self._params[cycle]) if cycle else MAX_STEP_SIZE

    def _check_step(self, current_time: float, step_size: float) -> None:
        """Refuse (IllegalCall) a doStep whose times are not finite and >= 0, or whose step is longer than
        ``_largest_step`` (checked once the block initialised: the native wrapper's order, fmi2_wrapper.c)."""
        check_time("currentCommunicationPoint", current_time)
        check_time("communicationStepSize", step_size)
        largest = self._largest_step() if self._init_error is None and self._eval_error is None else math.inf
        if step_size > largest:
            cycle = self.block_class.CYCLE_TIME
            ticks = f" ({MAX_STEP_TICKS:.6g} ticks of {cycle} = {float(self._params[cycle]):.6g} s)" if cycle else ""
            raise IllegalCall(
                f"communicationStepSize = {step_size:.6g} s exceeds the largest step this FMU takes, "
                f"{largest:.6g} s{ticks}"
            )

    def _front_step(self, current_time: float, step_size: float) -> int:
        """fmi2DoStep as the C front calls it (``pythonfmu_shim.c``, the fast path; pythonfmu's ``do_step`` with
        its checks, ``fmi_call``): 0 stepped; 3 stepped, 4 refused (Discard), each with messages logged, which
        the front has pythonfmu pass on; 2 not stepped (the instance failed earlier, or is not in step mode):
        the front calls pythonfmu's fmi2DoStep, which says why (also for a time it refuses: ``_check_step``)."""
        if (
            self._failed is not None
            or self._phase != STEPPING
            or not (0.0 <= current_time < math.inf and 0.0 <= step_size <= self._largest_step())
        ):  # the checked doStep answers, with its message
            return 2
        ok = self._step(current_time, step_size)
        if self.log_queue:
            return 3 if ok else 4
        return 0 if ok else 4

    def _step(self, current_time: float, step_size: float) -> bool:
        """Advance the block; a model failure is logged and reported as a refused step (Discard). Behind the
        C front the inputs come from its buffer and the outputs go back into it (``_exchange_buffer``)."""
        exchange = self._exchange
        if exchange is None:
            exchange = self._exchange = self._exchange_buffer()
        values = self._values
        if exchange is not False:
            values[: self._n_in] = exchange[0]()
        try:
            if self._init_error is not None:
                raise RuntimeError(f"the instance did not initialise: {self._init_error}")
            if self._eval_error is not None:
                raise RuntimeError(
                    f"the outputs of the inputs set at this communication point failed: {self._eval_error}"
                )
            self._block.do_step(current_time, step_size)
        except Exception as err:  # the host decides what to do; the instance stays usable for terminate/free
            self._log_error(f"doStep at t={current_time:.6g} s: {type(err).__name__}: {err}")
            return False
        finally:
            if exchange is not False:
                exchange[1](*values[self._n_in :])
        return True

    # -- FMU state (get/set FMU state) -------------------------------------------------
    @fmi_call()
    def _get_fmu_state(self) -> "SlaveState":
        block = self._block
        return SlaveState(
            type(self).__name__,
            dict(self._params),
            list(self._values) if block is None else None,
            None if block is None else block.get_state(),
            self._dirty,
            self._t0,
            self._phase,
            self._init_error,
        )

    @fmi_call()
    def _set_fmu_state(self, state: "SlaveState") -> None:
        if getattr(state, "owner", None) != type(self).__name__ or not hasattr(state, "block"):
            raise IllegalCall(
                f"not an FMU state of {type(self).__name__}: {type(state).__name__} "
                f"{getattr(state, 'owner', '')}".rstrip()
            )
        self._params = dict(state.params)
        if state.block is None:
            self._block = None
            self._values = list(state.values)
        else:
            if self._block is None:  # a block of the same class: set_state replaces all it holds
                self._block = self.block_class(state.params, name=self.instance_name)
            self._block.set_state(state.block)
            self._values = self._block.values
        self._dirty, self._t0, self._phase, self._init_error = state.dirty, state.t0, state.phase, state.error


class SlaveState:
    """What get FMU state hands the host (pythonfmu keeps the Python object behind the pointer)."""

    __slots__ = ("owner", "params", "values", "block", "dirty", "t0", "phase", "error")

    def __init__(self, owner, params, values, block, dirty, t0, phase, error) -> None:
        self.owner, self.params, self.values, self.block = owner, params, values, block
        self.dirty, self.t0, self.phase, self.error = dirty, t0, phase, error


def _survive_pythonfmu_cleanup(slave: Any) -> None:
    """Keep an instance that raised alive for the calls FMI still allows (terminate, reset, free).

    pythonfmu 0.7.0 and pythonfmu3 0.3.4 (PySlaveInstance::handle_py_exception)
    answer any Python exception by releasing one reference each to the slave
    class, the slave and its log queue, and release them again when the
    instance is freed: a double release that corrupts the interpreter after a
    few dozen failed calls (measured: segmentation fault after 68). One extra
    reference per exception, owned by nobody, balances the count. Only done
    under pythonfmu's C layer (the ``logger`` argument it passes).
    """
    for obj in (type(slave), slave, slave.log_queue):
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(obj))


def _pythonfmu_behind_front(resources: Optional[str], identifier: str) -> Optional[str]:
    """pythonfmu's library when the FMU's binary is the C front (``pythonfmu_shim.c``) on this platform, else None."""
    if not sys.platform.startswith("linux") or not resources:
        return None
    for platform in ("linux64", "x86_64-linux"):  # FMI 2.0, FMI 3.0
        library = os.path.join(
            os.path.dirname(os.path.abspath(resources)),
            "binaries",
            platform,
            f"{identifier}{PYTHONFMU_LIBRARY_SUFFIX}.so",
        )
        if os.path.exists(library):
            return library
    return None


def _front_exchange(library: Optional[str]) -> Optional[Callable]:
    """``mast_front_exchange(n_in, n_io, step, fresh)`` of the C front in front of pythonfmu's ``library`` (the
    front's own library, loaded by the host already), or None where it offers none (FMI 3.0, an older front)."""
    if library is None:
        return None
    try:  # PyDLL: the call keeps the GIL (the front takes a reference to the step it is given)
        take = ctypes.PyDLL(library.replace(PYTHONFMU_LIBRARY_SUFFIX + ".so", ".so")).mast_front_exchange
    except (OSError, AttributeError):
        return None
    take.restype = ctypes.c_void_p
    take.argtypes = (ctypes.c_size_t, ctypes.c_size_t, ctypes.py_object, ctypes.POINTER(ctypes.c_int))
    return take


def _defuse_pythonfmu_teardown(resources: Optional[str], library: Optional[str] = None) -> None:
    """Release the FMU library's interpreter guard before the process exits, where that is safe.

    pythonfmu 0.7.0 and pythonfmu3 0.3.4 keep a static ``std::shared_ptr<PyState>``
    in the FMU's library and reset it from the library's destructor function
    (``finalizePythonInterpreter``). The library cannot be unloaded (it has
    unique symbols), so that happens at process exit, after the exit handlers
    have already destroyed the shared_ptr: a release through a dangling pointer
    that writes into freed memory (valgrind: invalid read in
    finalizePythonInterpreter of a block freed by __run_exit_handlers) and now
    and then aborts the host at exit ("corrupted double-linked list").
    In a Python program (``sys.orig_argv`` set), which owns the interpreter,
    an atexit hook releases every library's guard before the C exit handlers
    run, and the late reset finds nothing to release (valgrind: the invalid
    read is gone). In a C/C++ host the guard of the library that started the
    interpreter must live until the end: the FMU's C front (pythonfmu_shim.c)
    resets it in an exit handler that runs before the C++ exit handlers
    (valgrind: no invalid read; without a C front, one). Linux only (on Windows pythonfmu
    resets it from DllMain). ``library``: pythonfmu's library behind the C front, if there is one.
    """
    if not sys.platform.startswith("linux") or not resources:
        return
    if library is None:
        found = glob.glob(os.path.join(os.path.dirname(os.path.abspath(resources)), "binaries", "*", "*.so"))
        if len(found) != 1:
            return
        library = found[0]
    if not sys.orig_argv:  # the interpreter was started by pythonfmu itself: a C/C++ host
        return
    registry = sys.modules.get("_mast_pythonfmu_process")
    if registry is None:  # shared by every FMU's bundled copy of this module
        registry = sys.modules["_mast_pythonfmu_process"] = types.ModuleType("_mast_pythonfmu_process")
        registry.released_at_exit = set()
    if library not in registry.released_at_exit:
        registry.released_at_exit.add(library)
        try:  # the loaded library (found by the file, which a host may delete before it exits)
            release = ctypes.CDLL(library).finalizePythonInterpreter
        except (OSError, AttributeError):
            return
        atexit.register(release)


def _drop_repeated_path(resources: Optional[str]) -> None:
    """pythonfmu inserts the resources folder into sys.path at every instantiation: keep one entry."""
    if resources and sys.path.count(resources) > 1:
        first = sys.path.index(resources)
        sys.path[:] = sys.path[: first + 1] + [p for p in sys.path[first + 1 :] if p != resources]


def _neutral(kind: type):
    return {float: 0.0, int: 0, str: ""}[kind]
