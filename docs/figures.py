"""The result figures the documentation states, generated into the pages: ``python docs/figures.py``.

A figure in a page (README.md, docs/**/*.md) is marked where it stands, invisible in the rendered page::

    **<!-- figure reproduce.predictions_within -->10<!-- /figure --> of 18 predictions**

``KEY`` names an entry of ``FIGURES`` below: the source that computes it, its format and the tolerance a
test compares the page with. ``python docs/figures.py`` computes every source the pages use (``--source
NAME`` only those; ``reproduce`` runs ``mast reproduce``: minutes) and writes the values into the pages;
``--check`` writes nothing and lists the figures that differ (exit 1). The tests compare the pages with
the code too (tests/test_docs.py for the cheap sources, tests/test_reproduce.py for ``reproduce`` on the
run it makes anyway) and fail with the page, the line, both values and this command.
"""

from __future__ import annotations

import argparse
import atexit
import functools
import json
import math
import re
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator, Mapping

ROOT = Path(__file__).resolve().parents[1]
MARKER = re.compile(r"<!-- figure (?P<key>[\w\-]+(?:\.[\w\-]+)+) -->(?P<value>.*?)<!-- /figure -->")
REGENERATE = "python docs/figures.py"


@dataclass(frozen=True)
class Figure:
    """One stated figure: ``source`` computes a dict of named values, ``pick`` takes this one from it, ``fmt``
    writes it, and a page agrees with the code when it states the value so written, or one within ``tolerance``
    (absolute, in the figure's unit: what may differ between machines)."""

    source: str
    pick: Callable[[Mapping], float]
    fmt: str
    tolerance: float = 0.0


def _row(key: str) -> Callable[[Mapping], float]:
    return lambda values: values["rows"][key]["ours"]


def _phase(motion: str) -> Callable[[Mapping], float]:
    return _row(f"position_phase/{motion}/10Hz")


def _magnitude_pct(motion: str) -> Callable[[Mapping], float]:
    return lambda values: 100 * values["rows"][f"position_magnitude/{motion}/10Hz"]["ours"]


def _named(source: str, rows: tuple[tuple[str, str, float], ...]) -> dict[str, Figure]:
    """``source.<name>`` for each (name, fmt, tolerance) of ``rows``: the value ``name`` of the source's flat dict."""
    return {f"{source}.{name}": Figure(source, (lambda n: lambda v: v[n])(name), fmt, tol) for name, fmt, tol in rows}


