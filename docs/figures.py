"""The result figures the documentation states, generated into the pages: ``python docs/figures.py``.

A figure in a page (README.md, docs/**/*.md) is marked where it stands, invisible in the rendered page::

    **<!-- figure reproduce.predictions_within -->10<!-- /figure --> of 18 predictions**

A page that states a figure to other digits than its key's format says so after the key, a format specification:
``<!-- figure geometry.z_home_m:.3f -->0.405<!-- /figure -->`` (the same value, written with ``{:.3f}``).

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
MARKER = re.compile(
    r"<!-- figure (?P<key>[\w\-]+(?:\.[\w\-]+)+)(?::(?P<spec>[^\s>]+))? -->(?P<value>.*?)<!-- /figure -->"
)
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


def _forensic(name: str) -> Callable[[Mapping], float]:
    return lambda values: values["summary"]["forensics"][name]


#: the motions of `mast reproduce`'s rows
MOTIONS = ("z", "psi", "theta")


def _below_band(values: Mapping, motion: str) -> float:
    """How far the 10 Hz position magnitude of ``motion`` lies below its band's lower end (its ratio)."""
    row = values["rows"][f"position_magnitude/{motion}/10Hz"]
    return row["tolerance_band"][0] - row["ours"]


def _above_band(values: Mapping, motion: str) -> float:
    """How far the 10 Hz position phase of ``motion`` lies above its band's upper end [deg]."""
    row = values["rows"][f"position_phase/{motion}/10Hz"]
    return row["ours"] - row["tolerance_band"][1]


