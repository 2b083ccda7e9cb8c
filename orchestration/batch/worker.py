"""The worker side: one case in a worker process, on a session per SSP kept between cases, with a
timeout; the entry points of the local pool, of an isolated re-run and of a Dask task."""

from __future__ import annotations

import faulthandler
import importlib
import os
import signal
import socket
import tempfile
import threading
import time
import traceback
from pathlib import Path
from typing import Any, Callable, Mapping, Optional

from ..analyses.metrics import FAMILIES, case_metrics, signals_for
from .store import atomic_write

_LOCAL = threading.local()  # per thread: {(ssp path, direct): Session}


class CaseTimeout(RuntimeError):
    pass


_MAX_SESSIONS = 4  # per worker thread: a long-lived (Dask) worker serving many batches keeps the latest


def _one_blas_thread() -> None:
    """Cases run side by side in worker processes: one BLAS thread each.

    numpy's and scipy's OpenBLAS start a thread per core, which spin on the other workers' cores
    (measured: 12 % more CPU per case for nothing). threadpoolctl sets the limit in an already
    loaded library (a forked worker); without it, the environment variables serve spawned ones."""
    global _BLAS_LIMITED
    if _BLAS_LIMITED:
        return
    _BLAS_LIMITED = True
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    try:
        from threadpoolctl import threadpool_limits
    except ModuleNotFoundError:
        return
    threadpool_limits(1)


_BLAS_LIMITED = False


def _session(path: str, direct: bool):
    from collections import OrderedDict

    from ..core.session import Session

    _one_blas_thread()

    sessions = _LOCAL.__dict__.setdefault("sessions", OrderedDict())
    key = (path, direct)
    if key in sessions:
        sessions.move_to_end(key)
    else:
        while len(sessions) >= _MAX_SESSIONS:
            sessions.popitem(last=False)[1].close()
        sessions[key] = Session(path, direct=direct)
    return sessions[key]


def run_case(task: Mapping) -> dict:
    """Run one case in this process (a worker): its metrics, kept signals, timings; never raises."""
    from ..core.master import SimulationError
    from ..core.motion import PoseStep, SineMotion, pose_inputs, system_axes
    from ..core.run import default_signals

    t_case, cpu_case = time.perf_counter(), time.process_time()
    record: dict[str, Any] = {
        "id": task["id"],
        "status": "ok",
        "error": None,
        "metrics": {},
        "worker": {"pid": os.getpid(), "host": socket.gethostname()},
        "started": time.time(),
    }
    timing = {"setup_s": 0.0, "init_s": 0.0, "step_s": 0.0, "metrics_s": 0.0}
    result = None
    try:
        if task.get("before_case") is not None:
            task["before_case"](dict(task))
        session = _session(task["ssp_path"], bool(task.get("direct")))
        motion = task.get("motion")
        if motion is not None:
            # any coordinate of the case's system (checked when the cases were made); the session binds the rest
            stimulus = SineMotion(motion["axis"], motion["amplitude_si"], motion["frequency"], axes=(motion["axis"],))
        elif all(s in session.system.system_inputs for s in pose_inputs(system_axes(session.system))):
            stimulus = PoseStep({})  # no motion: the system holds its home pose (docs/batch.md)
        else:
            stimulus = None  # a system without inputs (its own trajectory component)
        families = task.get("metrics", FAMILIES)
        wanted = signals_for(families, default_signals(session.system))
        record_names = list(dict.fromkeys(wanted + list(task.get("keep", ()))))
        try:
            result = session.run(
                stimulus,
                task["stop_time"],
                parameters=_nest(task["parameters"]),
                record=record_names,
                record_step=task["record_step"],
                progress=_deadline(task.get("timeout")),
            )
        except SimulationError as err:
            result = err.result
            raise
        finally:
            timing["setup_s"] = session.last_setup_s
            if result is not None:
                timing["init_s"] = result.stats.get("init_s", 0.0)
                timing["step_s"] = max(0.0, result.wall_time_s - timing["init_s"])
        t_m = time.perf_counter()
        limits = _limits(session.system, task["parameters"])
        metrics = case_metrics(
            result,
            families,
            _motion_si(motion),
            task["window"][0],
            task["window"][1],
            limits,
            _drives(session.system, task["parameters"]) if "sizing" in families else None,
        )
        custom = task.get("custom")
        if custom:
            func = _import_function(custom) if isinstance(custom, str) else custom
            metrics.update({str(k): float(v) for k, v in func(result, dict(task)).items()})
        timing["metrics_s"] = time.perf_counter() - t_m
        record["metrics"] = metrics
    except SimulationError as err:
        record["status"], record["error"] = "failed", str(err)
    except Exception as err:  # recorded, the batch goes on
        record["status"], record["error"] = "failed", f"{type(err).__name__}: {err}"
        record["traceback"] = traceback.format_exc(limit=8)
    keep = task.get("keep", ())
    if keep and result is not None and len(result.time):
        record["signals"] = {"time": result.time, **{n: result.signals[n] for n in keep if n in result.signals}}
    timing["case_s"] = time.perf_counter() - t_case
    timing["cpu_s"] = time.process_time() - cpu_case  # this worker's CPU time for the case
    record["timing"] = timing
    record["finished"] = time.time()
    return record