FIGURES: dict[str, Figure] = {
    # mast reproduce (docs/reproduction.md): the headline counts and the 10 Hz positions
    **{
        f"reproduce.{name}": Figure("reproduce", (lambda n: lambda v: v["summary"][n])(name), "{:d}")
        for name in ("predictions_within", "predictions", "fits_within", "fits", "reuses_within", "reuses", "runs")
    },
    **{f"reproduce.phase_10Hz_{m}": Figure("reproduce", _phase(m), "{:.2f}", 0.02) for m in ("z", "psi", "theta")},
    **{
        f"reproduce.magnitude_10Hz_{m}": Figure("reproduce", _magnitude_pct(m), "{:.1f}", 0.05)
        for m in ("z", "psi", "theta")
    },
    # the default system's controller gains (ssp/MAST.ssd, docs/controller.md)
    **{
        f"ssd.controller.{g}": Figure("ssd", (lambda v, g=g: v["controller"][g]), "{:.4g}")
        for g in ("k_v", "k_p", "k_i")
    },
    # the designs' workspaces (`mast workspace DESIGN`, docs/workspace.md; the --quick grid of `mast compare`, README)
    **{
        f"{grid}.{d}.{what}": Figure(grid, (lambda v, d=d, w=what: v[d][w]), fmt, tol)
        # a volume may differ by a grid node or two between machines (a node on the margin's edge): 0.005 m deg^2
        # each on the default grid, 0.4 on the quick one
        for grid, fmt_volume, cells in (("workspace", "{:.0f}", 0.5), ("workspace_quick", "{:.1f}", 0.8))
        for d in ("3PRS_T", "3PRS_120", "3PRS_inclined")
        for what, fmt, tol in (
            ("volume_m_deg2", fmt_volume, cells),
            ("smallest_margin", "{:.3f}", 0.0),
            ("worst_dexterity", "{:.1f}", 0.0),
        )
    },
    # the designs' workspaces through home and their margins at home on the default grid (docs/designs/README.md): a
    # range through home may move by one grid node (1 deg) between machines, like the volume
    **{
        f"workspace.{d}.{what}": Figure("workspace", (lambda v, d=d, w=what: v[d][w]), fmt, tol)
        for d in ("3PRS_T", "3PRS_120", "3PRS_inclined")
        for what, fmt, tol in (
            ("psi_home_lo_deg", "{:.0f}", 1.0),
            ("psi_home_hi_deg", "{:.0f}", 1.0),
            ("theta_home_lo_deg", "{:.0f}", 1.0),
            ("theta_home_hi_deg", "{:.0f}", 1.0),
            ("margin_home", "{:.3f}", 0.0),
            ("singularity_home_m", "{:.3f}", 0.0),
        )
    },
    # the designs' singularity margins at home (docs/mechanism.md)
    **{
        f"designs.{d}.{what}": Figure("designs", (lambda v, d=d, w=what: v[d][w]), fmt, 0.005)
        for d in ("3PRS_T", "3PRS_120", "3PRS_inclined")
        for what, fmt in (("parallel", "{:.3g}"), ("inverse", "{:.3g}"), ("dexterity", "{:.3g}"))
    },
    # paper Fig. 10's argument (docs/designs/README.md): the inertias per axis and the mechanism's mass matrix at home
    **_named(
        "inertias",
        (
            ("motor_side_kg", "{:.1f}", 0.0),
            ("guide_side_kg", "{:.1f}", 0.0),
            ("M_min_kg", "{:.2f}", 0.0),
            ("M_max_kg", "{:.1f}", 0.0),
            ("M_min_pct", "{:.1f}", 0.0),
            ("M_max_pct", "{:.1f}", 0.0),
        ),
    ),
    # the drives' datasheet ratings as docs/sizing.md restates them, in the page's units, from the set mast sizing
    # reads (ssp/resources/drive_ratings.ssv, SI): the same number, no tolerance (a unit conversion's rounding
    # stays below the printed digit)
    **{
        f"ratings.{name}": Figure("ratings", (lambda n, k, o: lambda v: v[n] * k + o)(name, scale, offset), fmt)
        for name, scale, offset, fmt in (
            ("tau_N", 1e3, 0.0, "{:.0f}"),
            ("i_N", 1.0, 0.0, "{:g}"),
            ("tau_stall", 1.0, 0.0, "{:.2f}"),
            ("n_max", 30 / math.pi, 0.0, "{:.0f}"),
            ("R_th1", 1.0, 0.0, "{:g}"),
            ("R_th2", 1.0, 0.0, "{:g}"),
            ("tau_w", 1.0, 0.0, "{:g}"),
            ("tau_s", 1.0, 0.0, "{:g}"),
            ("T_w_max", 1.0, -273.15, "{:.0f}"),
            ("tau_gear_cont", 1.0, 0.0, "{:g}"),
            ("tau_gear_int", 1.0, 0.0, "{:g}"),
            ("n_gear_max", 30 / math.pi, 0.0, "{:.0f}"),
            ("eta_gear", 100.0, 0.0, "{:.0f}"),
            ("F_guide_max", 1.0, 0.0, "{:.0f}"),
            ("v_guide_max", 1.0, 0.0, "{:g}"),
            ("i_amp_cont", 1.0, 0.0, "{:g}"),
            ("i_amp_peak", 1.0, 0.0, "{:g}"),
            ("T_ambient", 1.0, -273.15, "{:.0f}"),
            ("alpha_Cu", 1.0, 0.0, "{:g}"),
        )
    },
    # what `mast build` writes and the limits an untrusted archive meets (README, docs/interfaces.md): counts and
    # sizes the code defines, stated exactly
    "build.fmus": Figure("build", lambda v: v["fmus"], "{:d}"),
    **{
        f"build.{name}": Figure("build", (lambda n: lambda v: v[n])(name), "{:,d}" if name == "max_entries" else "{:g}")
        for name in ("max_archive_GiB", "max_entry_MiB", "max_entries", "ratio_floor_MiB", "max_ratio")
    },
    # `mast replay` of the EMPS record (docs/emps.md) with the benchmark's published estimates and with the nominal
    # model: relative errors [%] (and the force fit [%]). Tolerances far below the differences the page reasons
    # from (force: 5.41 against 5.56 % for a 0.1 or 0.2 ms computation delay; position: 0.0012 against the
    # benchmark's 0.014 %), far above what another machine's floats move in a 24.84 s closed loop
    **{
        f"emps.{model}.{what}": Figure("emps", (lambda m, w: lambda v: v[m][w])(model, what), fmt, tol)
        for model in ("published", "nominal")
        for what, fmt, tol in (("q_m", "{:.3g}", 0.0002), ("force", "{:.3g}", 0.02), ("force_fit", "{:.1f}", 0.05))
    },
    # the 6-UPS hexapod (docs/designs/6ups.md): margins and static forces at home, its workspaces on the coarse grid
    # HEXAPOD_GRID (a volume may differ by a grid node or two between machines)
    **_named(
        "hexapod",
        (
            ("parallel", "{:.3f}", 0.0),
            ("inverse", "{:.3f}", 0.0),
            ("dexterity", "{:.2f}", 0.0),
            ("F_home_odd", "{:.2f}", 0.0),
            ("F_home_even", "{:.2f}", 0.0),
            ("F_home_massless", "{:.3f}", 0.0),
            ("volume_xyz_L", "{:.1f}", 0.02),
            ("volume_angles_deg3", "{:.0f}", 60.0),
            ("volume_z_psi_theta_m_deg2", "{:.0f}", 0.4),
        ),
    ),
    # the 6-UPS as a system (docs/designs/6ups.md): its run z, 3 mm at 2 Hz, 0.4 s, Python FMUs (HEXAPOD_RUN);
    # checked by tests/test_hexapod_system.py on the run it makes; tolerances: another machine's floats in a closed loop
    **_named(
        "hexapod_run",
        (
            ("z_error_mm", "{:.3f}", 0.002),
            ("current_peak_A", "{:.2f}", 0.01),
            ("torque_peak_mNm", "{:.1f}", 0.2),
            ("phi_error_urad", "{:.2f}", 0.02),
        ),
    ),
    # `mast animate`'s page for the default system's `make run` motion (docs/animate.md): frames, sizes [MB, kB]; a
    # size may move by a few bytes between machines (a coordinate's rounding to 1 um flipping)
    "animate.frames": Figure("animate", lambda v: v["frames"], "{:d}"),
    **_named(
        "animate",
        (
            ("page_MB", "{:.2f}", 0.01),
            ("plotly_MB", "{:.2f}", 0.0),
            ("figure_MB", "{:.2f}", 0.01),
            ("frame_kB", "{:.0f}", 0.5),
            ("minute_MB", "{:.0f}", 0.5),
        ),
    ),
}

