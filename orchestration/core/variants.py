"""``python -m mast.core.variants``: (re)write every ssp/MAST_<variant>.ssd, the mechanism designs'
(``mast.core.designs``) and the controllers' (``mast.core.controllers``), from ssp/MAST.ssd."""
from __future__ import annotations

import sys
from pathlib import Path

from . import controllers, designs


def write_all() -> list[Path]:
    """Every variant SSD, designs first, then controllers; the paths written."""
    return designs.write_variants() + controllers.write_variants()


def main() -> int:
    for path in write_all():
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
