"""Draw docs/figures/backlash_profile.png: the phase-free deviance of backlash against its value (docs/diagnose.md).

Run from the repository root after `make build` and `.venv/bin/mast build --native`:
    .venv/bin/python docs/figures/make_backlash_profile.py
The issue's kind of plan with fast z tests (docs/figures.py DIAGNOSE_ISSUE_PLAN_FAST: z 0.7 Hz, psi 1.8 Hz, z 12 Hz
6 mm, theta 4 Hz, z 16 Hz 4.5 mm; the fast z tests hunt) with 0.07 rad of backlash hidden (seed 77, the case of
tests/test_diagnose_backlash.py) is synthesized into a temporary folder; `mast diagnose` runs on it with the backlash
scan replaced by 32 values from 0.03 to 0.15 rad and four realisations per value, and is stopped at the selection
step, where every value's ensemble is at hand (about 650 test simulations). Drawn: the deviance on all tests with one
and with four realisations per value, and pooled over the values within 2^(1/8) (two realisations each), as the
diagnosis scores a value (phasefree.pooled).
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import mast.diagnosis.nonlinear as nonlinear  # noqa: E402
import mast.diagnosis.workflow as workflow  # noqa: E402
from mast.analyses.synthesize import (
    TestSpec,  # noqa: E402
    synthesize,  # noqa: E402
)
from mast.core.build import default_build_dir  # noqa: E402
from mast.diagnosis import Options, diagnose  # noqa: E402
from mast.diagnosis.phasefree import POOL_RATIO, pooled  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
from docs_figures import figures  # noqa: E402  (docs/figures.py: the plan and the case, loaded as the tests load it)

OUT = Path(__file__).with_name("backlash_profile.png")
PLAN = tuple(TestSpec(*test) for test in figures.DIAGNOSE_ISSUE_PLAN_FAST)
(TRUTH,), SEED = (
    figures.DIAGNOSE_BACKLASH["backlash_issue_fast"][0].values(),
    figures.DIAGNOSE_BACKLASH["backlash_issue_fast"][1],
)
REALISATIONS = 4
#: a grid at 2^(1/6) over the basin's surroundings and one at 2^(1/16) across it (6 significant digits)
VALUES = sorted(
    {float(f"{0.03 * 2 ** (k / 6):.6g}") for k in range(15)}
    | {float(f"{0.052 * 2 ** (k / 16):.6g}") for k in range(17)}
)


class _Captured(Exception):
    def __init__(self, score, ensembles, names):
        super().__init__("captured")
        self.score, self.ensembles, self.names = score, ensembles, names


def _capture(score, ensembles, current, scan, names):
    raise _Captured(score, ensembles, names)


def _stage(ctx, state, effect, steps):
    return phase_free_stage(ctx, state, dataclasses.replace(effect, scan=tuple(VALUES)), steps)


phase_free_stage = nonlinear.phase_free_stage


def main() -> None:
    nonlinear.ENSEMBLE, nonlinear.leave_one_out, workflow.phase_free_stage = REALISATIONS, _capture, _stage
    with tempfile.TemporaryDirectory(prefix="mast_backlash_") as tmp:
        data = Path(tmp) / "data"
        synthesize(
            str(default_build_dir() / "ssp" / "MAST.ssp"),
            data,
            {"actuator": {"backlash": TRUTH}},
            tests=PLAN,
            direct=True,
            seed=SEED,
            log=lambda *_: None,
        )
        try:
            diagnose(
                Options(
                    data,
                    Path(tmp) / "out",
                    str(default_build_dir() / "ssp" / "native" / "MAST.ssp"),
                    figures=False,
                    direct=False,
                )
            )
        except _Captured as c:
            score, ensembles, names = c.score, c.ensembles, c.names
        else:
            raise SystemExit("backlash was not tried (the residual reached the floor before it)")
    values = [v for v in VALUES if ensembles.get(v) is not None]

    def deviance(ensemble):
        return score.fit(ensemble, names).deviance

    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    mrad = np.array(values) * 1e3
    for r, style, label in (
        (1, "x:", "one realisation per value"),
        (REALISATIONS, "o-", "four realisations per value"),
    ):
        ax.semilogy(
            mrad, [deviance({n: ensembles[v][n][:r] for n in names}) for v in values], style, ms=4, lw=1, label=label
        )
    two = {v: {n: ensembles[v][n][:2] for n in names} for v in values}
    ax.semilogy(
        mrad,
        [deviance(pooled(two, v, POOL_RATIO)) for v in values],
        "s-",
        ms=4,
        lw=1.5,
        label="pooled within 2^(1/8), two realisations per value",
    )
    floor = sum(score.floor(n) for n in names)
    ax.axvline(TRUTH * 1e3, color="k", lw=0.8, ls="--")
    ax.axhline(floor, color="grey", lw=0.8)
    ax.text(mrad[0], floor * 1.1, f"the five tests' floors ({floor:.0f})", fontsize=7, color="grey")
    ax.set_xlabel("backlash [mrad]")
    ax.set_ylabel("phase-free deviance, all five tests")
    ax.set_title(
        f"Issue plan, fast z (z 0.7/12/16 Hz, psi 1.8, theta 4 Hz), truth {TRUTH * 1e3:g} mrad (dashed), seed {SEED}",
        fontsize=8,
    )
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(OUT, dpi=110)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
