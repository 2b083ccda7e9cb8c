"""Generic FMI 2.0 Co-Simulation wrapper (pythonfmu) around a :class:`Block`.

The behaviour hosts rely on (initialization, errors, state, several instances)
is in ``slave.py``, shared with the FMI 3.0 wrapper ``fmi3.py``; this module
registers the variables the FMI 2.0 way and maps the typed calls.
"""

from __future__ import annotations

from typing import List

from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

from .slave import INSTANTIATED, STEPPING, BlockWrapper, FmiVocabulary, check_time, fast_get, fast_set, fmi_call

# re-exported: the generated FMU entry module imports keep_alive from here (mast.core.build)
from .slave import PARAMETERS_FILE as PARAMETERS_FILE
from .slave import keep_alive as keep_alive
from .slave import load_defaults as load_defaults


class BlockSlave(BlockWrapper, Fmi2Slave):
    """FMI 2.0 slave exposing one Block; subclasses set ``block_class``."""

    fmi = FmiVocabulary(
        {float: Real, int: Integer, str: String},
        Fmi2Causality,
        Fmi2Variability,
        Fmi2Initial,
        Fmi2Status,
        message_is_format=True,
        set_real="setReal",
        default_experiment=DefaultExperiment,
    )

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self._wrap(kwargs)
        self._register_block()

    def to_xml(self, model_options: dict | None = None):
        """pythonfmu's modelDescription, with the direct feedthrough (``Block.FEEDTHROUGH``) declared in
        ModelStructure/Outputs: each output lists the inputs it depends on (none: an empty list)."""
        root = super().to_xml({} if model_options is None else model_options)
        index = {vr: k + 1 for k, vr in enumerate(self.vars)}  # FMI 2.0 names variables by their position
        dependencies = {index[out]: ins for out, ins in self._output_dependencies().items()}
        for unknown in root.iterfind("ModelStructure/Outputs/Unknown"):
            unknown.set("dependencies", " ".join(str(index[vr]) for vr in dependencies[int(unknown.get("index"))]))
        return root

    # -- the calls pythonfmu's C layer makes ---------------------------------------------
    @fast_get
    @fmi_call()
    def get_real(self, vrs: List[int]) -> List[float]:
        return self._get_values(vrs)

    @fast_set
    @fmi_call()
    def set_real(self, vrs: List[int], values: List[float]) -> None:
        self._set_values(vrs, values)

    @fmi_call()
    def get_integer(self, vrs: List[int]) -> List[int]:
        self._check_refs(vrs, int, write=False)
        return super().get_integer(vrs)

    @fmi_call()
    def set_integer(self, vrs: List[int], values: List[int]) -> None:
        self._check_refs(vrs, int, write=True)
        super().set_integer(vrs, values)

    @fmi_call(INSTANTIATED)
    def setup_experiment(self, start_time: float, stop_time, tolerance) -> None:
        check_time("startTime", start_time)
        if stop_time is not None:  # pythonfmu passes None when the host defines no stop time
            check_time("stopTime", stop_time)
        self._setup(start_time)

    @fmi_call(STEPPING)
    def do_step(self, current_time: float, step_size: float) -> bool:
        self._check_step(current_time, step_size)
        return self._step(current_time, step_size)
