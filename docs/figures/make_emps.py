"""Draw docs/figures/emps_residual.png and emps_friction.png: `mast diagnose` on the EMPS record (docs/emps.md).

Run from the repository root after `make build`:  .venv/bin/python docs/figures/make_emps.py
It runs the commands of docs/emps.md (import, diagnose) into a temporary folder and copies the
report's two figures here; the record is read from ../shared/data/emps/DATA_EMPS.mat (or the
path given as the first argument).
"""

from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

from mast.core.build import default_build_dir
from mast.data.importer import import_file
from mast.diagnosis import Options, diagnose

REPO = Path(__file__).resolve().parents[2]
HERE = Path(__file__).parent


def main() -> None:
    record = Path(sys.argv[1]) if len(sys.argv) > 1 else REPO.parent / "shared" / "data" / "emps" / "DATA_EMPS.mat"
    with tempfile.TemporaryDirectory(prefix="mast_emps_") as tmp:
        import_file(record, REPO / "examples" / "emps" / "map.toml", Path(tmp) / "emps")
        diagnose(
            Options(Path(tmp) / "emps", Path(tmp) / "diagnosis", str(default_build_dir() / "ssp" / "EMPS_bench.ssp"))
        )
        for name in ("residual", "friction"):
            shutil.copy(Path(tmp) / "diagnosis" / f"fig_{name}.png", HERE / f"emps_{name}.png")
            print(f"wrote {HERE / f'emps_{name}.png'}")


if __name__ == "__main__":
    main()
