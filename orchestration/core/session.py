"""A reusable co-simulation session: one SSP opened once, its FMU instances reset between runs.

``mast.core.run.simulate`` opens the SSP, extracts every FMU, instantiates the
components and frees them again for each run: about 0.1 s per run on the
default system. A :class:`Session` does that once and then, between runs,
resets the instances (fmi2Reset) instead of freeing and loading them again.
The master sets every parameter (the SSD's bindings, then the run's overrides)
at each initialization, so nothing of one run leaks into the next: pythonfmu
0.7.0 answers fmi2Reset by creating a new Python slave object, whose parameters
are back at the FMU's start values (tests/test_batch.py checks that a reset
instance reproduces a fresh one).

After a failed run the session frees its instances and instantiates new ones
for the next run: an instance that raised (fmi2Error/fmi2Fatal) is not trusted
with another run.

pythonfmu FMUs share one interpreter per process: use one session per process
(or per thread), never one session from two threads at once. A session still
open when the interpreter exits is closed first (instances freed): pythonfmu
instances left alive through interpreter shutdown were seen to corrupt the heap.
"""
from __future__ import annotations

import tempfile
import time
import weakref
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence, Union

from fmus.common.parameters import Value

from .components import BlockComponent, FMUComponent
from .master import Master, Result, Stimulus
from .motion import NoStimulus, bind, system_axes
from .run import default_signals
from .ssp import SSPArchive, safe_extract


class Session:
    """Runs one SSP many times in this process; use as a context manager or call ``close``."""

    def __init__(self, ssp: Union[str, Path], direct: bool = False, base_step: Optional[float] = None,
                 step_sizes: Optional[Mapping[str, float]] = None) -> None:
        self.ssp = Path(ssp)
        self.direct = direct
        self.base_step = base_step
        self.step_sizes = dict(step_sizes) if step_sizes else None
        self._archive = SSPArchive(self.ssp)
        self.system = self._archive.system
        self._unzip_root: Optional[tempfile.TemporaryDirectory] = None
        self._unzipped: dict[Path, Path] = {}
        self._components: Optional[dict[str, object]] = None
        self._live: dict[str, dict] = {}  # what the exit hook frees: {"components": ...}
        self._finalizer = weakref.finalize(self, _free, self._live)
        #: counters: runs done, instance sets created, resets done (tests and benchmarks read them)
        self.runs = self.instantiations = self.resets = 0
        #: seconds the last run spent getting its components (instantiation or reset)
        self.last_setup_s = 0.0

    # -- components ------------------------------------------------------------------
    def _extract(self, fmu: Path, label: str) -> Path:
        if fmu not in self._unzipped:
            if self._unzip_root is None:
                self._unzip_root = tempfile.TemporaryDirectory(prefix="mast_session_")
            self._unzipped[fmu] = safe_extract(fmu, Path(self._unzip_root.name) / f"{len(self._unzipped)}_{fmu.stem}",
                                               label)
        return self._unzipped[fmu]

    def _instantiate(self) -> dict[str, object]:
        components: dict[str, object] = {}
        try:
            for name in self.system.components:
                fmu = self.system.fmu_path(name)
                if self.direct:
                    components[name] = BlockComponent(
                        name, BlockComponent.class_for(fmu.stem, self.system.components[name].parameters))
                else:
                    components[name] = FMUComponent(name, fmu, self._extract(fmu, self.system.fmu_label(name)))
        except Exception:
            for comp in components.values():
                comp.close()
            raise
        self.instantiations += 1
        return components

    def _acquire(self) -> dict[str, object]:
        """The components for the next run: the kept ones after a reset, else new ones."""
        if self._components is not None:
            try:
                for comp in self._components.values():
                    comp.reset()
                self.resets += 1
                return self._components
            except Exception:  # an instance that refuses to reset is replaced
                self._discard()
        self._components = self._live["components"] = self._instantiate()
        return self._components

    def _discard(self) -> None:
        self._components = None
        _free(self._live)

    # -- runs ------------------------------------------------------------------------------
    def run(self, stimulus: Optional[Stimulus], stop_time: float,
            parameters: Optional[Mapping[str, Mapping[str, Value]]] = None,
            record: Optional[Sequence[str]] = None, record_step: Optional[float] = 1e-3,
            progress: Optional[Callable[[float], None]] = None) -> Result:
        """Same arguments and result as ``mast.core.run.simulate`` (the SSP and route are the session's)."""
        if stimulus is None:
            if self.system.system_inputs:
                raise ValueError(f"{self.ssp}: the system has inputs ({', '.join(self.system.system_inputs)}): give a stimulus")
            stimulus = NoStimulus()
        else:   # the stimulus commands the coordinates of the system's mechanism
            bind(stimulus, system_axes(self.system, parameters), str(self.ssp))
        t0 = time.perf_counter()
        components = self._acquire()
        self.last_setup_s = time.perf_counter() - t0
        try:
            master = Master(self.system, components, base_step=self.base_step, step_sizes=self.step_sizes,
                            own_components=False)
            result = master.run(stop_time, stimulus, record=default_signals(self.system) if record is None else record,
                                record_step=record_step, parameters=parameters, progress=progress)
        except BaseException:
            self._discard()  # a failed run (or an interrupted one) does not hand its instances on
            raise
        finally:
            self.runs += 1
        return result

    def close(self) -> None:
        self._components = None
        self._finalizer()  # frees the instances, once
        if self._unzip_root is not None:
            self._unzip_root.cleanup()
            self._unzip_root = None
        self._unzipped.clear()
        self._archive.close()

    def __enter__(self) -> "Session":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _free(live: dict) -> None:
    """Close the components in ``live`` (also called at interpreter exit for a session left open)."""
    components = live.pop("components", None)
    for comp in (components or {}).values():
        try:
            comp.close()
        except Exception:
            pass