#: the 6-UPS system run of docs/designs/6ups.md: (axis, amplitude [m], frequency [Hz], stop time [s])
HEXAPOD_RUN = ("z", 0.003, 2.0, 0.4)
#: the compact test plan of docs/diagnose.md's "Every effect alone" and of tests/test_diagnose.py: (motion, amplitude
#: [m or rad], frequency [Hz], duration [s], settling [s]) of each test, every second in frequency order held out
DIAGNOSE_PLAN = (
    ("z", 0.005, 0.6, 2.0, 0.3),
    ("theta", math.radians(0.8), 1.5, 1.0, 0.3),
    ("z", 0.005, 3.0, 1.0, 0.3),
    ("z", 0.005, 7.0, 0.8, 0.3),
)
#: the effects hidden alone on DIAGNOSE_PLAN (docs/diagnose.md, tests/test_diagnose.py): case -> (the truth set on
#: every actuator, the seed of the synthetic noise)
DIAGNOSE_CASES = {
    "nothing": ({}, 3),
    "paper": ({"tau_c": 0.0718, "J1_scale": 1 / 1.56}, 1),
    "coulomb": ({"tau_c": 0.035}, 10),
    "stribeck": ({"tau_s": 0.02, "omega_s": 3.0}, 12),
    "inertia_motor": ({"J1_scale": 0.8}, 13),
    "inertia_guide": ({"J_guide": 6.8e-4}, 14),
    "carriage_mass": ({"M_load": 3.5}, 15),
    "offset": ({"tau_offset": 0.01}, 16),
}
# their figures: each fitted parameter to 0.1 % of its truth (far above what another machine's floats move in a fit by
# re-simulation, 1e-6, below the fit's own error the table shows), the held-out tests' torque NRMSE [%] before and
# after and its noise floor to the printed digit
FIGURES.update(
    {
        **{
            f"diagnose_{case}.{name}": Figure(
                f"diagnose_{case}", (lambda n: lambda v: v["fitted"][n])(name), "{:.4g}", 1e-3 * abs(truth)
            )
            for case, (truths, _) in DIAGNOSE_CASES.items()
            for name, truth in truths.items()
        },
        **{
            f"diagnose_{case}.held_out_{k}_{what}": Figure(
                f"diagnose_{case}", (lambda n, w: lambda v: v["held_out"][n][w])(k, what), "{:.1f}", 0.05
            )
            for case in DIAGNOSE_CASES
            for k in (1, 2)
            for what in ("before", "after", "floor")
        },
    }
)

#: the short variant of `mast compare --controller` docs/controller.md states and tests/test_controllers.py runs:
#: (controllers, motions, frequencies [Hz], the payload the controllers do not know [kg])
CONTROLLERS_SHORT = (("joint", "computed_torque"), ("z",), (1.0, 3.0), 3.0)
# its figures: per controller, the peak tracking error at the lowest frequency without and with the payload [mm] (to
# the printed digit, 5e-5 mm: a closed loop's floats move far less between machines) and their ratio
FIGURES.update(
    {
        f"controllers_short.{c}.{what}": Figure(
            "controllers_short", (lambda n, w: lambda v: v[n][w])(c, what), fmt, tol
        )
        for c in CONTROLLERS_SHORT[0]
        for what, fmt, tol in (
            ("tracking_mm", "{:.3g}", 5e-5),
            ("tracking_payload_mm", "{:.3g}", 5e-5),
            ("ratio", "{:.1f}", 0.05),
        )
    }
)


