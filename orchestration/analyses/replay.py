"""`mast replay SSP --measured DIR --out OUT`: a model driven by a record's commands and inputs.

Every test of the record folder (mast.data.record) is simulated with its command and
injected columns on the model's system inputs (zero-order hold of the samples); each
measured column (position, velocity, effort) is compared with the model output its
``model`` entry names, and with the command that drove it:

    relative error  100 ||y - y_sim|| / ||y||                (the EMPS benchmark's figure)
    fit             100 (1 - ||y - y_sim|| / ||y - mean(y)||)  (the system identification toolboxes' fit)

Sampled outputs (``sampled``: the value a controller computes at sample t_k from the
measurements at t_k) are read from the co-simulation where it publishes that sample's
value: one sample later (a master steps the controller at t_k and publishes after the
step). An effort is compared with what the drive applies (``model``: the controller's
output after its saturation plus the injected inputs), or, when the record says it was
logged before the injection (``tap = "before_injection"``), with the model output
``model`` + "_before_injection" (mast.data.record). Writes OUT/replay.json, OUT/replay.csv
(time, measured and simulated columns) and OUT/replay_<test>.png.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Mapping, Optional, Sequence, Union

import numpy as np

from fmus.common.parameters import Value

from ..data.record import MEASURED, Record, RecordError, RecordReplay, RecordSet, load_records


def relative_error_pct(y: np.ndarray, y_sim: np.ndarray) -> float:
    """100 ||y - y_sim|| / ||y||."""
    den = float(np.linalg.norm(y))
    return 100.0 * float(np.linalg.norm(y - y_sim)) / den if den > 0 else float("nan")


def fit_pct(y: np.ndarray, y_sim: np.ndarray) -> float:
    """100 (1 - ||y - y_sim|| / ||y - mean(y)||)."""
    den = float(np.linalg.norm(y - np.mean(y)))
    return 100.0 * (1.0 - float(np.linalg.norm(y - y_sim)) / den) if den > 0 else float("nan")


def initial_parameters(ssp: Union[str, Path], record: Record) -> dict[str, dict[str, Value]]:
    """Start the model where the record starts: every component with a parameter ``q_0`` (initial
    position) gets the first sample of the measured position it is compared with, or of its command."""
    from ..core.ssp import SSPArchive

    positions = record.of_kind("position")
    if not positions:
        return {}
    q0 = float(record.values[positions[0].name][0])
    out: dict[str, dict[str, Value]] = {}
    with SSPArchive(ssp) as archive:
        for name, comp in archive.system.components.items():
            if "q_0" in comp.parameters:
                out[name] = {"q_0": q0}
    return out


def _check_taps(components: Mapping, measured: Sequence, record: Record, ssp: Union[str, Path]) -> None:
    """An effort logged before the injection is compared with the model's output of that tap: a RecordError
    names the signal, the tap and the component's declared outputs when the system structure has none."""
    for s in measured:
        element, _, connector = s.model_output.rpartition(".")
        comp = components.get(element)
        if s.tap == "applied" or comp is None or connector in comp.outputs:
            continue  # an unknown component, or the applied tap: the master names it
        raise RecordError(
            f"{record.file.name}: signal {s.name} is logged at tap {s.tap!r}: it is compared with the "
            f"model output {s.model_output} ({s.model} at that tap), which {Path(ssp).name} does not "
            f"have; the outputs of {element}: {', '.join(comp.outputs)}"
        )


def simulate_record(
    ssp: Union[str, Path],
    record: Record,
    parameters: Optional[Mapping[str, Mapping]] = None,
    direct: bool = True,
    extra: Sequence[str] = (),
    stop_time: Optional[float] = None,
) -> dict[str, np.ndarray]:
    """The model's outputs named by the record's measured signals, at the record's samples (sampled outputs
    one sample later, module docstring); keys: signal names, and the ``extra`` outputs (ELEMENT.CONNECTOR)
    at the samples. ``stop_time``: simulate the record only up to there (the samples before it)."""
    from ..core.run import simulate
    from ..core.ssp import SSPArchive

    measured = record.of_kind(*MEASURED)
    with SSPArchive(ssp) as archive:
        inputs = list(archive.system.system_inputs)
        _check_taps(archive.system.components, measured, record, ssp)
    params = initial_parameters(ssp, record)
    for comp, values in (parameters or {}).items():
        params.setdefault(comp, {}).update(values)
    dt = record.sample_time
    end = record.duration if stop_time is None else min(float(stop_time), record.duration)
    time = record.time[record.time <= end + 1e-9]
    res = simulate(
        ssp,
        RecordReplay(record, inputs),
        float(time[-1]) + dt,
        parameters=params,
        record=sorted({s.model_output for s in measured} | set(extra)),
        record_step=None,
        direct=direct,
    )
    out = {}
    for s in measured:
        at = time + (dt if s.sampled else 0.0)
        out[s.name] = np.interp(at, res.time, res[s.model_output])
    for name in extra:
        out[name] = np.interp(time, res.time, res[name])
    return out


