"""Results on disk: every file written all or nothing; the batch folder, its manifest and each case's
record and kept signals."""

from __future__ import annotations

import io
import json
import math
import time
from pathlib import Path
from typing import Mapping, Sequence, Union

import numpy as np

from ..core.atomic import atomic_write
from .cases import Case, SystemInfo
from .config import BatchConfig

FORMAT_VERSION = 1
STATUSES = ("ok", "failed", "crashed")


def _json_safe(value):
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, (np.floating, np.integer)):
        return _json_safe(value.item())
    if isinstance(value, Mapping):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


def _dumps(obj) -> bytes:
    return (json.dumps(_json_safe(obj), indent=1, allow_nan=False) + "\n").encode()


class Store:
    """The batch folder (layout in the module docstring)."""

    def __init__(self, out: Union[str, Path]) -> None:
        self.out = Path(out)
        self.cases_dir = self.out / "cases"
        self._next_manifest = 0.0

    def case_file(self, case_id: str) -> Path:
        return self.cases_dir / f"{case_id}.json"

    def exists(self) -> bool:
        return (self.out / "batch.json").exists()

    def start(
        self, config: BatchConfig, cases: Sequence[Case], systems: Mapping[str, SystemInfo], sources: Mapping
    ) -> None:
        self.cases_dir.mkdir(parents=True, exist_ok=True)
        meta = {
            "format": FORMAT_VERSION,
            "name": config.name,
            "created": time.strftime("%Y-%m-%dT%H:%M:%S"),
            "config": config.to_json(),
            "ssp": {
                n: {"source": str(sources[n]), "copy": str(systems[n].path.name), "sha256": systems[n].sha256}
                for n in systems
            },
            "direct": config.direct,
            "cases": [{"id": c.id, "digest": c.digest} for c in cases],
        }
        atomic_write(self.out / "batch.json", _dumps(meta))

    def finished(self) -> dict[str, dict]:
        records = {}
        if self.cases_dir.exists():
            for path in self.cases_dir.glob("*.json"):
                try:
                    records[path.stem] = json.loads(path.read_text())
                except (OSError, ValueError):  # never written whole (cannot happen with atomic writes): run again
                    continue
        return records

    def write_case(self, case: Case, record: dict) -> dict:
        signals = record.pop("signals", None)
        entry = {**case.as_dict(), **{k: v for k, v in record.items() if k != "id"}}
        if signals:
            buffer = io.BytesIO()
            np.savez(buffer, **{name: np.asarray(values) for name, values in signals.items()})
            atomic_write(self.cases_dir / f"{case.id}.npz", buffer.getvalue())
            entry["signals_file"] = f"cases/{case.id}.npz"
        atomic_write(self.case_file(case.id), _dumps(entry))  # last: its presence means "finished"
        return entry

    def write_manifest(
        self, name: str, cases: Sequence[Case], records: Mapping[str, dict], force: bool = False
    ) -> None:
        now = time.monotonic()
        if not force and now < self._next_manifest:
            return
        counts = {s: 0 for s in STATUSES}
        rows = []
        for case in cases:
            rec = records.get(case.id)
            if rec is not None:
                counts[rec["status"]] = counts.get(rec["status"], 0) + 1
                rows.append(rec)
            else:
                rows.append({**case.as_dict(), "status": "pending"})
        manifest = {
            "name": name,
            "total": len(cases),
            **counts,
            "pending": len(cases) - sum(counts.values()),
            "updated": time.strftime("%Y-%m-%dT%H:%M:%S"),
            "cases": rows,
        }
        atomic_write(self.out / "manifest.json", _dumps(manifest), sync=force)
        # at most every 2 s, and never more than 5 % of the time (a manifest of 10 000 cases is large)
        self._next_manifest = time.monotonic() + max(2.0, 20.0 * (time.monotonic() - now))
