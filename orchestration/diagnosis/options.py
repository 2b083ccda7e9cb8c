"""What ``mast diagnose`` is asked to do (``Options``) and the nominal model's overrides (``--model``): shared by
the workflow on measured data (``workflow``) and on record folders (``records``) and by the report."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Optional, Sequence

from .effects import LIBRARY
from .resimulation import DiagnosisError


@dataclass
class Options:
    measured: Path
    out: Path
    ssp: str
    model: Optional[str] = None  # a parameter set (.ssv path or name in the SSP's resources)
    holdout: Optional[Sequence[str]] = None
    holdout_fraction: Optional[float] = None  # records (mast import) without held-out tests: the share held out
    workers: int = 2
    direct: bool = True
    native: bool = False  # re-simulate on the SSP's native variant (compiled FMUs, mast build --native)
    library: Sequence[str] = tuple(e.key for e in LIBRARY)
    figures: bool = True
    #: overrides of the nominal model in every re-simulation, {component: {parameter: value}} (``--specimen``: the
    #: mechanism's payload the measured machine carried)
    parameters: Optional[Mapping[str, Mapping]] = None


def with_parameters(base: dict, opt: Options) -> dict:
    """The re-simulations' overrides ``base`` with ``opt.parameters`` merged in per component (``--specimen``)."""
    for component, values in (opt.parameters or {}).items():
        base.setdefault(component, {}).update(values)
    return base


def model_overrides(ssp: str, model: Optional[str]) -> dict:
    """Actuator parameter overrides of the nominal model (``--model``): an .ssv file, or the name of a
    parameter set inside the SSP (resources/NAME.ssv) or of the project's sources (ssp/resources/NAME.ssv)."""
    if not model:
        return {}
    from ..core.build import REPO
    from ..core.ssp import SSPArchive
    from ..core.ssv import parse_ssv

    sources = REPO / "ssp" / "resources"
    path = Path(model)
    if path.exists():
        return {k: v.value for k, v in parse_ssv(path).items()}
    name = model if model.endswith(".ssv") else f"{model}.ssv"
    with SSPArchive(ssp) as archive:
        res = archive.ssd.parent / "resources"
        for candidate in (res / name, res / "parameters" / name, sources / name):
            if candidate.exists():
                return {k: v.value for k, v in parse_ssv(candidate).items()}
        have = sorted({p.stem for p in res.rglob("*.ssv")} | {p.stem for p in sources.glob("*.ssv")})
    raise DiagnosisError(
        f"--model {model}: neither a file nor a parameter set of the SSP or of ssp/resources (known: {', '.join(have)})"
    )
