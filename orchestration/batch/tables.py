"""Tables of a batch: a row per case (summary.csv), a row per frequency sweep (groups.csv); a listing
of the cases."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Mapping, Sequence

from ..analyses.metrics import sweep_metrics
from .cases import Case
from .store import atomic_write


def summary_rows(records: Sequence[Mapping]) -> list[dict]:
    """One row per case: id, status, ssp, motion, sample, the varied inputs, the metrics, time, error."""
    input_keys = list(dict.fromkeys(k for r in records for k in r.get("inputs", {})))
    metric_keys = list(dict.fromkeys(k for r in records for k in r.get("metrics", {}) or {}))
    rows = []
    for r in records:
        motion = r.get("motion") or {}
        row = {
            "id": r["id"],
            "status": r["status"],
            "ssp": r.get("ssp"),
            "axis": motion.get("axis"),
            "amplitude": motion.get("amplitude"),
            "frequency_Hz": motion.get("frequency"),
            "sample": r.get("sample"),
        }
        row.update({k: r.get("inputs", {}).get(k) for k in input_keys})
        row.update({k: (r.get("metrics") or {}).get(k) for k in metric_keys})
        row["case_s"] = (r.get("timing") or {}).get("case_s")
        row["error"] = (r.get("error") or "").splitlines()[0][:300] if r.get("error") else None
        rows.append(row)
    return rows


def group_rows(records: Sequence[Mapping]) -> list[dict]:
    """Per sweep group (same SSP, parameters and motion but the frequency): bandwidth and resonance."""
    groups: dict[str, list[Mapping]] = {}
    for r in records:
        if r.get("motion") and r["motion"].get("frequency"):
            groups.setdefault(r.get("group", ""), []).append(r)
    rows = []
    for key, members in groups.items():
        if len({m["motion"]["frequency"] for m in members}) < 2:
            continue
        first = members[0]
        ok = [m for m in members if m["status"] == "ok" and "magnitude" in (m.get("metrics") or {})]
        row = {
            "group": key,
            "ssp": first.get("ssp"),
            "axis": first["motion"]["axis"],
            "amplitude": first["motion"]["amplitude"],
            "sample": first.get("sample"),
            **{k: v for k, v in first.get("inputs", {}).items()},
            "cases": len(members),
            "ok": len(ok),
        }
        row.update(
            sweep_metrics(
                [m["motion"]["frequency"] for m in ok],
                [m["metrics"]["magnitude"] for m in ok],
                [m["metrics"]["phase_deg"] for m in ok],
            )
        )
        row["frequencies_Hz"] = [m["motion"]["frequency"] for m in ok]
        row["magnitudes"] = [m["metrics"]["magnitude"] for m in ok]
        row["phases_deg"] = [m["metrics"]["phase_deg"] for m in ok]
        rows.append(row)
    return rows


def write_tables(out: Path, records: Sequence[Mapping], groups: Sequence[Mapping]) -> None:
    _write_csv(out / "summary.csv", summary_rows(records))
    if groups:
        _write_csv(out / "groups.csv", [{k: v for k, v in g.items() if not isinstance(v, list)} for g in groups])


def _write_csv(path: Path, rows: Sequence[Mapping]) -> None:
    keys = list(dict.fromkeys(k for r in rows for k in r))
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=keys, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if row.get(k) is None else _fmt(row.get(k))) for k in keys})
    atomic_write(path, buffer.getvalue().encode())


def _fmt(value) -> str:
    if isinstance(value, float):
        return "nan" if value != value else f"{value:.10g}"
    return str(value)


def describe(cases: Sequence[Case], limit: int = 20) -> str:
    """A short listing of the cases (``mast batch --dry-run``)."""
    lines = [f"{len(cases)} case(s)"]
    for case in cases[:limit]:
        m = case.motion
        motion = f"{m['axis']} {m['amplitude']:g} @ {m['frequency']:g} Hz" if m else "no motion"
        inputs = ", ".join(f"{k}={_fmt(v) if isinstance(v, float) else v}" for k, v in case.inputs.items())
        lines.append(f"  {case.id}  ssp={case.ssp}  {motion}  stop {case.stop_time:g} s  {inputs}")
    if len(cases) > limit:
        lines.append(f"  ... {len(cases) - limit} more")
    return "\n".join(lines)
