"""Sampled-data block: the model object an FMU wraps.

A block owns a flat list ``values``: the inputs first (in ``INPUTS`` order),
then the outputs (in ``OUTPUTS`` order). The FMI wrapper maps value references
0..n-1 straight onto this list, and the direct composition reads and writes the
same list, so both routes run exactly the same arithmetic.

Life cycle: ``Block(params)`` validates the parameters; ``initialize(t0)``
computes the outputs at the start time from the initial state and the current
inputs; ``do_step(t, h)`` advances from ``t`` to ``t + h`` with the inputs held
(zero-order hold) and leaves the outputs valid at ``t + h``.

Direct feedthrough: an output listed in ``FEEDTHROUGH`` follows the inputs it names at a
communication point, without a step (a controller's command computed from the samples just
taken). ``evaluate()`` computes those outputs from the inputs as they are, changing no state;
the FMU declares the dependencies in its ModelStructure and the master sets the inputs of a
component, evaluates it and passes its feedthrough outputs on before the components they feed
read theirs (master.py). Every other output changes only in ``do_step``.

State: ``get_state()`` returns a snapshot of everything the block holds and
``set_state(snapshot)`` puts the block back there, so a host can roll back
(FMI get/set FMU state). The default copies the block's attributes deeply;
a block whose state is cheaper to describe may override both.
"""

from __future__ import annotations

import copy
from typing import ClassVar, Mapping, Optional

from .parameters import Param, Value, validate


class ModelError(RuntimeError):
    """The model cannot go on: unreachable pose, singularity, divergence, ..."""


class Block:
    INPUTS: ClassVar[tuple[str, ...]] = ()
    OUTPUTS: ClassVar[tuple[str, ...]] = ()
    PARAMETERS: ClassVar[tuple[Param, ...]] = ()
    #: units of inputs and outputs, by name (documentation and modelDescription)
    UNITS: ClassVar[Mapping[str, str]] = {}
    #: one-line descriptions of inputs and outputs, by name
    DESCRIPTIONS: ClassVar[Mapping[str, str]] = {}
    #: direct feedthrough: output -> the inputs it depends on at a communication point (module docstring)
    FEEDTHROUGH: ClassVar[Mapping[str, tuple[str, ...]]] = {}
    #: the parameter that is the block's cycle time (its tick, s), the step size its FMU's DefaultExperiment
    #: proposes; None: a block without one (its FMU proposes the step the project's systems give it)
    CYCLE_TIME: ClassVar[Optional[str]] = None

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        self.name = name or type(self).__name__
        self.params = validate(self.PARAMETERS, params, self.name)
        self.values: list[float] = [0.0] * (len(self.INPUTS) + len(self.OUTPUTS))

    @classmethod
    def for_parameters(cls, params: Mapping[str, Value]) -> type["Block"]:
        """The class whose variables a block of ``params`` has: this one, unless the variables follow the
        parameters (a mechanism's follow its topology, ``MechanismBlock``). An FMU fixes its variables with
        its built-in parameters (``slave.BlockWrapper``)."""
        return cls

    @classmethod
    def input_starts(cls, params: Mapping[str, Value]) -> dict[str, float]:
        """The inputs whose start value is not 0 for a block of ``params`` (an FMU declares them, FMI 3.0, and
        starts from them when a host leaves the inputs unset): none by default."""
        return {}

    # -- convenience accessors by name (not for hot paths) -------------------
    def index(self, name: str) -> int:
        try:
            return (self.INPUTS + self.OUTPUTS).index(name)
        except ValueError:
            raise KeyError(f"{self.name}: no input or output named '{name}'") from None

    def set(self, **inputs: float) -> None:
        for key, value in inputs.items():
            if key not in self.INPUTS:
                raise KeyError(f"{self.name}: no input named '{key}'; inputs are {', '.join(self.INPUTS)}")
            self.values[self.INPUTS.index(key)] = float(value)

    def get(self, name: str) -> float:
        return self.values[self.index(name)]

    def outputs(self) -> dict[str, float]:
        n = len(self.INPUTS)
        return dict(zip(self.OUTPUTS, self.values[n:]))

    # -- state snapshots (roll-back) ----------------------------------------------
    def get_state(self) -> object:
        """A snapshot of the block: parameters, internal state, inputs and outputs (deep copies)."""
        return copy.deepcopy(vars(self), {id(self): self})

    def set_state(self, state: object) -> None:
        """Return to a snapshot taken by ``get_state`` (of this block or of one of the same class).

        ``values`` is restored in place: whoever holds the list (the FMI wrapper,
        the master's prepared setters and getters) keeps seeing the live values.
        """
        restored = copy.deepcopy(state, {id(self): self})
        values = restored.pop("values")
        vars(self).update(restored)
        self.values[:] = values

    # -- to implement ----------------------------------------------------------
    def initialize(self, t0: float) -> None:
        raise NotImplementedError

    def do_step(self, t: float, h: float) -> None:
        raise NotImplementedError

    def evaluate(self) -> None:
        """The ``FEEDTHROUGH`` outputs from the inputs as they are now (no state change); nothing without any."""
