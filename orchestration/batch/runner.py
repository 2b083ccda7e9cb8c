"""The batch: expand the config, run the cases not finished yet, write each result the moment it
arrives, then the tables and plots; read a finished batch back."""

from __future__ import annotations

import json
import math
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Optional, Union

import numpy as np

from fmus.mechanism.topology import Coordinate

from .cases import DEFAULT_MAX_CASES, Case, SystemInfo, check_case_count, digest_of, expand, sha256
from .config import BatchConfig, BatchConfigError
from .executors import DaskCluster, LocalPool
from .progress import BatchProgress
from .store import STATUSES, Store
from .tables import group_rows, summary_rows, write_tables


@dataclass
class BatchResult:
    """What a batch produced: one record per case (as in DIR/cases/<id>.json) and one per sweep group."""

    out: Path
    name: str
    records: list[dict]
    groups: list[dict]
    ran: list[str] = field(default_factory=list)  # case ids run by this call
    skipped: list[str] = field(default_factory=list)  # finished before this call (resume)
    wall_s: float = 0.0
    interrupted: bool = False

    def count(self, status: str) -> int:
        return sum(1 for r in self.records if r.get("status") == status)

    @property
    def ok(self) -> int:
        return self.count("ok")

    @property
    def failed(self) -> int:
        return self.count("failed")

    @property
    def crashed(self) -> int:
        return self.count("crashed")

    @property
    def pending(self) -> int:
        return self.count("pending")

    def metric(self, name: str) -> np.ndarray:
        """One metric across the cases (NaN where missing)."""
        return np.array([_num(r.get("metrics", {}).get(name)) for r in self.records])

    def table(self) -> list[dict]:
        """summary.csv as a list of rows."""
        return summary_rows(self.records)


def _num(value) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else float("nan")


def run_batch(
    config: Union[str, Path, Mapping, BatchConfig],
    out: Union[str, Path],
    workers: Optional[int] = None,
    scheduler=None,
    resume: bool = False,
    retry_failed: bool = False,
    progress: Union[bool, Callable[[Mapping], None]] = True,
    plots: bool = True,
    before_case: Optional[Callable[[Mapping], None]] = None,
    custom_metrics: Optional[Callable] = None,
    mp_context=None,
    max_cases: int = DEFAULT_MAX_CASES,
) -> BatchResult:
    """Run every case of ``config`` and write the results to ``out`` (see the module docstring).

    ``workers``: local worker processes (default: the number of cores); ``scheduler``: a Dask scheduler
    address or ``distributed.Client`` instead of the local pool. ``resume``: go on with the batch in
    ``out``, skipping its finished cases (``retry_failed``: run its failed and crashed cases again).
    ``progress``: True for the progress bar on stderr, or a callable given the counts after each case.
    ``before_case(task)`` and ``custom_metrics(result, task) -> {name: value}`` run in the worker for
    each case (module-level functions: they are pickled). ``max_cases``: a config that expands to more cases is
    refused (BatchConfigError) before ``out`` is made. Returns a :class:`BatchResult`; an
    interrupted batch (Ctrl-C) raises KeyboardInterrupt after saving what finished.
    """
    if not isinstance(config, BatchConfig):
        config = BatchConfig.load(config) if isinstance(config, (str, Path)) else BatchConfig.from_dict(config)
    check_case_count(config, max_cases)
    Path(out).mkdir(parents=True, exist_ok=True)
    with _Lock(Path(out) / ".lock"):
        return _run_batch(
            config,
            Path(out),
            workers,
            scheduler,
            resume,
            retry_failed,
            progress,
            plots,
            before_case,
            custom_metrics,
            mp_context,
            max_cases,
        )