def controllers_short_argv(out: Path, fmus: Path) -> list[str]:
    """`mast compare` arguments of CONTROLLERS_SHORT (the direct composition, 2 workers), the FMUs from ``fmus``."""
    controllers, motions, frequencies, payload = CONTROLLERS_SHORT
    return [
        "compare",
        "--controller",
        *controllers,
        "--motions",
        *motions,
        "--frequencies",
        *(f"{f:g}" for f in frequencies),
        "--payload",
        f"{payload:g}",
        "--out",
        str(out),
        "--direct",
        "--workers",
        "2",
        "--fmus",
        str(fmus),
    ]


def controllers_values(comparison: Mapping) -> dict:
    """The controllers_short figures of a controller comparison (its comparison.json as a dict), the first motion."""
    motion = CONTROLLERS_SHORT[1][0]
    return {
        r["controller"]: {
            "tracking_mm": 1e3 * r["tracking_peak_f_min"],
            "tracking_payload_mm": 1e3 * r["tracking_peak_f_min_payload"],
            "ratio": r["tracking_peak_f_min_ratio"],
        }
        for r in comparison["robustness"]
        if r["motion"] == motion
    }


def source_controllers_short() -> dict:
    """CONTROLLERS_SHORT run by `mast compare` on the Python FMUs built into a temporary folder."""
    from mast.cli import main as cli_main
    from mast.core.build import build_all

    with tempfile.TemporaryDirectory(prefix="mast_figures_") as tmp:
        build_all(Path(tmp) / "build", log=lambda *_: None)
        if cli_main(controllers_short_argv(Path(tmp) / "out", Path(tmp) / "build" / "fmus")) != 0:
            raise RuntimeError("mast compare --controller failed (its message above)")
        return controllers_values(json.loads((Path(tmp) / "out" / "comparison.json").read_text()))


#: the short variant of `mast compare --mechanism` docs/designs/README.md states and tests/test_compare.py runs: (the
#: designs' mechanism FMUs, motions, frequencies [Hz]), through the FMUs
DESIGNS_SHORT = (("MastMechanism", "MastActuatorsOnly"), ("z",), (2.0, 8.0))
# its figures per design: -3 dB bandwidth [Hz] (interpolated between the two frequencies), peak and RMS motor torque
# [N m], peak tracking error [mm], each to its printed digit (what another machine's floats move stays far below)
FIGURES.update(
    {
        f"designs_short.{d}.{what}": Figure("designs_short", (lambda n, w: lambda v: v[n][w])(d, what), fmt, tol)
        for d in DESIGNS_SHORT[0]
        for what, fmt, tol in (
            ("bandwidth_Hz", "{:.2f}", 0.005),
            ("torque_peak_Nm", "{:.3f}", 0.0005),
            ("torque_rms_Nm", "{:.3f}", 0.0005),
            ("tracking_mm", "{:.2f}", 0.005),
            ("sizing_margin_pct", "{:.0f}", 0.5),
            ("sizing_holds_up_to_Hz", "{:g}", 0.0),
        )
    }
)
# paper Fig. 10 on the short variant: the bandwidth with the mechanism against the actuators alone [%]
FIGURES["designs_short.fig10.rise_pct"] = Figure("designs_short", lambda v: v["fig10"]["rise_pct"], "{:.0f}", 0.5)


def designs_values(comparison: Mapping) -> dict:
    """The designs_short figures of a design comparison (its comparison.json as a dict), the first motion."""
    motion = DESIGNS_SHORT[1][0]
    out = {
        r["design"]: {
            "bandwidth_Hz": r["bandwidth_Hz"],
            "torque_peak_Nm": r["torque_peak_Nm"],
            "torque_rms_Nm": r["torque_rms_Nm"],
            "tracking_mm": 1e3 * r["tracking_peak"],
            "sizing_margin_pct": 100 * r["sizing_margin"],
            "sizing_holds_up_to_Hz": r["sizing_holds_up_to_Hz"],
        }
        for r in comparison["summary"]
        if r["motion"] == motion
    }
    alone, with_mechanism = (out[d]["bandwidth_Hz"] for d in ("MastActuatorsOnly", "MastMechanism"))
    out["fig10"] = {"rise_pct": 100 * (with_mechanism / alone - 1)}
    return out


def run_designs_short(fmus: Path, out: Path) -> dict:
    """DESIGNS_SHORT by `mast.analyses.compare.compare` on the FMUs in ``fmus`` (the actuator's, the controller's and
    the designs'), 2 workers, the quick workspace grid: its comparison.json as a dict."""
    from mast.analyses.compare import WORKSPACE_GRID_QUICK, TestSet, compare

    designs, motions, frequencies = DESIGNS_SHORT
    compare(
        [fmus / f"{d}.fmu" for d in designs],
        out,
        TestSet(axes=motions, frequencies=frequencies),
        workers=2,
        fmu_dir=fmus,
        workspace_grid=WORKSPACE_GRID_QUICK,
    )
    return json.loads((out / "comparison.json").read_text())


