"""Batch co-simulation: hundreds of cases from one config, on a local process pool or a Dask cluster.

A config (TOML, YAML or JSON; docs/batch.md) names the SSP(s), the cases
(lists, grids, random samples with seeds, motions, SSP variants) and the
outputs (signals to keep, metrics to compute). :func:`run_batch` (``mast batch``)
expands it into cases, runs every case in a worker process and writes each
case's result atomically the moment it arrives:

    DIR/batch.json          the config, the cases (id, digest) and where the SSPs came from
    DIR/inputs/<ssp>.ssp    the SSPs the batch runs (copied once: a rebuild does not mix results)
    DIR/cases/<id>.json     one per finished case: parameters, motion, status, metrics, error, timings
    DIR/cases/<id>.npz      the kept signals of that case (``outputs.keep``), if any
    DIR/manifest.json       every case, finished or pending, in one file
    DIR/summary.csv         one row per case: status, varied inputs, metrics
    DIR/groups.csv          per frequency sweep (same system, axis, amplitude): bandwidth, resonance
    DIR/plots/*.png         metrics against the swept parameters

Workers. Each worker process keeps one :class:`mast.core.session.Session` per SSP: the
FMUs are extracted and instantiated once, and reset (fmi2Reset) between cases.
A case that raises, diverges (NaN) or times out is recorded as ``failed``; a
case that kills its worker (segmentation fault, ``os._exit``) is recorded as
``crashed``: the pool is restarted and the cases that were running beside it
are run again, each alone, so only the culprit is blamed. The batch goes on.

Resume. ``cases/<id>.json`` is written last (temp file, fsync, rename), so it
exists only for a finished case; ``resume=True`` skips those (when their
digest still matches the config) and runs the rest: an interrupted batch never
repeats or loses a finished case. Raising ``cases.random.samples`` and resuming
extends a Monte Carlo study: the first samples keep their ids and values.

Cluster. ``scheduler="tcp://host:8786"`` (or a ``distributed.Client``) runs the
same cases on an existing Dask cluster; the SSPs travel to the workers with the
tasks, each worker keeps its sessions between tasks. Start workers with one
thread each (``dask worker ADDRESS --nthreads 1 --nworkers N``): pythonfmu FMUs
share one interpreter per process, so processes, not threads, run cases side
by side.
"""

from __future__ import annotations

from .cases import DEFAULT_MAX_CASES, Case, SystemInfo, count_cases, expand
from .config import BatchConfig, BatchConfigError
from .runner import BatchResult, read_batch, run_batch
from .store import FORMAT_VERSION, STATUSES
from .tables import describe, group_rows, summary_rows
from .worker import run_case

__all__ = [
    "DEFAULT_MAX_CASES",
    "FORMAT_VERSION",
    "STATUSES",
    "BatchConfig",
    "BatchConfigError",
    "BatchResult",
    "Case",
    "SystemInfo",
    "count_cases",
    "describe",
    "expand",
    "group_rows",
    "read_batch",
    "run_batch",
    "run_case",
    "summary_rows",
]