class _Lock:
    """One driver per batch folder: a second `mast batch` on the same --out stops at once."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.handle = None

    def __enter__(self) -> "_Lock":
        self.handle = open(self.path, "a+")
        try:
            import fcntl

            fcntl.flock(self.handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except ImportError:  # not POSIX: no lock
            pass
        except OSError:
            self.handle.close()
            raise BatchConfigError(f"{self.path.parent}: another mast batch is running on this folder") from None
        return self

    def __exit__(self, *exc) -> None:
        self.handle.close()  # closing releases the lock


def _run_batch(
    config: BatchConfig,
    out: Path,
    workers,
    scheduler,
    resume,
    retry_failed,
    progress,
    plots,
    before_case,
    custom_metrics,
    mp_context,
    max_cases,
) -> BatchResult:
    t0 = time.perf_counter()
    store = Store(out)
    if store.exists() and not resume:
        raise BatchConfigError(f"{store.out} already holds a batch: resume it (--resume) or choose another --out")
    if resume and not store.exists():
        resume = False  # nothing to resume: a fresh start
    sources = dict(config.ssp)
    inputs_dir = store.out / "inputs"
    inputs_dir.mkdir(parents=True, exist_ok=True)
    systems: dict[str, SystemInfo] = {}
    for name, source in sources.items():
        copy = inputs_dir / f"{name}{Path(source).suffix}"
        if not copy.exists():
            if not Path(source).exists():
                raise BatchConfigError(f"ssp '{name}': {source} does not exist (run `mast build`?)")
            if Path(source).suffix == ".ssd":  # a source folder: run it where it is
                copy = Path(source).resolve()
            else:
                tmp = copy.with_suffix(".tmp")
                shutil.copyfile(source, tmp)
                os.replace(tmp, copy)
        elif Path(source).exists() and sha256(Path(source)) != sha256(copy):
            print(
                f"warning: {source} changed since this batch started; the batch goes on with its copy {copy}",
                file=sys.stderr,
            )
        systems[name] = SystemInfo.read(copy)
    cases = expand(config, systems, max_cases)
    by_id = {c.id: c for c in cases}
    finished = store.finished() if resume else {}
    for case_id, rec in finished.items():
        if case_id in by_id and rec.get("digest") != by_id[case_id].digest:
            raise BatchConfigError(
                f"{store.out}: case {case_id} was run with other settings than the config gives now "
                "(parameters, motion, SSP or outputs changed); start a new batch in another folder"
            )
    if retry_failed:
        finished = {k: v for k, v in finished.items() if v.get("status") == "ok"}
    records: dict[str, dict] = {k: v for k, v in finished.items() if k in by_id}
    store.start(config, cases, systems, sources)
    todo = [c for c in cases if c.id not in records]
    skipped = [c.id for c in cases if c.id in records]
    show = BatchProgress(config.name) if progress is True else (progress or None)
    counts = {s: sum(1 for r in records.values() if r["status"] == s) for s in STATUSES}
    ran: list[str] = []

    def state() -> dict:
        return {"total": len(cases), "done": len(records), "skipped": len(skipped), **counts}

    def on_result(record: dict) -> None:
        case = by_id[record["id"]]
        entry = store.write_case(case, record)
        records[case.id] = entry
        counts[entry["status"]] += 1
        ran.append(case.id)
        store.write_manifest(config.name, cases, records)
        if show:
            show(state())

    tasks = [_task(config, c, systems[c.ssp], before_case, custom_metrics) for c in todo]
    interrupted = False
    try:
        if tasks:
            if show:
                show(state())
            executor = DaskCluster(scheduler) if scheduler is not None else LocalPool(workers, mp_context)
            executor.run(tasks, on_result)
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        store.write_manifest(config.name, cases, records, force=True)
        ordered = [records.get(c.id, {**c.as_dict(), "status": "pending"}) for c in cases]
        groups = group_rows(ordered)
        write_tables(store.out, ordered, groups)
        if plots and not interrupted and any(r["status"] == "ok" for r in ordered):
            try:
                from .plots import plot_batch

                plot_batch(store.out / "plots", ordered, groups, config.plots)
            except Exception as err:  # a figure is not worth losing the batch summary
                print(f"warning: plots not written: {type(err).__name__}: {err}", file=sys.stderr)
    return BatchResult(store.out, config.name, ordered, groups, ran, skipped, time.perf_counter() - t0, interrupted)


def _task(config: BatchConfig, case: Case, info: SystemInfo, before_case, custom_metrics) -> dict:
    motion = None
    if case.motion is not None:
        m = case.motion
        motion = {
            **m,
            "amplitude_si": math.radians(m["amplitude"]) if Coordinate(m["axis"]).angular else m["amplitude"],
        }
    return {
        "id": case.id,
        "ssp_path": str(info.path),
        "ssp_sha": info.sha256 or digest_of(str(info.path)),
        "direct": config.direct,
        "parameters": case.parameters,
        "motion": motion,
        "stop_time": case.stop_time,
        "record_step": case.record_step,
        "window": case.window,
        "keep": list(config.keep),
        "metrics": list(config.metrics),
        "timeout": config.timeout,
        "before_case": before_case,
        "custom": custom_metrics or config.custom,
    }


def read_batch(out: Union[str, Path]) -> BatchResult:
    """The results of a batch folder (finished or not) as a :class:`BatchResult`."""
    out = Path(out)
    try:
        manifest = json.loads((out / "manifest.json").read_text())
    except (OSError, ValueError) as err:
        raise FileNotFoundError(f"{out}: no readable manifest.json ({err})") from None
    finished = Store(out).finished()  # the per-case files are the truth; the manifest may lag
    records = [finished.get(r["id"], r) for r in manifest["cases"]]
    return BatchResult(out, manifest["name"], records, group_rows(records))
