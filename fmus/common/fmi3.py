"""Generic FMI 3.0 Co-Simulation wrapper (pythonfmu3) around a :class:`Block`.

The FMI 3.0 variants of the MAST FMUs (``mast build --fmi3``): the same blocks,
the same behaviour (``slave.py``: state machine, illegal calls as fmi3Error behind
the C front, feedthrough outputs evaluated when their inputs are set), FMI 3.0
types (Float64, Int32, String), the independent variable ``time``, unit
definitions and the direct feedthrough in ModelStructure. Only the build imports
this module outside an FMU; inside one, pythonfmu3 travels with it.
"""

from __future__ import annotations

from typing import List

from pythonfmu3 import DefaultExperiment, Float64, Fmi3Causality, Fmi3Initial, Fmi3Slave, Fmi3Variability, Int32, String
from pythonfmu3.enums import Fmi3Status
from pythonfmu3.unit import Unit

from .slave import INSTANTIATED, STEPPING, BlockWrapper, FmiVocabulary, fast_get, fast_set, fmi_call

#: pythonfmu3 0.3.4 does not pass fmi3EnterInitializationMode's start time on to Python (it calls
#: enter_initialization_mode without it, and never setup_experiment), so the model would start at t = 0
#: whatever the host says. The C front (pythonfmu_shim.c, START_TIME_REFERENCE) sets the start time at this
#: value reference, which no variable has, right before it forwards fmi3EnterInitializationMode. Without the
#: front (a build without a C compiler) the start time is 0.
START_TIME_REFERENCE = 0x7FFFFFFF  # the largest that pythonfmu3 passes to Python unchanged (a C int)


class BlockSlave3(BlockWrapper, Fmi3Slave):
    """FMI 3.0 slave exposing one Block; subclasses set ``block_class``."""

    fmi = FmiVocabulary(
        {float: Float64, int: Int32, str: String},
        Fmi3Causality,
        Fmi3Variability,
        Fmi3Initial,
        Fmi3Status,
        message_is_format=False,
        set_real="setFloat64",
        default_experiment=DefaultExperiment,
    )

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self._wrap(kwargs)
        self._time = 0.0
        cls = self.block_class
        units = dict(cls.UNITS)
        units.update({p.name: p.unit for p in cls.PARAMETERS if p.kind is float and p.unit})
        self.register_units([Unit(u) for u in sorted(set(units.values()))])
        self._register_block(units, input_start=0.0)
        self.register_variable(
            Float64(
                "time",
                causality=Fmi3Causality.independent,
                variability=Fmi3Variability.continuous,
                getter=lambda: self._time,
            )
        )

    def to_xml(self, model_options: dict | None = None):
        """pythonfmu3's modelDescription, with the direct feedthrough (``Block.FEEDTHROUGH``) declared in
        ModelStructure: each Output lists the inputs it depends on by value reference (none: an empty list;
        an absent list would claim every input)."""
        root = super().to_xml({} if model_options is None else model_options)
        dependencies = self._output_dependencies()
        for output in root.iterfind("ModelStructure/Output"):
            inputs = dependencies[int(output.get("valueReference"))]
            output.set("dependencies", " ".join(map(str, inputs)))
            if inputs:
                output.set("dependenciesKind", " ".join("dependent" for _ in inputs))
        return root

    # -- the calls pythonfmu3's C layer makes --------------------------------------------
    @fast_get
    @fmi_call()
    def get_float64(self, vrs: List[int]) -> List[float]:
        return self._get_values(vrs)

    @fast_set
    @fmi_call()
    def set_float64(self, vrs: List[int], values: List[float]) -> None:
        if len(vrs) == 1 and vrs[0] == START_TIME_REFERENCE:  # the C front's, before enterInitializationMode
            if self._phase == INSTANTIATED:  # else enterInitializationMode, next, is refused and changes nothing
                self._setup(values[0])
                self._time = values[0]
            return
        self._set_values(vrs, values)

    @fmi_call()
    def get_int32(self, vrs: List[int]) -> List[int]:
        self._check_refs(vrs, int, write=False)
        return super().get_int32(vrs)

    @fmi_call()
    def set_int32(self, vrs: List[int], values: List[int]) -> None:
        self._check_refs(vrs, int, write=True)
        super().set_int32(vrs, values)

    # types none of the blocks' variables has: every value reference is refused with a message (fmi3Error;
    # Boolean: slave.py)
    @fmi_call()
    def get_int64(self, vrs: List[int]) -> List[int]:
        self._check_refs(vrs, "Int64", write=False)
        return super().get_int64(vrs)

    @fmi_call()
    def set_int64(self, vrs: List[int], values: List[int]) -> None:
        self._check_refs(vrs, "Int64", write=True)
        super().set_int64(vrs, values)

    @fmi_call()
    def get_uint64(self, vrs: List[int]) -> List[int]:
        self._check_refs(vrs, "UInt64", write=False)
        return super().get_uint64(vrs)

    @fmi_call()
    def set_uint64(self, vrs: List[int], values: List[int]) -> None:
        self._check_refs(vrs, "UInt64", write=True)
        super().set_uint64(vrs, values)

    @fmi_call(INSTANTIATED)
    def setup_experiment(self, start_time: float) -> None:
        self._setup(start_time)
        self._time = start_time

    @fmi_call(STEPPING)
    def do_step(self, current_time: float, step_size: float) -> bool:
        self._check_step(current_time, step_size)
        ok = self._step(current_time, step_size)
        if ok:
            self._time = current_time + step_size
        return ok