def source_designs_short() -> dict:
    """DESIGNS_SHORT on the FMUs built into a temporary folder."""
    from mast.core.build import FMUS, build_fmu

    with tempfile.TemporaryDirectory(prefix="mast_figures_") as tmp:
        for spec in FMUS:
            if spec.model_identifier in ("MastActuator", "MastController", *DESIGNS_SHORT[0]):
                build_fmu(spec, Path(tmp) / "fmus")
        return designs_values(run_designs_short(Path(tmp) / "fmus", Path(tmp) / "out"))


#: the run of the animate figures: the default system's `make run` motion (z sine, 0.01 m at 1 Hz) for 3 s
ANIMATE_RUN = ("z", 0.01, 1.0, 3.0)

#: the coarse grid of the hexapod's figures (step in m, step in deg): about 6 s for its three workspaces
HEXAPOD_GRID = (0.02, 3.0)

#: the EMPS benchmark's published inverse-model least-squares estimates (the EMPS README; docs/emps.md)
EMPS_PUBLISHED = {"M": 95.11, "F_v": 203.5, "F_c": 20.39, "F_offset": -3.16}
EMPS_RECORD = ROOT.parent / "shared" / "data" / "emps" / "DATA_EMPS.mat"


def source_reproduce() -> dict:
    """``mast reproduce`` as the command runs it (direct composition, the full sweep, 2 workers)."""
    from mast.analyses.reproduce import reproduce
    from mast.core.build import build_all

    with tempfile.TemporaryDirectory(prefix="mast_figures_") as tmp:
        build_all(Path(tmp) / "build", log=lambda *_: None)
        summary = reproduce(str(Path(tmp) / "build" / "ssp" / "MAST.ssp"), Path(tmp) / "out", workers=2, direct=True)
        rows = json.loads((Path(tmp) / "out" / "paper_table.json").read_text())
    return reproduce_values(summary, rows)


def reproduce_values(summary: Mapping, rows: list) -> dict:
    """The ``reproduce`` source from a run's summary and its paper_table.json rows (tests/test_reproduce.py)."""
    return {"summary": dict(summary), "rows": {r["key"]: r for r in rows}}


def source_ssd() -> dict:
    from mast.core.ssp import read_ssd

    return {"controller": dict(read_ssd(ROOT / "ssp" / "MAST.ssd").components["controller"].parameters)}


def source_inertias() -> dict:
    """Paper Fig. 10's argument (docs/designs/README.md): per axis, the inertia the position loop moves [kg, at the
    guide], motor side J1 / i_R^2 and guide side J2 / i_R^2 (``fmus.actuator.model.two_inertia`` of actuator_1 in
    ssp/MAST.ssd), and the T layout's mass matrix at home, its smallest and largest eigenvalue [kg] and their share of
    the axis' inertia [%]."""
    import numpy as np

    from fmus.actuator.model import transmission_ratio, two_inertia
    from mast.analyses.workspace import machine
    from mast.core.ssp import read_ssd

    params = read_ssd(ROOT / "ssp" / "MAST.ssd").components["actuator_1"].parameters
    J1, J2 = two_inertia(params)
    i_R = transmission_ratio(float(params["p"]), float(params["i_r"]))
    m = machine("3PRS_T")
    n = len(m.topology.drives)
    M = m.engine().inverse_dynamics_at_pose(m.topology.home, [0.0] * n, [0.0] * n).M
    eig = np.linalg.eigvalsh(M)
    axis = (J1 + J2) / i_R**2
    return {
        "motor_side_kg": J1 / i_R**2,
        "guide_side_kg": J2 / i_R**2,
        "M_min_kg": float(eig[0]),
        "M_max_kg": float(eig[-1]),
        "M_min_pct": 100 * float(eig[0]) / axis,
        "M_max_pct": 100 * float(eig[-1]) / axis,
    }


def source_ratings() -> dict:
    """The drive ratings `mast sizing` checks against (ssp/resources/drive_ratings.ssv), SI values."""
    from mast.core.ssv import parse_ssv

    return {name: v.value for name, v in parse_ssv(ROOT / "ssp" / "resources" / "drive_ratings.ssv").items()}


def source_build() -> dict:
    """How many FMUs `mast build` writes (mast.core.build.FMUS); the archive limits (mast.core.ssp.MAX_*), in the
    units the pages use (binary prefixes)."""
    from mast.core import ssp
    from mast.core.build import FMUS

    return {
        "fmus": len(FMUS),
        "max_archive_GiB": ssp.MAX_ARCHIVE_BYTES / 2**30,
        "max_entry_MiB": ssp.MAX_ENTRY_BYTES / 2**20,
        "max_entries": ssp.MAX_ENTRIES,
        "ratio_floor_MiB": ssp.RATIO_FLOOR / 2**20,
        "max_ratio": ssp.MAX_RATIO,
    }