def _motion_si(motion: Optional[Mapping]) -> Optional[dict]:
    if motion is None:
        return None
    return {"axis": motion["axis"], "amplitude": motion["amplitude_si"], "frequency": motion["frequency"]}


def _limits(system, flat: Mapping[str, Any]) -> dict[str, float]:
    """The drive's limits: i_max of the controller's current command, u_max of the current loop in the actuators
    (actuator_1's: one drive type for every axis)."""
    out = {}
    for component, name in (("controller", "i_max"), ("actuator_1", "u_max")):
        if component not in system.components:
            continue
        merged = {
            **system.components[component].parameters,
            **{k.split(".", 1)[1]: v for k, v in flat.items() if k.startswith(f"{component}.")},
        }
        if isinstance(merged.get(name), (int, float)):
            out[name] = float(merged[name])
    return out


def _drives(system, flat: Mapping[str, Any]) -> Optional[dict]:
    """The system's drives with their ratings (mast sizing), or None if it names none."""
    from ..analyses.sizing import SizingError, drives

    try:
        return drives(system, _nest(flat))
    except SizingError:
        return None


def _nest(flat: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    nested: dict[str, dict[str, Any]] = {}
    for key, value in flat.items():
        comp, _, param = key.partition(".")
        nested.setdefault(comp, {})[param] = value
    return nested


def _import_function(spec: str) -> Callable:
    module, _, name = spec.partition(":")
    if not module or not name:
        raise ValueError(f"outputs.custom = {spec!r}: expected 'package.module:function'")
    return getattr(importlib.import_module(module), name)


def _deadline(seconds: Optional[float]) -> Optional[Callable[[float], None]]:
    """A master progress callback that stops the run after ``seconds`` of wall time.

    The master calls it from its own loop (about every 1 % of the run), between FMU calls, so the
    run ends as any failing run does: recorded as failed, the instances discarded. A model that
    hangs inside one step is not interrupted."""
    if not seconds:
        return None
    deadline = time.perf_counter() + float(seconds)

    def check(_fraction: float) -> None:
        if time.perf_counter() > deadline:
            raise CaseTimeout(f"timed out after {seconds:g} s (run.timeout)")

    return check


def worker_init(tmp: Optional[str] = None) -> None:
    """Pool workers leave Ctrl-C to the driver, which stops them; a crash is diagnosed in its rerun alone.

    ``tmp``: the folder this worker's temporary files (extracted SSPs and FMUs) go to; the driver
    removes it when the batch ends, also after a worker was stopped or died without cleaning up."""
    if tmp is not None:
        os.environ["TMPDIR"] = tmp
        tempfile.tempdir = tmp
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    faulthandler.disable()
    _one_blas_thread()


def isolated_main(task: Mapping, conn, fault_file: str, tmp: Optional[str] = None) -> None:
    worker_init(tmp)
    with open(fault_file, "w") as handle:  # the Python stack at a fatal signal, for the crash record
        faulthandler.enable(file=handle)
        conn.send(run_case(task))
    conn.close()


def dask_run(task: Mapping, ssp_bytes: bytes) -> dict:
    """On a Dask worker: the SSP arrives as bytes (scattered once), cached on the worker's disk by digest."""
    cache = Path(tempfile.gettempdir()) / "mast_batch_ssp"
    cache.mkdir(parents=True, exist_ok=True)
    path = cache / f"{task['ssp_sha']}{Path(task['ssp_path']).suffix or '.ssp'}"
    if not path.exists():
        atomic_write(path, ssp_bytes, sync=False)
    return run_case({**task, "ssp_path": str(path)})


def crashed_record(task: Mapping, why: str) -> dict:
    return {
        "id": task["id"],
        "status": "crashed",
        "error": why,
        "metrics": {},
        "worker": {},
        "timing": {},
        "started": None,
        "finished": time.time(),
    }
