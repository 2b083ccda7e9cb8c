"""``python -m mast.core.variants``: (re)write the parameter sets of ssp/resources written from the
mechanism description files (``mast.core.description_sets``: geometry, masses, home pose, gravity
along inclined guides), then every system SSD of ssp/ that ``mast.core.systems`` generates: the
default system (ssp/MAST.ssd), the standalone one (ssp/MAST_standalone.ssd), the mechanism designs'
(``mast.core.designs``, with the standalone systems of other mechanisms: ssp/MAST_6UPS_standalone.ssd) and
the controllers' (``mast.core.controllers``). ssp/EMPS_bench.ssd, a single-axis bench and not a mechanism with
n drives, is written by hand."""

from __future__ import annotations

import sys
from pathlib import Path

from . import controllers, designs
from .description_sets import write_sets
from .systems import MAST, STANDALONE, generate


def write_all() -> list[Path]:
    """The sets written from the description files, then every generated SSD: the default and standalone systems, the
    designs, the controllers (the SSDs' topology is read from the sets); the paths written."""
    written = write_sets()
    for description in (MAST, STANDALONE):
        description.path.write_bytes(generate(description))
        written.append(description.path)
    return written + designs.write_variants() + designs.write_standalones() + controllers.write_variants()


def main() -> int:
    for path in write_all():
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