def source_emps() -> dict:
    """`mast replay` of the EMPS record on the bench (built into a temporary folder) with the published estimates
    and with the nominal model: {model: {q_m, force: relative error [%], force_fit [%]}}. Needs the record
    (../shared/data/emps/DATA_EMPS.mat); seconds."""
    from mast.analyses.replay import replay
    from mast.core.build import FMUS, SSP_SRC, build_fmu, build_ssp
    from mast.data.importer import import_file

    out = {}
    with tempfile.TemporaryDirectory(prefix="mast_figures_") as tmp:
        tmp = Path(tmp)
        for spec in FMUS:
            if spec.model_identifier in ("MastLoadAxis", "MastEmpsController"):
                build_fmu(spec, tmp / "fmus")
        bench = build_ssp(SSP_SRC / "EMPS_bench.ssd", tmp / "fmus", tmp / "ssp")
        import_file(EMPS_RECORD, ROOT / "examples" / "emps" / "map.toml", tmp / "record")
        for model, params in (("published", {"axis": EMPS_PUBLISHED}), ("nominal", {})):
            signals = replay(bench, tmp / "record", tmp / model, params, figures=False)["signals"]
            out[model] = {
                "q_m": signals["q_m"]["relative_error_pct"],
                "force": signals["force"]["relative_error_pct"],
                "force_fit": signals["force"]["fit_pct"],
            }
    return out


def source_animate(ssp: Path | None = None) -> dict:
    """`mast animate`'s page of ANIMATE_RUN on ``ssp`` (default: MAST.ssp built into a temporary folder), at the
    default frame rate: its frames and size [MB], how much of it is plotly.js and the figure, the figure's size per
    frame [kB] and what a minute of motion would weigh [MB]; seconds."""
    import plotly.offline

    from mast.analyses import animate
    from mast.core.build import FMUS, SSP_SRC, build_fmu, build_ssp
    from mast.core.run import motion_from_cli, simulate, write_outputs

    motion, amplitude, frequency, stop = ANIMATE_RUN
    with tempfile.TemporaryDirectory(prefix="mast_figures_") as tmp:
        tmp = Path(tmp)
        if ssp is None:
            for spec in FMUS:
                if spec.model_identifier in ("MastActuator", "MastController", "MastMechanism"):
                    build_fmu(spec, tmp / "fmus")
            ssp = build_ssp(SSP_SRC / "MAST.ssd", tmp / "fmus", tmp / "ssp")
        command = motion_from_cli(motion, amplitude, frequency)
        write_outputs(simulate(ssp, command, stop, direct=True), tmp / "run", stop, command, ssp)
        done = animate.write(tmp / "run", tmp / animate.PAGE)
    library = len(plotly.offline.get_plotlyjs().encode("utf-8"))
    figure = done["bytes"] - library
    return {
        "frames": done["frames"],
        "page_MB": done["bytes"] / 1e6,
        "plotly_MB": library / 1e6,
        "figure_MB": figure / 1e6,
        "frame_kB": figure / done["frames"] / 1e3,
        "minute_MB": (library + figure / done["frames"] * (60 * animate.FPS + 1)) / 1e6,
    }


def diagnose_values(doc: Mapping) -> dict:
    """A diagnosis' figures (its diagnosis.json as a dict): the fitted parameters of the named effects (and of their
    equivalent alternatives), and per held-out test (1, 2, ... in the plan's order) the torque NRMSE [%] before and
    after and its noise floor."""
    fitted: dict = {}
    for effect in doc["named_effects"]:
        for alternative in effect["evidence"].get("alternatives", []):
            fitted.update(alternative.get("parameters", {}))
        fitted.update(effect["parameters"])
    held_out = [g for g in doc["gap"].values() if g["role"] == "held-out"]
    return {
        "fitted": fitted,
        "held_out": {
            k: {
                "before": g["before"]["torque_nrmse_percent"],
                "after": g["after"]["torque_nrmse_percent"],
                "floor": g["before"]["torque_floor_percent"],
            }
            for k, g in enumerate(held_out, 1)
        },
    }