def compare(record: Record, simulated: Mapping[str, np.ndarray]) -> dict:
    """Per measured signal: kind, relative error and fit [%] over the record after its settle time (the
    command and injected columns drive the model: they are not compared)."""
    keep = record.time >= record.settle_s - 1e-12
    out = {}
    for s in record.of_kind(*MEASURED):
        y, ys = record.values[s.name][keep], simulated[s.name][keep]
        out[s.name] = {
            "kind": s.kind,
            "unit": s.unit,
            "model": s.model_output,
            **({"tap": s.tap} if s.kind == "effort" else {}),
            "relative_error_pct": relative_error_pct(y, ys),
            "fit_pct": fit_pct(y, ys),
            "rms_error": float(np.sqrt(np.mean((y - ys) ** 2))),
        }
    return out


def plot_replay(record: Record, simulated: Mapping[str, np.ndarray], path: Path, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    measured = record.of_kind(*MEASURED)
    fig, axes = plt.subplots(
        len(measured), 2, figsize=(12, 2.8 * len(measured)), squeeze=False, gridspec_kw={"width_ratios": [3, 1.2]}
    )
    for row, s in zip(axes, measured):
        y, ys = record.values[s.name], simulated[s.name]
        row[0].plot(record.time, y, lw=0.8, label="measured")
        row[0].plot(record.time, ys, lw=0.8, label="model")
        row[0].plot(record.time, y - ys, lw=0.6, label="measured - model")
        row[0].set_ylabel(f"{s.name} [{s.unit}]")
        row[0].legend(loc="upper right", fontsize=7)
        row[0].set_title(
            f"{s.name} ({s.kind}): relative error {relative_error_pct(y, ys):.3g} %, fit {fit_pct(y, ys):.3g} %",
            fontsize=9,
        )
        lo, hi = float(min(y.min(), ys.min())), float(max(y.max(), ys.max()))
        row[1].plot(y, ys, ",", alpha=0.5)
        row[1].plot([lo, hi], [lo, hi], "k--", lw=0.6)
        row[1].set_xlabel("measured")
        row[1].set_ylabel("model")
    axes[-1][0].set_xlabel("time [s]")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def replay(
    ssp: Union[str, Path],
    measured: Union[str, Path, RecordSet],
    out: Union[str, Path],
    parameters: Optional[Mapping[str, Mapping]] = None,
    direct: bool = True,
    figures: bool = True,
) -> dict:
    """Replay every test of ``measured`` on ``ssp``; write OUT/replay.json, replay.csv, figures. With one test
    ``signals`` is that test's table; with several, ``signals`` holds the first and ``tests`` every one."""
    records = measured if isinstance(measured, RecordSet) else load_records(measured)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tests = {}
    for rec in records.tests:
        sim = simulate_record(ssp, rec, parameters, direct)
        tests[rec.name] = compare(rec, sim)
        names = list(sim)
        table = np.column_stack([rec.time] + [c for n in names for c in (rec.values[n], sim[n])])
        header = ["time"] + [c for n in names for c in (n, f"{n}_model")]
        suffix = "" if len(records.tests) == 1 else f"_{rec.name}"
        np.savetxt(out / f"replay{suffix}.csv", table, delimiter=",", header=",".join(header), comments="", fmt="%.12g")
        if figures:
            plot_replay(rec, sim, out / f"replay_{rec.name}.png", f"{Path(ssp).name} on {records.machine}: {rec.name}")
    doc = {
        "model": str(ssp),
        "measured": str(records.folder),
        "machine": records.machine,
        "signals": tests[records.tests[0].name],
        "tests": tests,
    }
    (out / "replay.json").write_text(json.dumps(doc, indent=2))
    return doc