def _peaks(variant: str, motions: tuple, end: str) -> Callable[[Mapping], float]:
    """The smallest (``end`` "lo") or largest ("hi") peak current command [A] of the 10 Hz tests of ``motions``."""
    pick = min if end == "lo" else max
    return lambda values: pick(
        t["i_peak_A"]
        for t in values["summary"]["limits"]
        if t["variant"] == variant and t["motion"] in motions and t["frequency_Hz"] == 10.0
    )


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
    # the designs' workspaces through home, their margins at home and their largest static force inside on the default
    # grid (docs/designs/README.md) and the quick one (docs/designs/3rps.md): a range through home may move by one grid
    # node (1 deg, 4 deg) between machines, like the volume
    **{
        f"{grid}.{d}.{what}": Figure(grid, (lambda v, d=d, w=what: v[d][w]), fmt, tol)
        for grid, node in (("workspace", 1.0), ("workspace_quick", 4.0))
        for d in ("3PRS_T", "3PRS_120", "3PRS_inclined")
        for what, fmt, tol in (
            ("psi_home_lo_deg", "{:.0f}", node),
            ("psi_home_hi_deg", "{:.0f}", node),
            ("theta_home_lo_deg", "{:.0f}", node),
            ("theta_home_hi_deg", "{:.0f}", node),
            ("margin_home", "{:.3f}", 0.0),
            ("singularity_home_m", "{:.3f}", 0.0),
            ("largest_force_N", "{:.1f}", 0.0),
        )
    },
    # the designs' singularity margins at home (docs/mechanism.md)
    **{
        f"designs.{d}.{what}": Figure("designs", (lambda v, d=d, w=what: v[d][w]), fmt, 0.005)
        for d in ("3PRS_T", "3PRS_120", "3PRS_inclined")
        for what, fmt in (("parallel", "{:.3g}"), ("inverse", "{:.3g}"), ("dexterity", "{:.3g}"))
    },
    # their static forces at home [N]: in the mechanism per drive, each carriage's weight in its actuator (docs/designs)
    **{
        f"designs.{d}.{what}": Figure("designs", (lambda v, d=d, w=what: v[d][w]), "{:.2f}")
        for d in ("3PRS_T", "3PRS_120", "3PRS_inclined")
        for what in ("F_home_1", "F_home_2", "F_home_3", "carriage_N")
    },
    # docs/sizing.md "What it says for the MAST": the limiting drive of SIZING_RUNS (direct composition: another
    # machine's floats move these far below the printed digit)
    **{
        f"sizing.{run}.{name}": Figure("sizing", (lambda r, n: lambda v: v[r][n])(run, name), fmt, tol)
        for run in ("default", "z_10Hz")
        for name, fmt, tol in (
            ("margin_pct", "{:.0f}", 0.5),
            ("belt_force_N", "{:.0f}", 0.5),
            ("rms_current_A", "{:.1f}", 0.05),
            ("peak_current_A", "{:.1f}", 0.05),
            ("winding_C", "{:.0f}", 0.5),
            ("minutes_to_max", "{:.0f}", 0.5),
        )
    },
    # the commands' defaults (README "First results")
    "defaults.synthesize_tests": Figure("defaults", lambda v: v["synthesize_tests"], "{:d}"),
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
    # `mast diagnose` on the EMPS record (docs/emps.md): each figure to its printed digit (a closed loop of 24.84 s
    # re-simulated in a fit: what another machine's floats move stays far below)
    **{
        f"emps_diagnose.{name}": Figure("emps_diagnose", (lambda n: lambda v: v[n])(name), fmt, tol)
        for name, fmt, tol in (
            *((f"step_{k}_dbic", "{:.0f}", 0.5) for k in (1, 2, 3)),
            *((f"step_{k}_held_out_pct", "{:.1f}", 0.05) for k in (1, 2, 3)),
            ("sym_M", "{:.2f}", 0.005),
            ("sym_F_v", "{:.2f}", 0.005),
            ("sym_F_c", "{:.2f}", 0.005),
            ("sym_F_offset", "{:.2f}", 0.005),
            ("sym_M_std", "{:.2f}", 0.005),
            ("sym_F_v_std", "{:.1f}", 0.05),
            ("sym_F_c_std", "{:.2f}", 0.005),
            ("sym_F_offset_std", "{:.2f}", 0.005),
            ("sym_M_vs_published_pct", "{:+.1f}", 0.05),
            ("sym_F_v_vs_published_pct", "{:+.1f}", 0.05),
            ("sym_F_c_vs_published_pct", "{:+.1f}", 0.05),
            ("sym_F_offset_vs_published_N", "{:+.2f}", 0.005),
            ("ours_M", "{:.2f}", 0.005),
            ("ours_F_v", "{:.1f}", 0.05),
            ("ours_F_c", "{:.2f}", 0.005),
            ("ours_F_offset", "{:.2f}", 0.005),
            ("ours_force_pct", "{:.2f}", 0.005),
            ("ours_F_v_pos", "{:.1f}", 0.05),
            ("ours_F_v_neg", "{:.1f}", 0.05),
            ("routes_pct", "{:.1f}", 0.05),
            ("F_v_pos", "{:.1f}", 0.05),
            ("F_v_neg", "{:.1f}", 0.05),
            ("F_c", "{:.1f}", 0.05),
            ("dF_v", "{:.1f}", 0.05),
            ("F_offset", "{:.2f}", 0.005),
            ("F_offset_std", "{:.2f}", 0.005),
            ("residual_rms_N", "{:.1f}", 0.05),
            ("residual_over_noise", "{:.0f}", 0.5),
            ("noise_floor_N", "{:.2f}", 0.005),
            ("simulations", "{:d}", 0.0),
            *(
                (f"{model}_{part}_force_{what}", fmt, tol)
                for model in ("nominal", "symmetric", "diagnosed")
                for part in ("training", "held-out", "whole")
                for what, fmt, tol in (
                    ("pct", "{:.1f}" if model == "nominal" else "{:.2f}", 0.05 if model == "nominal" else 0.005),
                    ("fit", "{:.1f}", 0.05),
                )
            ),
            *((f"{model}_q_m_pct", "{:.2g}", 0.00005) for model in ("nominal", "symmetric", "diagnosed")),
        )
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
            # ranges through home and extents: a grid node (20 mm, 3 deg) between machines
            *((f"{c}_home_{end}_m", "{:.2f}", 0.02) for c in ("x", "y") for end in ("lo", "hi")),
            *((f"z_home_{end}_m", "{:.3f}", 0.02) for end in ("lo", "hi")),
            *((f"{c}_extent_{end}_m", "{:.2f}", 0.02) for c in ("x", "y") for end in ("lo", "hi")),
            *((f"{c}_home_{end}_deg", "{:.0f}", 3.0) for c in ("psi", "theta", "phi") for end in ("lo", "hi")),
            ("smallest_margin", "{:.3f}", 0.0),
            ("worst_dexterity", "{:.1f}", 0.0),
            ("largest_force_N", "{:.0f}", 0.0),
            ("stroke_bound_pct", "{:.0f}", 0.0),
            *((f"M_eig_{k}_kg", "{:.2f}", 0.0) for k in range(1, 7)),
        ),
    ),
    # the 6-PUS beside it (docs/designs/6ups.md): as the 6-UPS's, on HEXAPOD_GRID
    **_named(
        "hexapod_pus",
        (
            ("z_home_m", "{:.4f}", 0.0),
            ("parallel", "{:.3f}", 0.0),
            ("inverse", "{:.3f}", 0.0),
            ("dexterity", "{:.2f}", 0.0),
            ("F_home", "{:.2f}", 0.0),
            ("F_home_massless", "{:.2f}", 0.0),
            *((f"M_eig_{k}_kg", "{:.2f}", 0.0) for k in range(1, 7)),
            ("volume_xyz_L", "{:.1f}", 0.02),
            *((f"{c}_home_{end}_m", "{:.2f}", 0.02) for c in ("x", "y") for end in ("lo", "hi")),
            *((f"z_home_{end}_m", "{:.3f}", 0.02) for end in ("lo", "hi")),
            *((f"xyz_{why}_pct", "{:.0f}", 0.0) for why in ("reach", "stroke", "singularity")),
            ("volume_angles_deg3", "{:.0f}", 60.0),
            *((f"{c}_home_{end}_deg", "{:.0f}", 3.0) for c in ("psi", "theta", "phi") for end in ("lo", "hi")),
            ("volume_z_psi_theta_m_deg2", "{:.0f}", 0.4),
        ),
    ),
    # the 3-RPS (docs/designs/3rps.md): its parasitic motion, statics, mass matrix and margins at home, its workspace on
    # the default grid and on `mast compare --quick`'s (a range through home: a grid node between machines)
    **_named(
        "rps",
        (
            ("parasitic_phi_deg", "{:.3f}", 0.0),
            ("parasitic_y_mm", "{:.2f}", 0.0),
            ("parasitic_x_mm", "{:.2f}", 0.0),
            ("F_home", "{:.2f}", 0.0),
            ("tau_home_mNm", "{:.1f}", 0.0),
            ("F_carriage", "{:.2f}", 0.0),
            ("F_platform", "{:.2f}", 0.0),
            ("F_rail", "{:.2f}", 0.0),
            *((f"M_eig_{k}_kg", "{:.2f}", 0.0) for k in (1, 2, 3)),
            ("cond", "{:.1f}", 0.0),
            ("parallel", "{:.3f}", 0.0),
            ("inverse", "{:.3f}", 0.0),
            ("det", "{:.3f}", 0.0),
            *(
                (f"{grid}{what}", fmt, tol)
                for grid, node in (("", 1.0), ("quick_", 4.0))
                for what, fmt, tol in (
                    ("volume_m_deg2", "{:.0f}", 0.5 if not grid else 0.8),
                    *((f"{c}_home_{end}_deg", "{:.0f}", node) for c in ("psi", "theta") for end in ("lo", "hi")),
                    *((f"{c}_extent_{end}_deg", "{:.0f}", node) for c in ("psi", "theta") for end in ("lo", "hi")),
                    *((f"z_home_{end}_m", "{:.3f}", 0.0) for end in ("lo", "hi")),
                    ("stroke_bound_pct", "{:.1f}", 0.0),
                    ("singularity_home_m", "{:.3f}", 0.0),
                    ("smallest_margin", "{:.3f}", 0.0),
                    ("worst_dexterity", "{:.1f}", 0.0),
                    ("largest_force_N", "{:.0f}", 0.0),
                    ("largest_force_theta_deg", "{:.0f}", node),
                )
            ),
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
    # docs/diagnose.md (branch auditC: the regions outside the backlash sections): the documented drive the tables
    # compare with (ssp/MAST.ssd's controller, SI: the page's ms) and what the page reasons from (source_diagnose_model)
    **{
        f"ssd.controller.{name}": Figure(
            "ssd", (lambda n, k: lambda v: v["controller"][n.removesuffix("_ms")] * k)(name, scale), "{:g}"
        )
        for name, scale in (("T_vel_ms", 1e3), ("T_pos_ms", 1e3), ("i_max", 1.0))
    },
    **_named(
        "diagnose_model",
        (
            ("K_t", "{:.1f}", 0.0),
            ("mode_Hz", "{:.0f}", 0.0),
            ("mode_soft_Hz", "{:.0f}", 0.0),
            ("holding_N", "{:.0f}", 0.0),
            ("holding_kg", "{:.0f}", 0.0),
            ("hexapod_effects", "{:d}", 0.0),
        ),
    ),
    # README.md, docs/actuator.md, controller.md, batch.md, interfaces.md, using-the-fmus.md, geometry.md (issue 30's
    # last pass): the page's size in README's command table, to its printed digit
    # the parameter sets' values these pages restate (ssp/resources/<set>.ssv; scaled to the page's unit): the same
    # number, no tolerance
    **{
        f"sets.{ssv}.{name}{suffix}": Figure("sets", (lambda s, n, k: lambda v: k * v[s][n])(ssv, name, scale), fmt)
        for ssv, names, fmt, scale, suffix in (
            (
                "actuator_manufacturer",
                (
                    *("R", "L", "k_T", "k_E", "u_supply", "J_motor", "J_gearbox", "J_coupling", "J_brake", "J1_scale"),
                    *("J_guide", "M_load", "K_t", "C_t", "tau_c", "omega_c", "b_v", "tau_s", "omega_s", "backlash"),
                    *("tau_ripple", "T_meas", "delay_meas", "tau_offset", "g_guide", "n_dof"),
                ),
                "{:g}",
                1.0,
                "",
            ),
            ("actuator_manufacturer", ("ripple_period",), "{:.4g}", 1.0, ""),
            ("actuator_identified", ("J1_scale", "tau_c"), "{:g}", 1.0, ""),
            ("actuator_paper_reading", ("M_load",), "{:g}", 1.0, ""),
            ("transmission", ("i_r", "p"), "{:g}", 1.0, ""),
            ("stroke_3prs", ("rho_0", "rho_min", "rho_max"), "{:g}", 1.0, ""),
            ("drive", ("k_pc", "k_ic", "T_pos", "T_vel", "T_cur", "i_max", "u_max"), "{:g}", 1.0, ""),
            ("drive", ("T_pos", "T_vel", "T_cur"), "{:g}", 1e3, "_ms"),
            ("drive", ("T_cur",), "{:g}", 1e6, "_us"),
            ("controller_joint", ("k_v", "k_p", "k_i"), "{:g}", 1.0, ""),
            ("controller_computed_torque", ("zeta",), "{:g}", 1.0, ""),
            ("controller_computed_torque", ("omega_n",), "{:g}", 1 / (2 * math.pi), "_Hz"),
            ("geometry_3prs", ("H", "r", "L"), "{:g}", 1.0, ""),
            ("mass_3prs", ("m_platform", "m_leg"), "{:g}", 1.0, ""),
            ("trajectory_z", ("amplitude_z",), "{:g}", 1e3, "_mm"),
            ("trajectory_z", ("frequency",), "{:g}", 1.0, ""),
            ("attached", ("T_mech",), "{:g}", 1e3, "_ms"),
            ("geometry_3prs_inclined", ("beta",), "{:.0f}", 180 / math.pi, "_deg"),
            ("trajectory_6ups", ("amplitude_z",), "{:g}", 1e3, "_mm"),
            ("trajectory_6ups", ("frequency",), "{:g}", 1.0, ""),
        )
        for name in names
    },
    # docs/actuator.md: what the actuator's relations give for its parameter sets (fmus.actuator.model): computed
    # from the sets in closed form, to the printed digit
    **_named(
        "actuator",
        (
            ("i_R", "{:.3e}", 0.0),
            ("J1", "{:.3e}", 0.0),
            ("J1_identified", "{:.3e}", 0.0),
            ("J2_guide", "{:.3e}", 0.0),
            ("J2_carriage", "{:.3e}", 0.0),
            ("J2", "{:.3e}", 0.0),
            ("TF2_Hz", "{:.1f}", 0.0),
            ("TF2_p66_Hz", "{:.0f}", 0.0),
            ("TF1_Hz", "{:.1f}", 0.0),
            ("TF1_identified_Hz", "{:.1f}", 0.0),
            ("TF2d_Hz", "{:.1f}", 0.0),
            ("TF2d_identified_Hz", "{:.1f}", 0.0),
            ("J_for_table1_fn", "{:.3g}", 0.0),
            ("J_for_table1_fn_pct", "{:.0f}", 0.0),
            ("J_for_900Hz", "{:.3g}", 0.0),
            ("reading_TF2_Hz", "{:.0f}", 0.0),
            ("reading_TF1_Hz", "{:.0f}", 0.0),
            ("reading_TF1_identified_Hz", "{:.0f}", 0.0),
            ("R_over_L", "{:.0f}", 0.0),
            ("zeta_TF1", "{:.1g}", 0.0),
            ("phase_100us_rad", "{:.2f}", 0.0),
            ("substeps_100us", "{:d}", 0.0),
            ("substeps_1ms", "{:d}", 0.0),
            ("substeps_46kHz_100us", "{:d}", 0.0),
            ("backlash_substeps_100us", "{:d}", 0.0),
            ("static_deflection_rad", "{:.2g}", 0.0),
            ("static_deflection_um", "{:.2f}", 0.0),
            ("friction_time_identified_us", "{:.0f}", 0.0),
            ("friction_time_manufacturer_us", "{:.0f}", 0.0),
            ("coupling_at_motor", "{:.3g}", 0.0),
            ("coupling_J1_pct", "{:.0f}", 0.0),
            ("coupling_J1_factor", "{:.2f}", 0.0),
            ("eq23_guide_Nm", "{:.3f}", 0.0),
            ("identified_over_eq23", "{:.1f}", 0.0),
            ("gear_loss_Nm", "{:.4f}", 0.0),
            ("eta_gear_pct", "{:.0f}", 0.0),
            ("k_E_mV", "{:.2f}", 0.0),
            ("k_T_mNm", "{:.1f}", 0.0),
            ("k_T_k_E_pct", "{:.2f}", 0.0),
            ("weight_torque_Nm", "{:.4f}", 0.0),
            ("weight_over_tau_c_pct", "{:.0f}", 0.0),
            ("creep_mm_s", "{:.2f}", 0.0),
            ("creep_identified_mm_s", "{:.3f}", 0.0),
            ("omega_c_carriage_mm_s", "{:.1g}", 0.0),
            ("brake_J1_pct", "{:.0f}", 0.0),
        ),
    ),
    # docs/geometry.md, docs/interfaces.md: the 3PRS's home pose from its description (fmus/mechanism/descriptions)
    **_named(
        "geometry",
        (
            ("z_home_m", "{:.6f}", 0.0),
            ("leg_height_m", "{:.6f}", 0.0),
            ("gamma_deg", "{:.2f}", 0.0),
            ("max_tilt_deg", "{:.0f}", 0.0),
        ),
    ),
    # docs/batch.md, docs/controller.md: the cases the example configs expand to (`mast batch --dry-run`), the
    # sine tests of `mast compare --controller` with every controller and the default test set; docs/using-the-fmus.md:
    # the signals `mast hosts` compares on MAST_standalone.ssp: counts, exact
    **_named(
        "examples",
        (
            ("friction_sweep_cases", "{:d}", 0.0),
            ("friction_sweep_groups", "{:d}", 0.0),
            ("hexapod_sweep_cases", "{:d}", 0.0),
            ("monte_carlo_machines", "{:d}", 0.0),
            ("monte_carlo_cases", "{:d}", 0.0),
            ("monte_carlo_study_cases", "{:d}", 0.0),
            ("controllers_full_tests", "{:d}", 0.0),
            ("standalone_signals", "{:d}", 0.0),
        ),
    ),
    # -- docs/reproduction.md, docs/mechanism.md, docs/workspace.md, docs/designs/*.md, docs/native.md (auditB) --
    # docs/reproduction.md beyond its headline: rows of `mast reproduce` (a closed loop: each to its printed digit,
    # far above what another machine's floats move), the forensic numbers of its report (the summary's "forensics")
    # and the largest current commands of its time-domain tests (the summary's "limits")
    **{
        f"reproduce.{name}": Figure("reproduce", pick, fmt, tol)
        for name, pick, fmt, tol in (
            *(
                (f"fit_z_{f.replace('.', '_')}Hz_{what}", pick, fmt, 0.05)
                for f in ("0.4", "5")
                for what, pick, fmt in (
                    (
                        "magnitude_pct",
                        (lambda fr: lambda v: 100 * _row(f"position_magnitude/z/{fr}Hz")(v))(f),
                        "{:.1f}",
                    ),
                    ("phase_deg", _row(f"position_phase/z/{f}Hz"), "{:.1f}"),
                )
            ),
            *((f"bandwidth_{m}_Hz", _row(f"bandwidth/{m}"), "{:.2f}", 0.005) for m in ("z", "psi", "theta", "z_alone")),
            (
                "bandwidth_z_below_paper_pct",
                lambda v: 100 * (1 - _row("bandwidth/z")(v) / v["rows"]["bandwidth/z"]["paper"]),
                "{:.0f}",
                0.5,
            ),
            ("alike_below_2Hz_pct", lambda v: 100 * _row("alike_below_2hz")(v), "{:.2f}", 0.005),
            ("torque_difference_0_4Hz_Nm", _row("torque/difference_0.4Hz"), "{:.3f}", 0.0005),
            ("torque_error_0_4Hz_pct", lambda v: 100 * _row("torque/error_0.4Hz")(v), "{:.0f}", 0.5),
            ("torque_square_0_4Hz", _row("torque/square_0.4Hz"), "{:.2f}", 0.005),
            ("torque_excess_10Hz_Nm", _row("torque/excess_10Hz"), "{:.3f}", 0.0005),
            (
                "torque_excess_10Hz_off_pct",
                lambda v: 100 * (_row("torque/excess_10Hz")(v) / v["rows"]["torque/excess_10Hz"]["paper"] - 1),
                "{:.1f}",
                0.05,
            ),
            # the 10 Hz rows against their bands: how far each lies outside
            ("magnitude_10Hz_z_below_band_pp", lambda v: 100 * _below_band(v, "z"), "{:.2f}", 0.005),
            ("magnitude_10Hz_below_band_min", lambda v: min(_below_band(v, m) for m in MOTIONS), "{:.4f}", 5e-5),
            ("magnitude_10Hz_below_band_max", lambda v: max(_below_band(v, m) for m in MOTIONS), "{:.4f}", 5e-5),
            ("phase_10Hz_above_band_min_deg", lambda v: min(_above_band(v, m) for m in MOTIONS), "{:.1f}", 0.05),
            ("phase_10Hz_above_band_max_deg", lambda v: max(_above_band(v, m) for m in MOTIONS), "{:.1f}", 0.05),
            (
                "phase_z_5_to_10Hz_deg",
                lambda v: _row("position_phase/z/5Hz")(v) - _row("position_phase/z/10Hz")(v),
                "{:.0f}",
                0.5,
            ),
            # forensics: the resonances against the paper's (arithmetic of the parameters: no tolerance)
            *(
                (f"{name}{suffix}_Hz", _forensic(f"{name}{suffix}_Hz"), "{:.0f}", 0.0)
                for name in ("tf2", "fn")
                for suffix in ("", "_eq22")
            ),
            *(
                (
                    f"{name}{suffix}_vs_paper_pct",
                    (lambda key, r: lambda v: 100 * (_forensic(key)(v) / v["rows"][r]["paper"] - 1))(
                        f"{name}{suffix}_Hz", row
                    ),
                    "{:+.1f}",
                    0.0,
                )
                for name, row in (("tf2", "tf2_resonance"), ("fn", "fn_table1"))
                for suffix in ("", "_eq22")
            ),
            *((f"{n}", _forensic(n), "{:.2f}", 0.005) for n in ("db3_z_Hz", "db3_z_alone_Hz", "paper_phase_45_Hz")),
            *(
                (
                    f"{n}_off_pct",
                    (lambda key, r: lambda v: 100 * (_forensic(key)(v) / v["rows"][r]["paper"] - 1))(n, row),
                    "{:.0f}",
                    0.5,
                )
                for n, row in (("db3_z_Hz", "bandwidth/z"), ("db3_z_alone_Hz", "bandwidth/z_alone"))
            ),
            *((f"paper_db3_from_{f}Hz", _forensic(f"paper_db3_from_{f}Hz"), "{:.1f}", 0.0) for f in (5, 10)),
            *((n, _forensic(n), "{:.0f}", 0.0) for n in ("m_actuator_kg", "m_actuator_manufacturer_kg")),
            # the mass the reading removes from each carriage [kg] and its share of each set's reflected inertia [%]
            ("reading_removes_kg", lambda v: _forensic("M_eq22_kg")(v) - _forensic("M_star_kg")(v), "{:.2f}", 0.0),
            *(
                (
                    f"reading_share_{name}_pct",
                    (
                        lambda key: (
                            lambda v: 100 * (_forensic("M_eq22_kg")(v) - _forensic("M_star_kg")(v)) / _forensic(key)(v)
                        )
                    )(mass),
                    "{:.0f}",
                    0.0,
                )
                for name, mass in (("manufacturer", "m_actuator_manufacturer_kg"), ("identified", "m_actuator_kg"))
            ),
            *((f"m_mechanism_{k}_kg", _forensic(f"m_mechanism_{k}_kg"), "{:.2f}", 0.0) for k in (1, 2, 3)),
            *(
                (f"mass_{label}kg_{what}_Hz", _forensic(f"mass_{extra}_{what}_Hz"), "{:.2f}", 0.005)
                for extra, label in (("2.27", "2_27"), ("6", "6"))
                for what in ("phase_45", "db3")
            ),
            *(
                (f"tau_c_{n}_mNm", (lambda which: lambda v: 1e3 * _forensic(f"tau_c_{which}_Nm")(v))(n), "{:.1f}", 0.0)
                for n in ("manufacturer", "identified")
            ),
            (
                "tau_c_difference_mNm",
                lambda v: 1e3 * (_forensic("tau_c_identified_Nm")(v) - _forensic("tau_c_manufacturer_Nm")(v)),
                "{:.1f}",
                0.0,
            ),
            ("peak_difference_Nm", _forensic("peak_difference_Nm"), "{:.3f}", 0.0005),
            (
                "peak_difference_off_pct",
                lambda v: (
                    100 * (1 - _forensic("peak_difference_Nm")(v) / v["rows"]["torque/difference_0.4Hz"]["paper"])
                ),
                "{:.0f}",
                0.5,
            ),
            ("peak_error_pct", lambda v: 100 * _forensic("peak_error")(v), "{:.0f}", 0.5),
            *((f"lowpass_{T}ms_Nm", _forensic(f"lowpass_{T}ms_Nm"), "{:.3f}", 0.0005) for T in (2, 5, 10)),
            *((f"gain_{g}", _forensic(g), "{:.4g}", 0.0) for g in ("k_v", "k_p", "k_i")),
            (
                "fit_evaluations",
                lambda v: int(re.search(r"over (\d+) evaluations", v["summary"]["forensics"]["fit"])[1]),
                "{:d}",
                0.0,
            ),
            # the largest current command of the 10 Hz tests [A]: the manufacturer set's tilts, the identified set's
            *(
                (f"i_peak_10Hz_{variant}_{end}_A", _peaks(label, motions, end), "{:.1f}", 0.05)
                for variant, label, motions in (
                    ("manufacturer_tilts", "Sim. Manufac.", ("psi", "theta")),
                    ("identified", "Sim. Ident.", MOTIONS),
                )
                for end in ("lo", "hi")
            ),
        )
    },
    # the 3PRS designs at home, their forces' split on a 5 Hz sine, the 120 deg layout's parasitic motion, the
    # inclined guides' gravity, the actuators-only pose (docs/designs/*.md, docs/mechanism.md): no simulation, the
    # same floats on every machine to far below the printed digit
    **{
        f"design_pages.{d}.{what}": Figure("design_pages", (lambda de, w: lambda v: v[de][w])(d, what), fmt)
        for d in ("3PRS_T", "3PRS_120", "3PRS_inclined")
        for what, fmt in (
            ("z_home_m", "{:.6f}"),
            *((f"F_home_{k}", "{:.3f}") for k in (1, 2, 3)),
            ("F_home_sum", "{:.4f}"),
            *((f"M_eig_{k}_kg", "{:.2f}") for k in (1, 2, 3)),
            ("cond", "{:.1f}"),
            ("drho_dz", "{:.3f}"),
            *((f"z_{part}_{k}", "{:.2f}") for part in ("F", "inertial", "gravity") for k in (1, 2, 3)),
            *((f"psi_inertial_{k}", "{:.2f}") for k in (1, 2, 3)),
            *((f"{motion}_velocity_max_mN", "{:.1f}") for motion in ("z", "psi")),
        )
    },
    "design_pages.compare_tests": Figure("design_pages", lambda v: v["compare_tests"], "{:d}"),
    "design_pages.3PRS_120.parasitic_phi_deg": Figure(
        "design_pages", lambda v: v["3PRS_120"]["parasitic_phi_deg"], "{:.2f}"
    ),
    "design_pages.3PRS_120.parasitic_y_mm": Figure("design_pages", lambda v: v["3PRS_120"]["parasitic_y_mm"], "{:.1f}"),
    "design_pages.3PRS_inclined.g_guide": Figure("design_pages", lambda v: v["3PRS_inclined"]["g_guide"], "{:.3f}"),
    "design_pages.actuators_only.z_above_carriages_m": Figure(
        "design_pages", lambda v: v["actuators_only"]["z_above_carriages_m"], "{:.6f}"
    ),
    # the designs' workspaces on the default grid beyond the figures above (docs/workspace.md, docs/designs/*.md): a
    # height or a range through home may move by a grid node (5 mm, 1 deg) between machines, a boundary share by a face
    # or two, a count of heights by one
    **{
        f"workspace.{d}.{what}": Figure("workspace", (lambda de, w: lambda v: v[de][w])(d, what), fmt, tol)
        for d in ("3PRS_T", "3PRS_120", "3PRS_inclined")
        for what, fmt, tol in (
            ("z_home_lo_m", "{:.3f}", 0.005),
            ("z_home_hi_m", "{:.3f}", 0.005),
            *((f"{cause}_pct", "{:.1f}", 0.2) for cause in ("stroke", "singularity", "branch")),
            *((f"square_{X}_{end}_m", "{:.3f}", 0.005) for X in (10, 15, 20) for end in ("lo", "hi")),
            *((f"square_{X}_levels", "{:d}", 1.0) for X in (10, 15, 20)),
            ("smallest_margin_z_m", "{:.2f}", 0.005),
            ("smallest_margin_psi_deg", "{:.0f}", 1.0),
            ("singular_z_m", "{:.2f}", 0.005),
            ("singular_psi_deg", "{:.0f}", 1.0),
            ("singular_theta_deg", "{:.0f}", 1.0),
        )
    },
    # `mast workspace 3PRS_T --payload 5` (docs/workspace.md): forces [N], where the largest is, torques [N m]
    **_named(
        "workspace_payload",
        (
            ("F_home_1", "{:.1f}", 0.0),
            ("largest_N", "{:.0f}", 0.0),
            ("at_z_m", "{:.2f}", 0.005),
            ("at_psi_deg", "{:.0f}", 1.0),
            ("at_theta_deg", "{:.0f}", 1.0),
            ("torque_Nm", "{:.3f}", 0.0),
            ("peak_Nm", "{:.3f}", 0.0),
            ("torque_over_peak", "{:.2f}", 0.0),
            ("beyond_peak_pct", "{:.2f}", 0.0),
        ),
    ),
    # `mast diagnose` of the EMPS record (docs/emps.md): the localisation's correlation and constant share, what the
    # first re-simulated step lowers the cost by (tests/test_emps.py on its diagnosis, as the other emps_diagnose)
    "emps_diagnose.sign_velocity_correlation": Figure(
        "emps_diagnose", lambda v: v["sign_velocity_correlation"], "{:+.2f}", 0.005
    ),
    "emps_diagnose.bias_share_pct": Figure("emps_diagnose", lambda v: v["bias_share_pct"], "{:.1f}", 0.05),
    "emps_diagnose.first_step_cost_pct": Figure("emps_diagnose", lambda v: v["first_step_cost_pct"], "{:.1f}", 0.05),
    # `mast replay` of the diagnosed EMPS bench on the synthetic pulse record (docs/emps.md): relative errors [%], fit
    # [%], to the printed digit (a closed loop of 24.84 s after a diagnosis: another machine's floats move far less);
    # the import's warning: the step [N] and gain [N/V] it regresses, the edges it counts
    **{
        f"emps_pulses.{case}.{what}": Figure("emps_pulses", (lambda c, w: lambda v: v[c][w])(case, what), fmt, tol)
        for case in ("applied", "before_injection", "not_applied", "nominal")
        for what, fmt, tol in (("q_m", "{:.2g}", 5e-6), ("force", "{:.3g}", 0.005), ("force_fit", "{:.1f}", 0.05))
    },
    **{
        f"emps_pulses.warning.{what}": Figure("emps_pulses", (lambda w: lambda v: v["warning"][w])(what), fmt, tol)
        for what, fmt, tol in (("step_N", "{:.0f}", 0.5), ("gain_N_per_V", "{:.2f}", 0.005), ("edges", "{:d}", 0.0))
    },
    # docs/native.md: the generated C of the native mechanisms [kB] and of the drive actuator [KiB], its step
    # kernels, what the parameters alone fix in the 3PRS's traced functions (the generator's output: exact)
    **_named(
        "native",
        (
            *((f"c_kB_{name}", "{:.0f}", 0.0) for name in ("3PRS", "3RPS", "6PUS", "6UPS")),
            ("actuator_c_KiB", "{:.0f}", 0.0),
            ("kernels", "{:d}", 0.0),
            ("kernels_n2", "{:d}", 0.0),
            ("kernels_n1", "{:d}", 0.0),
            ("invariants_ikjac", "{:d}", 0.0),
            ("invariants_dynamics", "{:d}", 0.0),
            ("invariants_pose", "{:d}", 0.0),
            *((f"chain_top_kHz_{n}", "{:.1f}", 0.0) for n in (4, 6, 8)),
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
#: a smaller plan of other frequencies, amplitudes and axes (tests/test_diagnose.py SMALL, docs/diagnose.md): z 1.2 Hz
#: 4 mm, psi 2.5 Hz 0.6 deg (held out), z 5 Hz 3 mm; as DIAGNOSE_PLAN
DIAGNOSE_SMALL = (
    ("z", 0.004, 1.2, 1.1, 0.3),
    ("psi", math.radians(0.6), 2.5, 0.8, 0.3),
    ("z", 0.003, 5.0, 0.6, 0.2),
)
#: five tests of the issue's kind (tests/test_diagnose_split.py PLAN_A): z 0.8, 3.3, 5.8 Hz, psi 1.7 Hz, theta 4.2 Hz
DIAGNOSE_PLAN_A = (
    ("z", 0.004, 0.8, 1.1, 0.3),
    ("psi", math.radians(0.7), 1.7, 0.8, 0.3),
    ("z", 0.003, 3.3, 0.8, 0.2),
    ("theta", math.radians(0.5), 4.2, 0.7, 0.2),
    ("z", 0.0025, 5.8, 0.7, 0.2),
)
#: three short tests (tests/test_diagnose_split.py PLAN_B): z 2.5 Hz, psi 3 Hz, z 6 Hz; the default split holds out psi
#: alone, so no held-out test moves actuators 1 and 3
DIAGNOSE_PLAN_B = (
    ("z", 0.003, 2.5, 1.0, 0.25),
    ("psi", math.radians(0.6), 3.0, 0.7, 0.2),
    ("z", 0.0028, 6.0, 0.6, 0.2),
)
#: backlash hidden alone (tests/test_diagnose.py, docs/diagnose.md "Backlash, two values"): DIAGNOSE_PLAN with its two
#: fast z tests at 10 Hz 8 mm and 15 Hz 5 mm. With the mechanism's inertial reaction at every 100 us step (issue 27)
#: the loop hunts there (a backlash of 1e-6 more parts the torque by 1.1-3.0 mN m, 0.5-1.4 x the noise, at 0.03-0.1
#: rad), and barely on z 7 Hz (0.2 mN m at 0.01 rad; the fitted model's z 7 Hz at 1.17-1.23 x the noise at 0.1-0.15
#: rad: on the 1.2 x floor, a coin toss of the last bits)
DIAGNOSE_PLAN_FAST = (
    ("z", 0.005, 0.6, 2.0, 0.3),
    ("theta", math.radians(0.8), 1.5, 1.0, 0.3),
    ("z", 0.008, 10.0, 0.8, 0.2),
    ("z", 0.005, 15.0, 0.6, 0.2),
)
#: backlash on a plan of the issue's kind (tests/test_diagnose_backlash.py, docs/diagnose.md "Backlash where the loop
#: hunts"): tests/test_diagnose.py ISSUE_PLAN (z, psi and theta; the fast z tests training) with its two fast z tests at
#: 12 Hz 6 mm and 16 Hz 4.5 mm instead of 3.5 Hz 3 mm and 6 Hz 2.5 mm: with the inertial reaction at every step (issue
#: 27) a few mrad no longer make ISSUE_PLAN's loop hunt (0.05 rad: the nominal model at 1.07-1.34 x the noise floor),
#: 0.07 rad makes these two hunt (1.7 and 1.9 x the noise)
DIAGNOSE_ISSUE_PLAN_FAST = (
    ("z", 0.004, 0.7, 1.2, 0.3),
    ("psi", math.radians(0.7), 1.8, 0.9, 0.3),
    ("z", 0.006, 12.0, 0.8, 0.2),
    ("theta", math.radians(0.5), 4.0, 0.7, 0.2),
    ("z", 0.0045, 16.0, 0.7, 0.2),
)
DIAGNOSE_PLANS = {
    "compact": DIAGNOSE_PLAN,
    "SMALL": DIAGNOSE_SMALL,
    "A": DIAGNOSE_PLAN_A,
    "B": DIAGNOSE_PLAN_B,
    "fast": DIAGNOSE_PLAN_FAST,
    "issue_fast": DIAGNOSE_ISSUE_PLAN_FAST,
}
#: heavier and lighter machines on both plans (docs/diagnose.md "Heavier and lighter", tests/test_diagnose_unseen.py):
#: case -> (the truth set on every actuator, the seed, the plan of DIAGNOSE_PLANS)
DIAGNOSE_HEAVIER_LIGHTER = {
    "inertia_up_small": ({"J1_scale": 1.2}, 31, "SMALL"),  # the guide-side equivalent destabilises the loop
    "mass_up_compact": ({"M_load": 2.9}, 32, "compact"),  # nominal 2.27 kg
    "mass_down_small": ({"M_load": 1.6}, 33, "SMALL"),
    "inertia_up_compact": ({"J1_scale": 1.15}, 35, "compact"),
    "mass_up_small": ({"M_load": 3.1}, 36, "SMALL"),
    "inertia_down_small": ({"J1_scale": 0.85}, 37, "SMALL"),
}
#: a measurement lag among other effects, as a delay and as a filter (docs/diagnose.md "A lag among other effects",
#: tests/test_diagnose_split.py): case -> (the truth set on every actuator, the seed, the plan of DIAGNOSE_PLANS);
#: "delay_plan_a" also states its cross-validation (the held-out residual over the folds without each effect)
DIAGNOSE_LAGS = {
    "coulomb_inertia_delay": ({"tau_c": 0.05, "J1_scale": 0.75, "delay_meas": 0.0025}, 301, "compact"),
    "coulomb_inertia_filter": ({"tau_c": 0.05, "J1_scale": 0.75, "T_meas": 0.0025}, 322, "compact"),
    "viscous_delay": ({"b_v": 1.5e-4, "delay_meas": 0.0017}, 323, "SMALL"),
    "viscous_filter": ({"b_v": 1.5e-4, "T_meas": 0.0017}, 324, "SMALL"),
    "heavier_delay_small": ({"tau_c": 0.04, "J1_scale": 1.2, "delay_meas": 0.0015}, 332, "SMALL"),
    "delay_plan_a": ({"tau_c": 0.045, "J1_scale": 0.8, "delay_meas": 0.0012}, 331, "A"),
}
#: backlash where fast z tests make the loop hunt (docs/diagnose.md "Backlash where the loop hunts",
#: tests/test_diagnose_backlash.py): case -> (the truth set on every actuator, the seed, the plan of DIAGNOSE_PLANS)
DIAGNOSE_BACKLASH = {
    "backlash_issue_fast": ({"backlash": 0.07}, 77, "issue_fast"),
    "backlash_fast": ({"backlash": 0.05}, 75, "fast"),
}
#: a motor-side inertia change on one axis beside a viscous change on all (docs/diagnose.md "Whatever the default
#: split", tests/test_diagnose_split.py): case -> (the truth per component, the seed, the plan of DIAGNOSE_PLANS)
DIAGNOSE_PER_AXIS = {
    "axis2_plan_a": ({"actuator_2": {"J1_scale": 1.35}, "actuator": {"b_v": 1.6e-4}}, 302, "A"),
    "axis1_plan_b": ({"actuator_1": {"J1_scale": 0.65}, "actuator": {"b_v": 1.5e-4}}, 314, "B"),
    "axis2_plan_b": ({"actuator_2": {"J1_scale": 1.4}, "actuator": {"b_v": 1.7e-4}}, 315, "B"),
    "axis3_plan_b": ({"actuator_3": {"J1_scale": 1.35}, "actuator": {"b_v": 1.4e-4}}, 316, "B"),
}


#: effects on one axis and in the drive (docs/diagnose.md "One axis, and the drive", tests/test_diagnose_unseen.py):
#: case -> (the truth per component, the seed, the plan of DIAGNOSE_PLANS, the effect named, its parameter, the value
#: it must have: a per-axis parameter is the increment on that axis, M_load's from the nominal 2.27 kg)
DIAGNOSE_ONE_AXIS_AND_DRIVE = {
    "mass_down_axis1": (
        {"actuator_1": {"M_load": 1.7}},
        63,
        "compact",
        "carriage_mass_axis1",
        "M_load_axis1",
        1.7 - 2.27,
    ),
    "offset_axis3": ({"actuator_3": {"tau_offset": -0.006}}, 92, "compact", "offset_axis3", "tau_offset_axis3", -0.006),
    "integral_gain": ({"controller": {"k_i": 2.27}}, 93, "SMALL", "velocity_integral", "k_i", 2.27),
    "cycle_time": ({"controller": {"T_vel": 0.002}}, 81, "SMALL", "velocity_cycle", "T_vel", 0.002),
    "current_limit": ({"controller": {"i_max": 3.3}}, 71, "compact", "current_limit", "i_max", 3.3),
    # the position-loop gain 39 % above its documentation (21.52 1/s)
    "position_gain_up": ({"controller": {"k_v": 30.0}}, 94, "compact", "position_gain", "k_v", 30.0),
}


#: the hexapod's diagnosis (docs/diagnose.md "The hexapod", tests/test_hexapod_diagnosis.py): Coulomb friction
#: 0.05 N m on drive 5 alone of the 6-UPS, three short sines (z 1.2 Hz 4 mm, x 2.5 Hz 4 mm held out, z 5 Hz 3 mm), the
#: actuator-side effects on all axes and on each of the six drives (35 effects), re-simulated on the direct composition
DIAGNOSE_HEXAPOD = {
    "system": "6UPS",
    "drive": 5,
    "tau_c": 0.05,
    "plan": (("z", 0.004, 1.2, 1.1, 0.3), ("x", 0.004, 2.5, 0.8, 0.3), ("z", 0.003, 5.0, 0.6, 0.2)),
    "effects": ("coulomb", "viscous", "inertia_motor", "offset", "lag"),
    "seed": 5,
}


def hexapod_library() -> tuple[str, ...]:
    """DIAGNOSE_HEXAPOD's effects on all axes and on each of the six drives alone."""
    effects = DIAGNOSE_HEXAPOD["effects"]
    return effects + tuple(f"{e}_axis{j}" for e in effects for j in range(1, 7))


def per_axis_truth(hidden: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
    """A DIAGNOSE_PER_AXIS truth as the diagnosis names its parameters: an actuator's own scale factor as the increment
    from 1 on its axis (J1_scale 1.35 on actuator 2: J1_scale_axis2 0.35), the values of every actuator as they are."""
    out: dict[str, float] = {}
    for component, values in hidden.items():
        for name, value in values.items():
            if component == "actuator":
                out[name] = value
            elif name.endswith("_scale"):
                out[f"{name}_axis{component.removeprefix('actuator_')}"] = value - 1.0
            else:
                raise ValueError(
                    f"DIAGNOSE_PER_AXIS: {component}.{name}: expected a scale factor (*_scale) on one axis"
                )
    return out


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
    # backlash: named on the phase-free score (the loop hunts), tests/test_diagnose.py; on DIAGNOSE_PLAN_FAST
    "backlash": ({"backlash": 0.06}, 7),
    "backlash_small": ({"backlash": 0.03}, 8),
}
#: the cases of DIAGNOSE_CASES on another plan than DIAGNOSE_PLAN (a name of DIAGNOSE_PLANS)
DIAGNOSE_CASE_PLANS = {"backlash": "fast", "backlash_small": "fast"}
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
        # heavier and lighter, and the lags: the fitted value, as the cases above
        **{
            f"diagnose_{case}.{name}": Figure(
                f"diagnose_{case}", (lambda n: lambda v: v["fitted"][n])(name), "{:.4g}", 1e-3 * abs(truth)
            )
            for case, (truths, _, _) in {
                **DIAGNOSE_HEAVIER_LIGHTER,
                **DIAGNOSE_LAGS,
                **{case: (per_axis_truth(hidden), *rest) for case, (hidden, *rest) in DIAGNOSE_PER_AXIS.items()},
                **{case: ({p: v}, s, plan) for case, (_, s, plan, _, p, v) in DIAGNOSE_ONE_AXIS_AND_DRIVE.items()},
            }.items()
            for name, truth in truths.items()
        },
        # the hexapod: the fitted increment of drive 5's friction and its 95 % interval to 0.1 % of the truth's
        # increment (the truth's increment is about 0.03 N m), every test's torque NRMSE [%] before and after
        **{
            f"diagnose_hexapod.{p}{what}": Figure(
                "diagnose_hexapod",
                (lambda q, w: lambda v: v["ci95"][q][w == "_hi"] if w else v["fitted"][q])(p, what),
                "{:.6g}",
                3e-5,
            )
            for p in (f"tau_c_axis{DIAGNOSE_HEXAPOD['drive']}",)
            for what in ("", "_lo", "_hi")
        },
        **{
            f"diagnose_hexapod.test_{k}_{what}": Figure(
                "diagnose_hexapod", (lambda n, w: lambda v: v["tests"][n][w])(k, what), "{:.1f}", 0.05
            )
            for k in (1, 2, 3)
            for what in ("before", "after", "floor")
        },
        # the cross-validation: the held-out residual summed over the folds without each effect against with them
        **{
            f"diagnose_delay_plan_a.without_{key}": Figure(
                "diagnose_delay_plan_a", (lambda k: lambda v: v["cross_validation"][k])(key), fmt, tol
            )
            for key, fmt, tol in (("lag", "{:.1f}", 0.05), ("inertia_motor", "{:.0f}", 0.5), ("coulomb", "{:.0f}", 0.5))
        },
        # backlash: its value, std and 95 % interval to the test's own tolerance, 5 % of the truth: the loop hunts
        # chaotically, and which regime a record falls into depends on the floats' last bits (tests/test_diagnose.py,
        # marker "regime"); this replaces the value's 0.1 % above
        **{
            f"diagnose_{case}.backlash{what}": Figure(
                f"diagnose_{case}",
                (
                    lambda w: (
                        lambda v: (
                            v["fitted"]["backlash"]
                            if not w
                            else v["std"]["backlash"]
                            if w == "_std"
                            else v["ci95"]["backlash"][w == "_hi"]
                        )
                    )
                )(what),
                "{:.4g}" if not what else "{:.3g}",
                0.05 * DIAGNOSE_CASES[case][0]["backlash"],
            )
            for case in ("backlash", "backlash_small")
            for what in ("", "_std", "_lo", "_hi")
        },
        # backlash where fast z tests hunt: its value, error [%] and 95 % interval, to the test's 5 % of the truth
        **{
            f"diagnose_{case}.backlash{what}": Figure(
                f"diagnose_{case}",
                (
                    lambda w, t: (
                        lambda v: (
                            v["fitted"]["backlash"]
                            if not w
                            else 100 * (v["fitted"]["backlash"] / t - 1)
                            if w == "_error_pct"
                            else v["ci95"]["backlash"][w == "_hi"]
                        )
                    )
                )(what, truth["backlash"]),
                fmt,
                tol,
            )
            for case, (truth, _, _) in DIAGNOSE_BACKLASH.items()
            for what, fmt, tol in (
                ("", "{:.4g}", 0.05 * truth["backlash"]),
                ("_error_pct", "{:+.1f}", 5.0),
                ("_lo", "{:.3g}", 0.05 * truth["backlash"]),
                ("_hi", "{:.3g}", 0.05 * truth["backlash"]),
            )
        },
        # the paper's case in full (docs/diagnose.md "The paper's case"): every test's NRMSE, the fitted values' std (to
        # the printed digit: a tenth of its last digit's unit moves the fit's covariance far more than floats do)
        **{
            f"diagnose_paper.test_{k}_{what}": Figure(
                "diagnose_paper", (lambda n, w: lambda v: v["tests"][n][w])(k, what), "{:.1f}", 0.05
            )
            for k in range(1, len(DIAGNOSE_PLAN) + 1)
            for what in ("before", "after", "floor")
        },
        **{
            f"diagnose_paper.std_{name}": Figure(
                "diagnose_paper", (lambda n: lambda v: v["std"][n])(name), "{:.2g}", tol
            )
            for name, tol in (("tau_c", 1e-6), ("J1_scale", 1e-5))
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


#: the runs of docs/sizing.md "What it says for the MAST": name -> (axis, amplitude [m], frequency [Hz], stop time [s]);
#: the 10 Hz test for 1 s (its steady cycle is the same as the paper's 3 s test's: the verdict repeats a cycle)
SIZING_RUNS = {"default": ("z", 0.01, 1.0, 3.0), "z_10Hz": ("z", 0.005, 10.0, 1.0)}


def sizing_values(sizing: Mapping) -> dict:
    """The figures of a run's sizing.json (`mast run` writes it): the limiting drive's items by name, its margin [%],
    and the minutes its winding takes to reach its limit with the cycle repeated."""
    drive = sizing["drives"][sizing["limiting"]["drive"]]
    items = {f"{i['component']} {i['item']}": i["figure"] for i in drive["items"]}
    return {
        "margin_pct": 100 * sizing["limiting"]["margin"],
        "belt_force_N": items["guide peak axial force"],
        "rms_current_A": items["motor RMS current"],
        "peak_current_A": items["amplifier peak current"],
        "winding_C": items["motor winding temperature, steady cycle"],
        "minutes_to_max": (drive.get("time_to_max_winding_temperature_s") or math.nan) / 60,
    }


def source_sizing(ssp: Path | None = None) -> dict:
    """SIZING_RUNS by `mast run --direct` on ``ssp`` (default: MAST.ssp built into a temporary folder): {run:
    sizing_values}; seconds."""
    from mast.cli import main as cli_main
    from mast.core.build import FMUS, SSP_SRC, build_fmu, build_ssp

    out = {}
    with tempfile.TemporaryDirectory(prefix="mast_figures_") as tmp:
        tmp = Path(tmp)
        if ssp is None:
            for spec in FMUS:
                if spec.model_identifier in ("MastActuator", "MastController", "MastMechanism"):
                    build_fmu(spec, tmp / "fmus")
            ssp = build_ssp(SSP_SRC / "MAST.ssd", tmp / "fmus", tmp / "ssp")
        for name, (axis, amplitude, frequency, stop) in SIZING_RUNS.items():
            argv = ["run", str(ssp), "--motion", axis, "--amplitude", f"{amplitude:g}", "--frequency", f"{frequency:g}"]
            argv += ["--stop-time", f"{stop:g}", "--direct", "--out", str(tmp / name)]
            if cli_main(argv) != 0:
                raise RuntimeError(f"mast run {name} failed (its message above)")
            out[name] = sizing_values(json.loads((tmp / name / "sizing.json").read_text()))
    return out


def source_defaults() -> dict:
    """Counts the commands' defaults define (README "First results"): the tests `mast synthesize` writes by default."""
    from mast.analyses.synthesize import DEFAULT_TESTS

    return {"synthesize_tests": len(DEFAULT_TESTS)}


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


def emps_diagnose_values(doc: Mapping, record) -> dict:
    """The figures of `mast diagnose` on the EMPS record (its diagnosis.json as a dict) and of our inverse-model least
    squares on the same record (``record``: the imported test, mast.data.records): docs/emps.md's tables."""
    from mast.analyses.inverse_model import inverse_model_ls

    sym, after = doc["symmetric_model"], doc["values"]
    ours = inverse_model_ls(record.time, record.values["q_m"], record.values["force"])
    ours_asym = inverse_model_ls(record.time, record.values["q_m"], record.values["force"], asymmetric=True)
    steps = [st for st in doc["steps"] if st.get("delta_bic_training") is not None]
    gaps = {"nominal": doc["gap"]["before"], "symmetric": sym["gap"], "diagnosed": doc["gap"]["after"]}
    out = {
        **{f"step_{k}_dbic": st["delta_bic_training"] for k, st in enumerate(steps, 1)},
        **{f"step_{k}_held_out_pct": st["held_out_rss_change_percent"] for k, st in enumerate(steps, 1)},
        **{f"sym_{p}": sym["values"][p] for p in ("M", "F_v", "F_c", "F_offset")},
        **{f"sym_{p}_std": sym["std"][p] for p in ("M", "F_v", "F_c", "F_offset")},
        **{f"sym_{p}_vs_published_pct": 100 * (sym["values"][p] / EMPS_PUBLISHED[p] - 1) for p in ("M", "F_v", "F_c")},
        "sym_F_offset_vs_published_N": sym["values"]["F_offset"] - EMPS_PUBLISHED["F_offset"],
        **{f"ours_{p}": ours[p] for p in ("M", "F_v", "F_c", "F_offset")},
        "ours_force_pct": ours["relative_error_pct"],
        "ours_F_v_pos": ours_asym["F_v+"],
        "ours_F_v_neg": ours_asym["F_v-"],
        # the two routes: the largest relative difference of M, F_v, F_c [%]
        "routes_pct": max(abs(100 * (sym["values"][p] / ours[p] - 1)) for p in ("M", "F_v", "F_c")),
        "F_v_pos": doc["asymmetry"]["viscous"]["positive_velocity"],
        "F_v_neg": doc["asymmetry"]["viscous"]["negative_velocity"],
        "F_c": after["F_c"],
        "dF_v": after["dF_v"],
        "F_offset": after["F_offset"],
        "F_offset_std": next(e for e in doc["named_effects"] if e["key"] == "offset")["uncertainty"]["F_offset"]["std"],
        "residual_rms_N": doc["gap"]["after"]["emps"]["force"]["whole"]["rms"],
        "residual_over_noise": doc["verdict"]["residual_over_noise_held_out"]["emps.force"],
        "noise_floor_N": doc["noise_floor"]["effort_std"],
        "simulations": doc["timing"]["simulations"],
        # the localisation before: the force residual's correlation with sign(velocity), its constant part's share [%];
        # the first re-simulated Gauss-Newton step from the regression's estimate: how much it lowers the cost [%]
        "sign_velocity_correlation": doc["localise"]["before"]["emps.force"]["correlation"]["sign(velocity)"],
        "bias_share_pct": 100 * doc["localise"]["before"]["emps.force"]["bias_share"],
        "first_step_cost_pct": 100 * (1 - steps[0]["fit"]["rss_history"][-1] / steps[0]["fit"]["rss_history"][0]),
    }
    for model, gap in gaps.items():
        for part in ("training", "held-out", "whole"):
            force = gap["emps"]["force"][part]
            out[f"{model}_{part}_force_pct"] = force["relative_error_pct"]
            out[f"{model}_{part}_force_fit"] = force["fit_pct"]
        out[f"{model}_q_m_pct"] = gap["emps"]["q_m"]["whole"]["relative_error_pct"]
    return out


def source_emps_diagnose() -> dict:
    """`mast diagnose` of the EMPS record on the bench (built into a temporary folder) from the nominal model, as
    tests/test_emps.py runs it: its emps_diagnose_values; about a minute."""
    from mast.core.build import FMUS, SSP_SRC, build_fmu, build_ssp
    from mast.data.importer import import_file
    from mast.data.record import load_records
    from mast.diagnosis import Options, diagnose

    with tempfile.TemporaryDirectory(prefix="mast_figures_") as tmp:
        tmp = Path(tmp)
        for spec in FMUS:
            if spec.model_identifier in ("MastLoadAxis", "MastEmpsController"):
                build_fmu(spec, tmp / "fmus")
        bench = build_ssp(SSP_SRC / "EMPS_bench.ssd", tmp / "fmus", tmp / "ssp")
        import_file(EMPS_RECORD, ROOT / "examples" / "emps" / "map.toml", tmp / "record")
        doc = diagnose(Options(tmp / "record", tmp / "out", str(bench), figures=False), log=lambda *_: None)
        return emps_diagnose_values(doc, load_records(tmp / "record").tests[0])


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
    equivalent alternatives) and the standard deviations of the named ones, and per held-out test (1, 2, ... in the
    plan's order) and per test (``tests``: every test in the plan's order) the torque NRMSE [%] before and after and
    its noise floor."""
    fitted: dict = {}
    std: dict = {}
    ci95: dict = {}
    for effect in doc["named_effects"]:
        for alternative in effect["evidence"].get("alternatives", []):
            fitted.update(alternative.get("parameters", {}))
        fitted.update(effect["parameters"])
        std.update({name: u["std"] for name, u in effect.get("uncertainty", {}).items()})
        ci95.update({name: u["ci95"] for name, u in effect.get("uncertainty", {}).items()})

    def nrmse(g: Mapping) -> dict:
        before, after = g["before"], g["after"]
        return {
            "before": before["torque_nrmse_percent"],
            "after": after["torque_nrmse_percent"],
            "floor": before["torque_floor_percent"],
        }

    gaps = list(doc["gap"].values())
    return {
        "fitted": fitted,
        "std": std,
        "ci95": ci95,
        # per effect the cross-validation judged: the held-out residual summed over its folds, without it / with it
        "cross_validation": {
            key: e["held_out_rss_without"] / e["held_out_rss_with"]
            for key, e in doc.get("cross_validation", {}).get("effects", {}).items()
            if e.get("held_out_rss_with")
        },
        "held_out": {k: nrmse(g) for k, g in enumerate((g for g in gaps if g["role"] == "held-out"), 1)},
        "tests": {k: nrmse(g) for k, g in enumerate(gaps, 1)},
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


def source_diagnose_hexapod() -> dict:
    """`mast diagnose --direct` of DIAGNOSE_HEXAPOD hidden by `mast synthesize` on the Python FMUs' MAST_<system>.ssp,
    as tests/test_hexapod_diagnosis.py runs it: its diagnose_values."""
    from mast.analyses.synthesize import TestSpec, synthesize
    from mast.diagnosis import Options, diagnose

    h = DIAGNOSE_HEXAPOD
    ssp = str(_diagnose_build() / f"MAST_{h['system']}.ssp")
    with tempfile.TemporaryDirectory(prefix="mast_figures_") as tmp:
        data = Path(tmp) / "data"
        hidden = {f"actuator_{h['drive']}": {"tau_c": h["tau_c"]}}
        plan = tuple(TestSpec(*t) for t in h["plan"])
        synthesize(ssp, data, hidden, tests=plan, direct=True, seed=h["seed"], log=lambda *_: None)
        doc = diagnose(
            Options(data, Path(tmp) / "out", ssp, figures=False, direct=True, library=hexapod_library()),
            log=lambda *_: None,
        )
    return diagnose_values(doc)


def source_diagnose(case: str) -> dict:
    """`mast diagnose` of DIAGNOSE_CASES[case] (on DIAGNOSE_PLAN, or DIAGNOSE_CASE_PLANS') or of the case of
    DIAGNOSE_HEAVIER_LIGHTER, DIAGNOSE_LAGS, DIAGNOSE_BACKLASH, DIAGNOSE_PER_AXIS or DIAGNOSE_ONE_AXIS_AND_DRIVE (on its
    plan) hidden by
    `mast synthesize` (the Python models synthesize, the native variant re-simulates, as tests/test_diagnose.py runs
    it): its diagnose_values."""
    from mast.analyses.synthesize import TestSpec, synthesize
    from mast.diagnosis import Options, diagnose

    truth, seed, plan_name = (
        (*DIAGNOSE_CASES[case], DIAGNOSE_CASE_PLANS.get(case, "compact"))
        if case in DIAGNOSE_CASES
        else {
            **DIAGNOSE_HEAVIER_LIGHTER,
            **DIAGNOSE_LAGS,
            **DIAGNOSE_BACKLASH,
            **DIAGNOSE_PER_AXIS,
            **{case: entry[:3] for case, entry in DIAGNOSE_ONE_AXIS_AND_DRIVE.items()},
        }[case]
    )
    hidden = truth if case in (*DIAGNOSE_PER_AXIS, *DIAGNOSE_ONE_AXIS_AND_DRIVE) else {"actuator": truth}
    ssp = _diagnose_build()
    with tempfile.TemporaryDirectory(prefix="mast_figures_") as tmp:
        data, plan = Path(tmp) / "data", tuple(TestSpec(*t) for t in DIAGNOSE_PLANS[plan_name])
        synthesize(str(ssp / "MAST.ssp"), data, hidden, tests=plan, direct=True, seed=seed, log=lambda *_: None)
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
        F = eng.inverse_dynamics_at_pose(m.topology.home, [0.0] * 3, [0.0] * 3).t_rho
        out[name] = {
            "parallel": margins.parallel,
            "inverse": margins.inverse,
            "dexterity": margins.dexterity,
            **{f"F_home_{k}": float(F[k - 1]) for k in (1, 2, 3)},
            "carriage_N": m.drive["M_load"] * m.drive["g_guide"],
        }
    return out


def source_workspace(quick: bool = False) -> dict:
    """The designs' `mast workspace` summaries on its default grid, or on `mast compare --quick`'s."""
    from mast.analyses.compare import WORKSPACE_GRID, WORKSPACE_GRID_QUICK
    from mast.analyses.workspace import compute, machine, summarize

    out = {}
    for name in ("3PRS_T", "3PRS_120", "3PRS_inclined"):
        ws = compute(machine(name), *(WORKSPACE_GRID_QUICK if quick else WORKSPACE_GRID))
        s = summarize(ws)
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
            "largest_force_N": s["static_forces"]["largest_N"],
            **workspace_details(ws, s),
        }
    return out


def home_mass_eigenvalues(m) -> list[float]:
    """The eigenvalues [kg] of a machine's joint-space mass matrix at home, ascending."""
    import numpy as np

    n = len(m.topology.drives)
    M = m.engine().inverse_dynamics_at_pose(m.topology.home, [0.0] * n, [0.0] * n).M
    return [float(e) for e in np.linalg.eigvalsh(np.asarray(M, dtype=float).reshape(n, n))]


def section_values(summary: Mapping) -> dict:
    """A workspace summary's (``mast.analyses.workspace.summarize``) ranges through home and extents (``<c>_home_lo_m``,
    ``<c>_extent_hi_deg``, ...), its smallest margin, worst dexterity, largest static force [N] and the share of its
    boundary each cause bounds [%] (``<cause>_pct``: stroke, reach, singularity)."""
    out: dict = {}
    for what, ranges in (("home", summary["ranges_through_home"]), ("extent", summary["extent"])):
        for column, (lo, hi) in ranges.items():
            c, unit = column.rsplit("_", 1)
            out[f"{c}_{what}_lo_{unit}"], out[f"{c}_{what}_hi_{unit}"] = lo, hi
    causes = {
        "outside the stroke": "stroke",
        "not assemblable": "reach",
        "within the margin of a singularity": "singularity",
    }
    return {
        **out,
        **{f"{name}_pct": 100 * summary["limited_by"].get(cause, 0.0) for cause, name in causes.items()},
        "smallest_margin": summary["smallest_margin"]["value"],
        "worst_dexterity": summary["worst_dexterity"]["value"],
        "largest_force_N": summary["static_forces"]["largest_N"],
        "singularity_home_m": summary["distance_to_singularity_at_home_m"],
    }


def _sections(m) -> dict[str, dict]:
    """A six-coordinate machine's three workspace sections on HEXAPOD_GRID: x, y, z at the home orientation; psi,
    theta, phi at the home position; z, psi, theta."""
    from mast.analyses.workspace import compute, summarize

    step, tilt = HEXAPOD_GRID[0], math.radians(HEXAPOD_GRID[1])
    return {
        sweep: summarize(compute(m, step, tilt, sweep=sweep.split(",")))
        for sweep in ("x,y,z", "psi,theta,phi", "z,psi,theta")
    }


def source_hexapod() -> dict:
    """The 6-UPS's margins, static forces and mass matrix at home (its description's values) and its workspaces on
    HEXAPOD_GRID: x, y, z at the home orientation [L], psi, theta, phi at the home position [deg^3], z, psi, theta
    [m deg^2], the ranges through home, and over the three the smallest margin, worst dexterity, the largest static
    leg force of the x, y, z section and the smallest share of a boundary the strokes bound."""
    from fmus.mechanism.description import load
    from fmus.mechanism.engine import Engine
    from mast.analyses.workspace import machine

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
    volume = _sections(m)
    sections = {sweep: section_values(s) for sweep, s in volume.items()}
    xyz, angles = sections["x,y,z"], sections["psi,theta,phi"]
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
        **{k: v for k, v in xyz.items() if k.startswith(("x_", "y_", "z_home"))},
        **{k: v for k, v in angles.items() if "_home_" in k},
        "smallest_margin": min(s["smallest_margin"] for s in sections.values()),
        "worst_dexterity": max(s["worst_dexterity"] for s in sections.values()),
        "largest_force_N": xyz["largest_force_N"],
        "stroke_bound_pct": min(s["stroke_pct"] for s in sections.values()),
        **{f"M_eig_{k}_kg": e for k, e in enumerate(home_mass_eigenvalues(m), 1)},
    }


def source_hexapod_pus() -> dict:
    """The 6-PUS's home height [m], margins, static carriage forces (and with massless links) and mass matrix at home,
    its workspaces on HEXAPOD_GRID as the 6-UPS's, and what bounds the x, y, z section [%]."""
    from fmus.mechanism.description import load
    from fmus.mechanism.engine import Engine
    from mast.analyses.workspace import machine

    m = machine("6PUS")
    eng = m.engine()
    home = m.topology.home
    margins = eng.margins(home)
    F = eng.inverse_dynamics_at_pose(home, [0.0] * 6, [0.0] * 6).t_rho
    file = load("6PUS")
    bare = Engine(file.describe({**file.values(), "m_link": 0.0}), g=file.values()["g"])
    volume = _sections(m)
    xyz = section_values(volume["x,y,z"])
    angles = section_values(volume["psi,theta,phi"])
    return {
        "z_home_m": home[2],
        "parallel": margins.parallel,
        "inverse": margins.inverse,
        "dexterity": margins.dexterity,
        "F_home": float(F[0]),
        "F_home_massless": float(bare.inverse_dynamics_at_pose(home, [0.0] * 6, [0.0] * 6).t_rho[0]),
        **{f"M_eig_{k}_kg": e for k, e in enumerate(home_mass_eigenvalues(m), 1)},
        "volume_xyz_L": 1e3 * volume["x,y,z"]["volume_m3"],
        **{k: v for k, v in xyz.items() if k.startswith(("x_home", "y_home", "z_home"))},
        **{f"xyz_{why}_pct": xyz[f"{why}_pct"] for why in ("reach", "stroke", "singularity")},
        "volume_angles_deg3": volume["psi,theta,phi"]["volume_deg3"],
        **{k: v for k, v in angles.items() if "_home_" in k},
        "volume_z_psi_theta_m_deg2": volume["z,psi,theta"]["volume_m_deg2"],
    }


def source_rps() -> dict:
    """The 3-RPS (docs/designs/3rps.md): its parasitic motion at psi = theta = 10 deg [mm, deg]; at home its static leg
    force [N] and motor torque [mN m] (through actuator_1's screw of ssp/MAST_3RPS.ssd), the force's parts (the
    carriage's, the platform's, the rail's), the mass matrix' eigenvalues [kg], cond(drho/dq), margins and det; its
    workspace on the default grid and (``quick_``) on `mast compare --quick`'s."""
    from fmus.mechanism.description import load
    from fmus.mechanism.engine import Engine
    from mast.analyses.compare import WORKSPACE_GRID, WORKSPACE_GRID_QUICK
    from mast.analyses.workspace import compute, machine, summarize
    from mast.core.ssp import read_ssd

    m = machine("3RPS")
    eng = m.engine()
    home = m.topology.home
    x, y, _, _, _, phi = eng.pose((home[0], math.radians(10.0), math.radians(10.0)))
    file = load("3RPS")
    values = file.values()

    def force(**zero: float) -> float:
        engine = Engine(file.describe({**values, **zero}), g=values["g"])
        return float(engine.inverse_dynamics_at_pose(home, [0.0] * 3, [0.0] * 3).t_rho[0])

    F, no_carriage, platform = force(), force(m_carriage=0.0), force(m_carriage=0.0, m_cylinder=0.0)
    actuator = read_ssd(ROOT / "ssp" / "MAST_3RPS.ssd").components["actuator_1"].parameters
    margins = eng.margins(home)
    out = {
        "parasitic_phi_deg": math.degrees(phi),
        "parasitic_y_mm": 1e3 * y,
        "parasitic_x_mm": 1e3 * x,
        "F_home": F,
        "tau_home_mNm": 1e3 * F * float(actuator["p"]) / (2 * math.pi * float(actuator["i_r"])),
        "F_carriage": F - no_carriage,
        "F_platform": platform,
        "F_rail": no_carriage - platform,
        **{f"M_eig_{k}_kg": e for k, e in enumerate(home_mass_eigenvalues(m), 1)},
        "cond": eng.jacobian(home)[2],
        "parallel": margins.parallel,
        "inverse": margins.inverse,
    }
    for prefix, grid in (("", WORKSPACE_GRID), ("quick_", WORKSPACE_GRID_QUICK)):
        s = summarize(compute(m, *grid))
        section = section_values(s)
        out.update(
            {
                f"{prefix}volume_m_deg2": s["volume_m_deg2"],
                **{f"{prefix}{k}": section[k] for k in section if k.startswith(("psi_", "theta_", "z_home"))},
                f"{prefix}stroke_bound_pct": section["stroke_pct"],
                **{
                    f"{prefix}{k}": section[k]
                    for k in ("singularity_home_m", "smallest_margin", "worst_dexterity", "largest_force_N")
                },
                f"{prefix}largest_force_theta_deg": s["static_forces"]["at"]["theta_deg"],
            }
        )
        out.setdefault("det", s["home"]["det"])
    return out


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


#: docs/diagnose.md: the softer transmission [N m/rad] of tests/test_diagnose_unseen.py
#: test_a_softer_transmission_is_named_as_itself
DIAGNOSE_SOFT_K_T = 5.0


def source_diagnose_model() -> dict:
    """What docs/diagnose.md reasons from, from the parameter sets ssp/MAST.ssd binds (actuator_1, the controller):
    the transmission's stiffness K_t [N m/rad] (paper Table 1) and its mode sqrt(K_t (J1 + J2) / (J1 J2)) [Hz] (paper
    Eqs. 2-3) there and at DIAGNOSE_SOFT_K_T; the force along the guide [N] the drive holds at its current limit, k_T
    i_max / i_R (friction aside), and the carriage mass [kg] whose weight that is (tests/test_diagnose_unseen.py
    test_a_failed_trial_is_information_not_the_end: every trial that fails is heavier); the number of effects the
    hexapod's diagnosis is offered (DIAGNOSE_HEXAPOD). No simulation."""
    from fmus.actuator.model import transmission_ratio, two_inertia
    from mast.core.ssp import read_ssd

    system = read_ssd(ROOT / "ssp" / "MAST.ssd")
    actuator = dict(system.components["actuator_1"].parameters)
    K_t = float(actuator["K_t"])

    def mode_Hz(stiffness: float) -> float:
        J1, J2 = two_inertia(actuator)
        return math.sqrt(stiffness * (J1 + J2) / (J1 * J2)) / (2 * math.pi)

    i_R = transmission_ratio(float(actuator["p"]), float(actuator["i_r"]))
    holding = float(actuator["k_T"]) * float(system.components["controller"].parameters["i_max"]) / i_R
    return {
        "K_t": K_t,
        "mode_Hz": mode_Hz(K_t),
        "mode_soft_Hz": mode_Hz(DIAGNOSE_SOFT_K_T),
        "holding_N": holding,
        "holding_kg": holding / float(actuator["g_guide"]),
        "hexapod_effects": len(hexapod_library()),
    }


# -- README.md, docs/actuator.md, controller.md, batch.md, interfaces.md, using-the-fmus.md, geometry.md --------------
def source_sets() -> dict:
    """Every parameter set of ssp/resources: {set: {name: value}} (numbers only, SI as the sets state them)."""
    from mast.core.ssv import parse_ssv

    return {
        path.stem: {name: v.value for name, v in parse_ssv(path).items() if isinstance(v.value, (int, float))}
        for path in sorted((ROOT / "ssp" / "resources").glob("*.ssv"))
    }


def source_actuator() -> dict:
    """docs/actuator.md's figures from the actuator's parameter sets (manufacturer: transmission.ssv,
    actuator_manufacturer.ssv, stroke_3prs.ssv; identified: actuator_identified.ssv over it; the paper reading's
    carriage: actuator_paper_reading.ssv's M_load) through ``fmus.actuator.model``: i_R [m/rad], J1, J2 [kg m^2],
    the two-inertia model's natural frequencies [Hz], the inertia Table 1's f_n would need, the discretisation's
    figures (electrical pole [1/s], phase of the fastest mode per 100 us step [rad], substeps), the static deflection
    under the carriage's weight, the friction law's time constant [us], and the paper data's questionable points."""
    from fmus.actuator.model import natural_frequencies, substep_rule, transmission_ratio, two_inertia
    from mast.analyses import paper

    sets = source_sets()
    p = {**sets["transmission"], **sets["actuator_manufacturer"], **sets["stroke_3prs"]}
    ident = {**p, **sets["actuator_identified"]}
    reading = {**p, "M_load": sets["actuator_paper_reading"]["M_load"]}
    i_R = transmission_ratio(p["p"], p["i_r"])
    J1, J2 = two_inertia(p)
    f, f_ident = natural_frequencies(p), natural_frequencies(ident)
    f_reading = natural_frequencies(reading)
    f_reading_ident = natural_frequencies({**reading, "J1_scale": ident["J1_scale"]})
    K_t, h = p["K_t"], 1e-4
    omega_1 = 2 * math.pi * f["TF1"]
    J_eff = J1 * J2 / (J1 + J2)
    J_fn = K_t / (2 * math.pi * paper.FN_TABLE1) ** 2
    weight = i_R * p["M_load"] * p["g_guide"]
    eq23 = p["tau_c"] * p["i_r"]  # the set's Eq. 23 friction, at the guide shaft [N m]
    eta = sets["drive_ratings"]["eta_gear"]
    raw_J1 = p["J_motor"] + p["J_gearbox"] + p["J_coupling"] + p["J_brake"]
    J1_coupling_right = raw_J1 - p["J_coupling"] + p["J_coupling"] / p["i_r"] ** 2
    return {
        "i_R": i_R,
        "J1": J1,
        "J1_identified": two_inertia(ident)[0],
        "J2_guide": p["J_guide"] / p["i_r"] ** 2,
        "J2_carriage": p["M_load"] * i_R**2,
        "J2": J2,
        "TF2_Hz": f["TF2"],
        "TF2_p66_Hz": natural_frequencies({**p, "p": 0.066})["TF2"],
        "TF1_Hz": f["TF1"],
        "TF1_identified_Hz": f_ident["TF1"],
        "TF2d_Hz": f["TF2d"],
        "TF2d_identified_Hz": f_ident["TF2d"],
        "J_for_table1_fn": J_fn,
        "J_for_table1_fn_pct": 100 * J_fn / J2,
        "J_for_900Hz": K_t / (2 * math.pi * 900.0) ** 2,
        "reading_TF2_Hz": f_reading["TF2"],
        "reading_TF1_Hz": f_reading["TF1"],
        "reading_TF1_identified_Hz": f_reading_ident["TF1"],
        "R_over_L": p["R"] / p["L"],
        "zeta_TF1": p["C_t"] / (2 * math.sqrt(K_t * J_eff)),
        "phase_100us_rad": omega_1 * h,
        "substeps_100us": substep_rule(omega_1, h, 0.0, 0.0, 1.0)[0],
        "substeps_1ms": substep_rule(omega_1, 1e-3, 0.0, 0.0, 1.0)[0],
        "substeps_46kHz_100us": substep_rule(2 * math.pi * 46e3, h, 0.0, 0.0, 1.0)[0],
        "backlash_substeps_100us": substep_rule(omega_1, h, 1e-6, 0.0, 1.0)[0],
        "static_deflection_rad": weight / K_t,
        "static_deflection_um": 1e6 * i_R * weight / K_t,
        "friction_time_identified_us": 1e6 * J2 * p["omega_c"] / ident["tau_c"],
        "friction_time_manufacturer_us": 1e6 * J2 * p["omega_c"] / p["tau_c"],
        "coupling_at_motor": p["J_coupling"] / p["i_r"] ** 2,
        "coupling_J1_pct": 100 * (1 - J1_coupling_right / raw_J1),
        "coupling_J1_factor": raw_J1 / J1_coupling_right,
        "eq23_guide_Nm": eq23,
        "identified_over_eq23": ident["tau_c"] / p["tau_c"],
        "gear_loss_Nm": p["tau_c"] * (1 / eta - 1),
        "eta_gear_pct": 100 * eta,
        "k_E_mV": 1e3 * p["k_E"],
        "k_T_mNm": 1e3 * p["k_T"],
        "k_T_k_E_pct": 100 * (p["k_T"] / p["k_E"] - 1),
        "weight_torque_Nm": weight,
        "weight_over_tau_c_pct": 100 * weight / p["tau_c"],
        "creep_mm_s": 1e3 * i_R * p["omega_c"] * math.atanh(weight / p["tau_c"]),
        "creep_identified_mm_s": 1e3 * i_R * p["omega_c"] * math.atanh(weight / ident["tau_c"]),
        "omega_c_carriage_mm_s": 1e3 * i_R * p["omega_c"],
        "brake_J1_pct": 100 * p["J_brake"] / (raw_J1 - p["J_brake"]),
    }


def source_geometry() -> dict:
    """The 3PRS's home pose (its description, 3PRS_T.toml): z [m], the legs' height above the sliders at mid-stroke
    [m] and their elevation gamma [deg]; the largest tilt the kinematics admit (MAX_TILT) [deg]."""
    from fmus.mechanism.kinematics import MAX_TILT
    from mast.analyses.workspace import machine

    m = machine("3PRS_T")
    z, rho = m.topology.home[0], m.rho_home[0]
    L = source_sets()["geometry_3prs"]["L"]
    return {
        "z_home_m": z,
        "leg_height_m": z - rho,
        "gamma_deg": math.degrees(math.asin((z - rho) / L)),
        "max_tilt_deg": math.degrees(MAX_TILT),
    }


def source_examples(build: Path | None = None) -> dict:
    """The cases `mast batch --dry-run` lists for the example configs (their SSPs from ``build``, default the
    checkout's build/: `mast build` first): examples/friction_sweep.yaml's cases and frequency sweeps,
    examples/hexapod_sweep.toml's cases, examples/monte_carlo_bandwidth.toml's machines and cases and its script's
    (the nominal machine's sweep beside them); and the sine tests `mast compare --controller` runs with every
    controller on the default test set, as designed and with the payload; the signals MAST_standalone.ssp records by
    default, which `mast hosts` compares."""
    from mast.analyses.compare import DEFAULT
    from mast.analyses.workspace import machine
    from mast.batch import BatchConfig, expand
    from mast.batch.cases import SystemInfo
    from mast.core.controllers import CONTROLLERS
    from mast.core.run import default_signals
    from mast.core.ssp import SSPArchive

    build = build or ROOT / "build"

    def cases(name: str) -> tuple[BatchConfig, list]:
        config = BatchConfig.load(ROOT / "examples" / name)
        systems = {v: SystemInfo.read(build / "ssp" / Path(path).name) for v, path in config.ssp.items()}
        return config, expand(config, systems)

    friction, friction_cases = cases("friction_sweep.yaml")
    monte_carlo, monte_carlo_cases = cases("monte_carlo_bandwidth.toml")
    sweep = len(monte_carlo.cases["frequency"])
    with SSPArchive(build / "ssp" / "MAST_standalone.ssp") as archive:
        standalone = default_signals(archive.system)
    coordinates = len(machine("3PRS_T").topology.names)
    return {
        "friction_sweep_cases": len(friction_cases),
        "friction_sweep_groups": len(friction_cases) // len(friction.cases["frequency"]),
        "hexapod_sweep_cases": len(cases("hexapod_sweep.toml")[1]),
        "monte_carlo_machines": len(monte_carlo_cases) // sweep,
        "monte_carlo_cases": len(monte_carlo_cases),
        "monte_carlo_study_cases": len(monte_carlo_cases) + sweep,
        # as designed and with the payload, every controller, frequency and coordinate of the 3PRS
        "controllers_full_tests": 2 * len(CONTROLLERS) * len(DEFAULT.frequencies) * coordinates,
        "standalone_signals": len(standalone),
    }


# -- docs/mechanism.md, docs/workspace.md, docs/designs/*.md, docs/native.md (auditB) ----------------------------------
#: the 3PRS designs the design pages state figures of
DESIGN_NAMES = ("3PRS_T", "3PRS_120", "3PRS_inclined")
#: docs/designs: the sines of "what dominates": motion -> amplitude [m, rad], at DOMINATES_HZ, split at 45 deg of the
#: cycle
DOMINATES = {"z": 0.005, "psi": math.radians(0.8)}
DOMINATES_HZ = 5.0
#: docs/workspace.md: the squares of combined tilts (|psi|, |theta| <= X deg) whose heights the pages state
SQUARES_DEG = (10, 15, 20)
#: docs/workspace.md: the payload [kg] on the T design's platform, default grid
WORKSPACE_PAYLOAD_KG = 5.0
#: docs/native.md: the native mechanisms whose generated C the page sizes (FMU -> name on the page)
NATIVE_MECHANISMS = {"MastMechanism": "3PRS", "Mast3RPS": "3RPS", "Mast6PUS": "6PUS", "Mast6UPS": "6UPS"}


def sine_joints(eng, home, axis: int, amplitude: float, frequency: float, phase: float, h: float = 1e-4) -> tuple:
    """(q, rho_dot, rho_ddot) of the pose ``home`` + ``amplitude`` sin(2 pi f t) along coordinate ``axis`` at
    ``phase`` [rad]: rho_dot = drho/dq q_dot, rho_ddot by central second differences of the inverse kinematics over
    ``h`` [s] (an error of order h^2, far below the printed digits)."""
    w = 2 * math.pi * frequency
    t = phase / w

    def q_at(time: float) -> list[float]:
        q = list(home)
        q[axis] += amplitude * math.sin(w * time)
        return q

    q = q_at(t)
    n = len(q)
    A = eng.jacobian(q)[0]
    q_dot = [0.0] * n
    q_dot[axis] = amplitude * w * math.cos(w * t)
    rho_dot = [sum(A[i * n + j] * q_dot[j] for j in range(n)) for i in range(n)]
    before, now, after = (eng.ik(q_at(t + k * h)) for k in (-1, 0, 1))
    rho_ddot = [(a - 2 * b + c) / h**2 for a, b, c in zip(after, now, before)]
    return q, rho_dot, rho_ddot


def source_design_pages() -> dict:
    """The 3PRS designs' pages (docs/designs/*.md, docs/mechanism.md): per design at home its pose z [m], static forces
    [N] and their sum, the mass matrix' eigenvalues [kg], cond(drho/dq), drho/dz of guide 1; the split of the forces
    into inertial, velocity and gravity terms [N] for the DOMINATES sines at 45 deg of the cycle (and the velocity
    terms' largest there [mN]); the 120 deg layout's parasitic motion at psi = theta = 10 deg [deg, mm]; the inclined
    guides' gravity g_guide [m/s^2] its set binds; the actuators-only design's z above the mean carriage [m]; the sine
    tests of docs/designs/README.md's full comparison of its four designs (``compare_tests``)."""
    from mast.analyses.compare import DEFAULT, for_axes
    from mast.analyses.workspace import machine
    from mast.core.ssv import parse_ssv

    out: dict = {}
    for name in DESIGN_NAMES:
        m = machine(name, 0.0)
        eng = m.engine()
        home = list(m.topology.home)
        idp = eng.inverse_dynamics_at_pose(home, [0.0] * 3, [0.0] * 3)
        A, _, cond = eng.jacobian(home)
        d = {
            "z_home_m": home[0],
            **{f"F_home_{k}": float(f) for k, f in enumerate(idp.t_rho, 1)},
            "F_home_sum": float(sum(idp.t_rho)),
            **{f"M_eig_{k}_kg": e for k, e in enumerate(home_mass_eigenvalues(m), 1)},
            "cond": cond,
            "drho_dz": A[0],
        }
        for motion, amplitude in DOMINATES.items():
            axis = m.topology.names.index(motion)
            res = eng.inverse_dynamics_at_pose(*sine_joints(eng, home, axis, amplitude, DOMINATES_HZ, math.pi / 4))
            for part, values in (("F", res.t_rho), ("inertial", res.I_term), ("velocity", res.c_term)):
                d.update({f"{motion}_{part}_{k}": float(v) for k, v in enumerate(values, 1)})
            d.update({f"{motion}_gravity_{k}": float(v) for k, v in enumerate(res.g_term, 1)})
            d[f"{motion}_velocity_max_mN"] = 1e3 * max(abs(float(c)) for c in res.c_term)
        out[name] = d
    eng120 = machine("3PRS_120", 0.0).engine()
    _, y, _, _, _, phi = eng120.pose((out["3PRS_120"]["z_home_m"], math.radians(10.0), math.radians(10.0)))
    out["3PRS_120"].update({"parasitic_phi_deg": math.degrees(phi), "parasitic_y_mm": 1e3 * y})
    guide = parse_ssv(ROOT / "ssp" / "resources" / "guide_inclined.ssv")
    out["3PRS_inclined"]["g_guide"] = guide["g_guide"].value
    actuators_only = machine("actuators_only", 0.0)
    out["actuators_only"] = {"z_above_carriages_m": actuators_only.topology.home[0] - actuators_only.rho_home[0]}
    # the full design comparison of docs/designs/README.md: its four designs, each motion of a 3PRS at each frequency
    test_set = for_axes(DEFAULT, actuators_only.topology.names)
    out["compare_tests"] = 4 * len(test_set.axes) * len(test_set.frequencies)
    return out


def workspace_details(ws, summary: Mapping) -> dict:
    """A 3PRS workspace's figures beyond ``source_workspace``'s: z through home [m], the share of its boundary each
    cause stops [%], where its smallest margin and its nearest sampled singular pose lie [m, deg], and per square of
    SQUARES_DEG the heights at which every pose of the square is inside (``square_<X>_lo_m``, ``_hi_m``: NaN where
    none) and their number (``square_<X>_levels``)."""
    import numpy as np

    from mast.analyses.workspace import INSIDE

    z, psi, theta = (np.asarray(a) for a in ws.axes)
    out: dict = {}
    for X in SQUARES_DEG:
        tilts = np.radians(X) + 1e-9
        inside = ws.status[:, np.abs(psi) <= tilts][:, :, np.abs(theta) <= tilts] == INSIDE
        levels = z[inside.all(axis=(1, 2))]
        out[f"square_{X}_levels"] = len(levels)
        out[f"square_{X}_lo_m"], out[f"square_{X}_hi_m"] = (
            (float(levels.min()), float(levels.max())) if len(levels) else (math.nan, math.nan)
        )
    shares = summary["limited_by"]
    at_margin = summary["smallest_margin"]["at"]
    at_singular = summary["smallest_distance_to_singularity_m"]["at"]
    return {
        **out,
        "z_home_lo_m": summary["ranges_through_home"]["z_m"][0],
        "z_home_hi_m": summary["ranges_through_home"]["z_m"][1],
        "stroke_pct": 100 * shares.get("outside the stroke", 0.0),
        "singularity_pct": 100 * shares.get("within the margin of a singularity", 0.0),
        "branch_pct": 100 * shares.get("on the other assembly branch", 0.0),
        "smallest_margin_z_m": at_margin["z_m"],
        "smallest_margin_psi_deg": at_margin["psi_deg"],
        **({f"singular_{k}": v for k, v in at_singular.items()} if at_singular else {}),
    }


def source_workspace_payload() -> dict:
    """`mast workspace 3PRS_T --payload WORKSPACE_PAYLOAD_KG` on the default grid: the static force of legs 1 and 3 at
    home, the largest inside and where [N, m, deg], the motor torque that holds it and the drives' peak [N m], their
    ratio and the share of the poses beyond the peak [%]; about 10 s."""
    from mast.analyses.compare import WORKSPACE_GRID
    from mast.analyses.workspace import compute, machine, summarize

    forces = summarize(compute(machine("3PRS_T", WORKSPACE_PAYLOAD_KG), *WORKSPACE_GRID))["static_forces"]
    return {
        "F_home_1": forces["home_N"][0],
        "F_home_3": forces["home_N"][2],
        "largest_N": forces["largest_N"],
        **{f"at_{k}": v for k, v in forces["at"].items()},
        "torque_Nm": forces["largest_motor_torque_Nm"],
        "peak_Nm": forces["motor_peak_torque_Nm"],
        "torque_over_peak": forces["largest_torque_fraction_of_peak"],
        "beyond_peak_pct": 100 * forces["fraction_of_poses_beyond_peak_torque"],
    }


def source_native(build: Path | None = None) -> dict:
    """docs/native.md's counts and sizes of the generated C, from the native FMUs of ``build`` (default: the checkout's
    build/, `mast build --native` first): per mechanism the generated C [kB]; the drive actuator's generated C [KiB]
    and its step kernels in all and for n_dof = 2 and 1; the assignments of the 3PRS's traced ikjac, dynamics and pose
    that the parameters alone fix (translate.split_invariants); the chains' top modes of why N_MAX = 8 [kHz]."""
    import re
    import zipfile

    from fmus.mechanism.designs import traced_engine
    from mast.core.build import default_parameters
    from mast.core.native.translate import split_invariants

    fmus = (build or ROOT / "build") / "fmus" / "native"

    def size(fmu: str, member: str) -> int:
        with zipfile.ZipFile(fmus / f"{fmu}.fmu") as z:
            return z.getinfo(member).file_size

    with zipfile.ZipFile(fmus / "MastActuator.fmu") as z:
        source = z.read("sources/MastActuator_model.c").decode()
    kernels = re.findall(r"^static int kernel_n(\d+)_\w+\(", source, re.M)
    eng = traced_engine(default_parameters("MastMechanism"), "MastMechanism")
    hoisted = {
        name: split_invariants(eng._fn(name).source, list(eng.parameters))[2] for name in ("ikjac", "forces", "pose")
    }
    return {
        **{f"c_kB_{label}": size(fmu, f"sources/{fmu}_model.c") / 1e3 for fmu, label in NATIVE_MECHANISMS.items()},
        "actuator_c_KiB": len(source.encode()) / 2**10,
        "actuator_so_KiB": size("MastActuator", "binaries/linux64/MastActuator.so") / 2**10,
        "kernels": len(kernels),
        "kernels_n2": kernels.count("2"),
        "kernels_n1": kernels.count("1"),
        "invariants_ikjac": hoisted["ikjac"],
        "invariants_dynamics": hoisted["forces"],
        "invariants_pose": hoisted["pose"],
        # why N_MAX = 8: the top mode [kHz] of the paper's transmission (actuator_1 of ssp/MAST.ssd: its J2 and K_t)
        # split evenly over n - 1 bodies and springs behind the motor's J1
        **{f"chain_top_kHz_{n}": chain_top_mode_Hz(n) / 1e3 for n in (4, 6, 8)},
    }


def chain_top_mode_Hz(n: int) -> float:
    """The highest natural frequency [Hz] of an n-body chain: the motor side J1 of actuator_1 in ssp/MAST.ssd, then
    its guide side J2 split into n - 1 equal bodies joined by n - 1 equal springs of stiffness (n - 1) K_t."""
    from fmus.actuator.model import chain_frequencies, two_inertia
    from mast.core.ssp import read_ssd

    params = read_ssd(ROOT / "ssp" / "MAST.ssd").components["actuator_1"].parameters
    J1, J2 = two_inertia(params)
    return float(chain_frequencies([J1] + [J2 / (n - 1)] * (n - 1), [float(params["K_t"]) * (n - 1)] * (n - 1)).max())


def emps_pulses_values(diagnosed: Path, bench: Path, tmp: Path) -> dict:
    """docs/emps.md "A record with injected inputs": the synthetic pulse record (examples/emps/pulse_record.py, the
    truth simulated on ``bench``) imported as examples/emps/map_pulses.toml says (``applied``), with its effort
    declared logged before the injection (``before_injection``: the import's warning's step [N], gain [N/V] and
    edges too) and with the estimation record's map (``not_applied``: u_inj = 0), replayed with the ``diagnosed``
    bench, and as imported replayed with the nominal ``bench``: {case: {q_m, force: relative error [%], force_fit}}."""
    import importlib.util
    import re

    from mast.analyses.replay import replay
    from mast.data.importer import import_file

    spec = importlib.util.spec_from_file_location("pulse_record", ROOT / "examples" / "emps" / "pulse_record.py")
    pulse_record = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(pulse_record)
    record = tmp / "emps_pulses.mat"
    pulse_record.make(EMPS_RECORD, record, bench)
    maps = ROOT / "examples" / "emps"
    before = tmp / "map_before_injection.toml"
    text = (maps / "map_pulses.toml").read_text()
    before.write_text(text.replace("sampled = true", 'sampled = true\ntap = "before_injection"', 1))
    out: dict = {}
    for case, mapping, ssp in (
        ("applied", maps / "map_pulses.toml", diagnosed),
        ("before_injection", before, diagnosed),
        ("not_applied", maps / "map.toml", diagnosed),
        ("nominal", maps / "map_pulses.toml", bench),
    ):
        summary = import_file(record, mapping, tmp / f"record_{case}")
        if case == "before_injection":
            found = re.search(r"steps by ([\d.]+) N \(([\d.]+) N/V\) at the (\d+) edges", " ".join(summary["warnings"]))
            out["warning"] = {"step_N": float(found[1]), "gain_N_per_V": float(found[2]), "edges": int(found[3])}
        signals = replay(ssp, tmp / f"record_{case}", tmp / f"replay_{case}", figures=False)["signals"]
        out[case] = {
            "q_m": signals["q_m"]["relative_error_pct"],
            "force": signals["force"]["relative_error_pct"],
            "force_fit": signals["force"]["fit_pct"],
        }
    return out


def source_emps_pulses() -> dict:
    """`mast diagnose` of the EMPS record on the bench (built into a temporary folder), then its diagnosed bench on
    the synthetic pulse record: emps_pulses_values (tests/test_emps.py checks them on the diagnosis it runs); about
    a minute and a half."""
    from mast.core.build import FMUS, SSP_SRC, build_fmu, build_ssp
    from mast.data.importer import import_file
    from mast.diagnosis import Options, diagnose

    with tempfile.TemporaryDirectory(prefix="mast_figures_") as tmp:
        tmp = Path(tmp)
        for spec in FMUS:
            if spec.model_identifier in ("MastLoadAxis", "MastEmpsController"):
                build_fmu(spec, tmp / "fmus")
        bench = build_ssp(SSP_SRC / "EMPS_bench.ssd", tmp / "fmus", tmp / "ssp")
        import_file(EMPS_RECORD, ROOT / "examples" / "emps" / "map.toml", tmp / "record")
        diagnose(Options(tmp / "record", tmp / "out", str(bench), figures=False), log=lambda *_: None)
        (tmp / "pulses").mkdir()
        return emps_pulses_values(tmp / "out" / "EMPS_bench_diagnosed.ssp", bench, tmp / "pulses")


SOURCES: dict[str, Callable[[], dict]] = {
    "reproduce": source_reproduce,
    "ssd": source_ssd,
    "designs": source_designs,
    "ratings": source_ratings,
    "inertias": source_inertias,
    "defaults": source_defaults,
    "sizing": source_sizing,
    "build": source_build,
    "emps": source_emps,
    "emps_diagnose": source_emps_diagnose,
    "workspace": source_workspace,
    "workspace_quick": lambda: source_workspace(quick=True),
    "hexapod": source_hexapod,
    "hexapod_pus": source_hexapod_pus,
    "rps": source_rps,
    "hexapod_run": source_hexapod_run,
    "diagnose_hexapod": source_diagnose_hexapod,
    "animate": source_animate,
    "controllers_short": source_controllers_short,
    "designs_short": source_designs_short,
    **{
        f"diagnose_{case}": functools.partial(source_diagnose, case)
        for case in (
            *DIAGNOSE_CASES,
            *DIAGNOSE_HEAVIER_LIGHTER,
            *DIAGNOSE_LAGS,
            *DIAGNOSE_BACKLASH,
            *DIAGNOSE_PER_AXIS,
            *DIAGNOSE_ONE_AXIS_AND_DRIVE,
        )
    },
    "diagnose_model": source_diagnose_model,
    "sets": source_sets,
    "actuator": source_actuator,
    "geometry": source_geometry,
    "examples": source_examples,
    # docs/mechanism.md, docs/workspace.md, docs/designs/*.md, docs/native.md (auditB)
    "design_pages": source_design_pages,
    "workspace_payload": source_workspace_payload,
    "native": source_native,
    "emps_pulses": source_emps_pulses,
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


def written_as(match: re.Match, figure: Figure, computed: float) -> str:
    """``computed`` as the marker ``match`` writes it: with its own format specification if it has one (module
    docstring), else with the figure's."""
    return ("{:" + match["spec"] + "}").format(computed) if match["spec"] else figure.fmt.format(computed)


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
                prefix = key.split(".", 1)[0]
                alike = sorted(k for k in FIGURES if k.split(".", 1)[0] == prefix)
                problems.append(
                    f"{where}:{line}: figure {key!r} is not in docs/figures.py FIGURES ("
                    + (f"known of {prefix}: {', '.join(alike)}" if alike else f"known sources: {', '.join(SOURCES)}")
                    + ")"
                )
                continue
            if figure.source not in values:
                continue
            computed = figure.pick(values[figure.source])
            written = written_as(match, figure, computed)
            if written != stated and not abs(_number(stated) - computed) <= figure.tolerance:
                problems.append(
                    f"{where}:{line}: the page states {key} = {stated}, the code gives "
                    f"{written} (tolerance {figure.tolerance:g}): run `{REGENERATE} "
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
            new = written_as(match, figure, figure.pick(values[figure.source]))
            if new != match["value"]:
                line = text.count("\n", 0, match.start()) + 1
                where = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
                changes.append(f"{where}:{line} {match['key']}: {match['value']} -> {new}")
            spec = f":{match['spec']}" if match["spec"] else ""
            return f"<!-- figure {match['key']}{spec} -->{new}<!-- /figure -->"

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