@functools.lru_cache(maxsize=None)
def _diagnose_build() -> Path:
    """MAST.ssp's Python FMUs (which synthesize) and its native form (which the diagnoses re-simulate), built once per
    process into a temporary folder removed at exit."""
    from mast.core.build import build_all
    from mast.core.native.build import build_native_all

    folder = Path(tempfile.mkdtemp(prefix="mast_figures_"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    build_all(folder, log=lambda *_: None)
    build_native_all(folder, [ROOT / "ssp" / "MAST.ssd"], log=lambda *_: None)
    return folder / "ssp"


def source_diagnose(case: str) -> dict:
    """`mast diagnose` of DIAGNOSE_CASES[case] hidden by `mast synthesize` on DIAGNOSE_PLAN (the Python models
    synthesize, the native variant re-simulates, as tests/test_diagnose.py runs it): its diagnose_values."""
    from mast.analyses.synthesize import TestSpec, synthesize
    from mast.diagnosis import Options, diagnose

    truth, seed = DIAGNOSE_CASES[case]
    ssp = _diagnose_build()
    with tempfile.TemporaryDirectory(prefix="mast_figures_") as tmp:
        data, plan = Path(tmp) / "data", tuple(TestSpec(*t) for t in DIAGNOSE_PLAN)
        synthesize(
            str(ssp / "MAST.ssp"), data, {"actuator": truth}, tests=plan, direct=True, seed=seed, log=lambda *_: None
        )
        doc = diagnose(
            Options(data, Path(tmp) / "out", str(ssp / "native" / "MAST.ssp"), figures=False, direct=False),
            log=lambda *_: None,
        )
    return diagnose_values(doc)


def source_designs() -> dict:
    from mast.analyses.workspace import machine

    out = {}
    for name in ("3PRS_T", "3PRS_120", "3PRS_inclined"):
        m = machine(name, 0.0)
        eng = m.engine()
        margins = eng.margins(eng.dk(m.rho_home)[0])
        out[name] = {"parallel": margins.parallel, "inverse": margins.inverse, "dexterity": margins.dexterity}
    return out


def source_workspace(quick: bool = False) -> dict:
    """The designs' `mast workspace` summaries on its default grid, or on `mast compare --quick`'s."""
    from mast.analyses.compare import WORKSPACE_GRID, WORKSPACE_GRID_QUICK
    from mast.analyses.workspace import compute, machine, summarize

    out = {}
    for name in ("3PRS_T", "3PRS_120", "3PRS_inclined"):
        s = summarize(compute(machine(name), *(WORKSPACE_GRID_QUICK if quick else WORKSPACE_GRID)))
        through_home = s["ranges_through_home"]
        out[name] = {
            "volume_m_deg2": s["volume_m_deg2"],
            "smallest_margin": s["smallest_margin"]["value"],
            "worst_dexterity": s["worst_dexterity"]["value"],
            "psi_home_lo_deg": through_home["psi_deg"][0],
            "psi_home_hi_deg": through_home["psi_deg"][1],
            "theta_home_lo_deg": through_home["theta_deg"][0],
            "theta_home_hi_deg": through_home["theta_deg"][1],
            "margin_home": min(s["home"]["margin_parallel"], s["home"]["margin_inverse"]),
            "singularity_home_m": s["distance_to_singularity_at_home_m"],
        }
    return out


def source_hexapod() -> dict:
    """The 6-UPS's margins and static forces at home (its description's values) and its workspaces on HEXAPOD_GRID:
    x, y, z at the home orientation [L], psi, theta, phi at the home position [deg^3], z, psi, theta [m deg^2]."""
    from fmus.mechanism.description import load
    from fmus.mechanism.engine import Engine
    from mast.analyses.workspace import compute, machine, summarize

    m = machine("6UPS")
    eng = m.engine()
    home = m.topology.home
    margins = eng.margins(home)
    F = eng.inverse_dynamics_at_pose(home, [0.0] * 6, [0.0] * 6).t_rho
    file = load("6UPS")
    legs = (
        "m_cylinder",
        "I_cylinder_xx",
        "I_cylinder_yy",
        "I_cylinder_zz",
        "I_cylinder_xz",
        "m_rod",
        "I_rod_xx",
        "I_rod",
    )
    F_bare = Engine(file.describe({**file.values(), **dict.fromkeys(legs, 0.0)}), g=file.values()["g"])
    step, tilt = HEXAPOD_GRID[0], math.radians(HEXAPOD_GRID[1])
    volume = {
        sweep: summarize(compute(m, step, tilt, sweep=sweep.split(",")))
        for sweep in ("x,y,z", "psi,theta,phi", "z,psi,theta")
    }
    return {
        "parallel": margins.parallel,
        "inverse": margins.inverse,
        "dexterity": margins.dexterity,
        "F_home_odd": float(F[0]),
        "F_home_even": float(F[1]),
        "F_home_massless": float(F_bare.inverse_dynamics_at_pose(home, [0.0] * 6, [0.0] * 6).t_rho[0]),
        "volume_xyz_L": 1e3 * volume["x,y,z"]["volume_m3"],
        "volume_angles_deg3": volume["psi,theta,phi"]["volume_deg3"],
        "volume_z_psi_theta_m_deg2": volume["z,psi,theta"]["volume_m_deg2"],
    }


def hexapod_run_values(summary: Mapping) -> dict:
    """The figures of the 6-UPS system run (HEXAPOD_RUN) from its summary (``mast.core.run.summarize``): the peak
    tracking error in z [mm], the largest peak motor current [A] and torque [mN m] of the six drives, the held yaw's
    peak error [urad]."""
    drives = range(1, 7)
    return {
        "z_error_mm": 1e3 * summary["coordinates"]["z"]["error_peak"],
        "current_peak_A": max(summary[f"i_m_{k}_peak_A"] for k in drives),
        "torque_peak_mNm": 1e3 * max(summary[f"tau_m_{k}_peak_Nm"] for k in drives),
        "phi_error_urad": 1e6 * summary["coordinates"]["phi"]["error_peak"],
    }


def source_hexapod_run() -> dict:
    """HEXAPOD_RUN on build/ssp/MAST_6UPS.ssp (`mast build` first)."""
    from fmus.mechanism.topology import POSE
    from mast.core.motion import SineMotion
    from mast.core.run import simulate, summarize

    axis, amplitude, frequency, stop = HEXAPOD_RUN
    motion = SineMotion(axis=axis, amplitude=amplitude, frequency=frequency, axes=POSE)
    result = simulate(ROOT / "build" / "ssp" / "MAST_6UPS.ssp", motion, stop)
    return hexapod_run_values(summarize(result, stop, motion))


SOURCES: dict[str, Callable[[], dict]] = {
    "reproduce": source_reproduce,
    "ssd": source_ssd,
    "designs": source_designs,
    "ratings": source_ratings,
    "inertias": source_inertias,
    "build": source_build,
    "emps": source_emps,
    "workspace": source_workspace,
    "workspace_quick": lambda: source_workspace(quick=True),
    "hexapod": source_hexapod,
    "hexapod_run": source_hexapod_run,
    "animate": source_animate,
    "controllers_short": source_controllers_short,
    "designs_short": source_designs_short,
    **{f"diagnose_{case}": functools.partial(source_diagnose, case) for case in DIAGNOSE_CASES},
}


def pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def marks(path: Path) -> Iterator[tuple[int, re.Match]]:
    """(line number, match) of every figure marker in ``path``."""
    for number, line in enumerate(path.read_text().splitlines(), 1):
        for match in MARKER.finditer(line):
            yield number, match


def _number(text: str) -> float:
    try:
        return float(text.replace("\u2212", "-").replace(",", ""))
    except ValueError:
        return math.nan


def check(values: Mapping[str, dict], paths: list[Path] | None = None) -> list[str]:
    """Every marked figure whose source is in ``values`` against the computed value: the disagreements, each
    naming the page, the line, both values and the command that regenerates the page. Unknown keys too."""
    problems = []
    for path in paths or pages():
        where = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
        for line, match in marks(path):
            key, stated = match["key"], match["value"]
            figure = FIGURES.get(key)
            if figure is None:
                problems.append(
                    f"{where}:{line}: figure {key!r} is not in docs/figures.py FIGURES (known: "
                    f"{', '.join(sorted(FIGURES))})"
                )
                continue
            if figure.source not in values:
                continue
            computed = figure.pick(values[figure.source])
            if figure.fmt.format(computed) != stated and not abs(_number(stated) - computed) <= figure.tolerance:
                problems.append(
                    f"{where}:{line}: the page states {key} = {stated}, the code gives "
                    f"{figure.fmt.format(computed)} (tolerance {figure.tolerance:g}): run `{REGENERATE} "
                    f"--source {figure.source}` and say in the text why the figure moved"
                )
    return problems


def used_sources(paths: list[Path] | None = None) -> set[str]:
    return {FIGURES[m["key"]].source for path in paths or pages() for _, m in marks(path) if m["key"] in FIGURES}


def write(values: Mapping[str, dict], paths: list[Path] | None = None) -> list[str]:
    """Write the computed values into the pages' markers; returns the changes ("page:line key old -> new")."""
    changes = []
    for path in paths or pages():
        text = path.read_text()

        def replace(match: re.Match, text: str = text, path: Path = path) -> str:
            figure = FIGURES.get(match["key"])
            if figure is None or figure.source not in values:
                return match[0]
            new = figure.fmt.format(figure.pick(values[figure.source]))
            if new != match["value"]:
                line = text.count("\n", 0, match.start()) + 1
                changes.append(f"{path.relative_to(ROOT)}:{line} {match['key']}: {match['value']} -> {new}")
            return f"<!-- figure {match['key']} -->{new}<!-- /figure -->"

        updated = MARKER.sub(replace, text)
        if updated != text:
            path.write_text(updated)
    return changes


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument(
        "--source",
        action="append",
        choices=sorted(SOURCES),
        help="compute only these sources (repeatable; default: every source a page uses)",
    )
    parser.add_argument("--check", action="store_true", help="write nothing; list the figures that differ (exit 1)")
    args = parser.parse_args(argv)
    values = {name: SOURCES[name]() for name in sorted(args.source or used_sources())}
    if args.check:
        problems = check(values)
        print("\n".join(problems) or f"every figure of {', '.join(values)} agrees")
        return 1 if problems else 0
    changes = write(values)
    print("\n".join(changes) or "no figure changed")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main())
