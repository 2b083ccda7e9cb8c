"""Generic FMI 2.0 Co-Simulation wrapper (pythonfmu) around a :class:`Block`.

Value references: 0..n_in-1 are the block's inputs, n_in..n_in+n_out-1 its
outputs (both straight onto ``Block.values``), then the parameters. Parameter
start values come from ``resources/parameters.json``, written by ``mast build``
from the SSP parameter sets, so the values live in one place (the .ssv files).

Behaviour hosts rely on:
- parameters are validated when the block is built (leaving initialization
  mode, or the first output read in initialization mode): a bad value is
  logged with its name and the call returns fmi2Error;
- in initialization mode outputs follow the inputs (the host may iterate to
  a consistent initial point), so get after set recomputes them;
- an exception in the model is logged (class and message, instance and
  time) and the call returns fmi2Error instead of killing the host.
"""
from __future__ import annotations

import json
import os
from typing import ClassVar, List, Optional

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

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


class BlockSlave(Fmi2Slave):
    """FMI slave exposing one Block; subclasses set ``block_class``."""

    block_class: ClassVar[type[Block]]

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        cls = self.block_class
        self.description = (type(self).__doc__ or cls.__doc__ or "").strip().split("\n")[0] or None
        self._n_io = len(cls.INPUTS) + len(cls.OUTPUTS)
        self._values: List[float] = [0.0] * self._n_io
        self._block: Optional[Block] = None
        self._dirty = True
        self._t0 = 0.0
        defaults = load_defaults(self.resources)
        self._params = {p.name: defaults.get(p.name, _neutral(p.kind)) for p in cls.PARAMETERS}
        self._param_names: List[str] = []
        for name in cls.INPUTS:
            self.register_variable(Real(name, causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous,
                                        description=cls.DESCRIPTIONS.get(name)))
        for name in cls.OUTPUTS:
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        initial=Fmi2Initial.exact,
                                        description=cls.DESCRIPTIONS.get(name)))
        kinds = {float: Real, int: Integer, str: String}
        for spec in cls.PARAMETERS:
            self._param_names.append(spec.name)
            self.register_variable(kinds[spec.kind](
                spec.name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                description=f"[{spec.unit}] {spec.description}" if spec.unit else spec.description,
                getter=lambda n=spec.name: self._params[n],
                setter=lambda v, n=spec.name: self._set_param(n, v)))

    # -- value access: inputs/outputs go straight to the list --------------
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

    def get_real(self, vrs: List[int]) -> List[float]:
        n = self._n_io
        if self._in_init and self._dirty and any(len(self.block_class.INPUTS) <= vr < n for vr in vrs):
            self._guard(self._ensure_outputs)
        values = self._values
        return [values[vr] if vr < n else float(self.vars[vr].getter()) for vr in vrs]

    def set_real(self, vrs: List[int], values: List[float]) -> None:
        n = self._n_io
        target = self._values
        for vr, value in zip(vrs, values):
            if vr < n:
                target[vr] = value
            else:
                self.vars[vr].setter(value)
        if self._in_init:
            self._dirty = True

    # -- life cycle ----------------------------------------------------------
    _in_init = False

    def setup_experiment(self, start_time: float, stop_time, tolerance) -> None:
        self._t0 = start_time

    def enter_initialization_mode(self) -> None:
        self._in_init = True

    def exit_initialization_mode(self) -> None:
        self._guard(self._ensure_outputs)
        self._in_init = False

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Advance the block; a model failure is logged and reported as a refused step (fmi2Discard)."""
        try:
            self._block.do_step(current_time, step_size)
        except Exception as err:  # the host decides what to do; the instance stays usable for terminate/free
            self.log(f"doStep at t={current_time:.6g} s: {type(err).__name__}: {err}",
                     status=Fmi2Status.error, category="logStatusError")
            return False
        return True

    def _guard(self, func) -> None:
        """Run model code; log the cause of a failure, then let pythonfmu turn it into an error status."""
        try:
            func()
        except Exception as err:  # logged first: pythonfmu's own message does not carry the cause
            self.log(f"{type(err).__name__}: {err}", status=Fmi2Status.error,
                     category="logStatusError")
            raise


def _neutral(kind: type):
    return {float: 0.0, int: 0, str: ""}[kind]
