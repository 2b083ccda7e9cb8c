"""The drive-mechanism exchange's linear stability (mast.analyses.coupling) and the condensed force law
(fmus.mechanism.coupling), against independent routes: the monolithic solve, and the nonlinear co-simulation
of today's exchange, which leaves the stroke where the analysis says it grows."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from conftest import RESOURCES, ROOT, load_params

from fmus.mechanism.coupling import condensation, condensed_forces
from fmus.mechanism.designs import engine
from fmus.mechanism.model import MechanismBlock
from mast.analyses.coupling import BANDWIDTH, Drive, exchange, joint_space_mass
from mast.core.motion import SineMotion
from mast.core.run import simulate
from mast.core.ssp import read_ssd
from mast.core.ssv import read_values

SSP = ROOT / "ssp"


def mechanism(ssd: str) -> dict:
    """The mechanism parameters a system binds (those its block takes)."""
    values = dict(read_ssd(SSP / ssd).components["mechanism"].parameters)
    names = {p.name for p in MechanismBlock.for_parameters(values).PARAMETERS}
    return {k: v for k, v in values.items() if k in names}


def belt() -> dict:
    """The paper's belt axis (actuator_1 of the MAST)."""
    return load_params("actuator")


def belt_leg() -> dict:
    """The paper's belt axis as a hexapod leg: the leg's moving part is the mechanism's (docs/designs/6ups.md)."""
    return {**belt(), "M_load": 0.0, "g_guide": 0.0}


def screw() -> dict:
    """The hexapod's screw leg (MAST_6UPS.ssd's actuator sets), rigid as shipped."""
    merged = {**belt()}
    for name in ("actuator_6ups.ssv", "transmission_screw.ssv", "actuator_screw.ssv"):
        merged.update(read_values(RESOURCES / name))
    return {k: v for k, v in merged.items() if k in belt()}


def test_the_condensed_force_law_is_the_monolithic_solution_while_the_drive_forces_hold():
    rng = np.random.default_rng(3)
    for n in (1, 3, 6):
        G = rng.normal(size=(n, n))
        M = G @ G.T * rng.uniform(0.1, 100.0) + np.outer(np.ones(n), np.ones(n)) * rng.uniform(0.0, 50.0)
        m = rng.uniform(0.5, 10.0, n)
        T, b = rng.normal(size=n) * 100.0, rng.normal(size=n) * 20.0
        W, D = condensation(M, m)
        c = condensed_forces(b, T, W)
        a = (T - c) / (m + D)  # each drive alone: m_k a_k = T_k - (c_k + D_k a_k)
        monolithic = np.linalg.solve(M + np.diag(m), T - b)
        assert np.allclose(a, monolithic, rtol=1e-10, atol=1e-12 * np.abs(monolithic).max())
        assert np.all(D >= -1e-12 * np.abs(M).max()) and np.all(np.diag(W) == 0.0)


def test_the_condensation_refuses_what_it_cannot_condense():
    with pytest.raises(ValueError, match=r"expected \(2, 2\) for 2 drives"):
        condensation(np.eye(3), np.ones(2))
    with pytest.raises(ValueError, match="expected every one > 0 kg"):
        condensation(np.eye(2), np.array([1.0, 0.0]))


def test_the_analysis_puts_the_explicit_exchange_s_limit_where_it_was_met_and_the_condensed_one_runs_past_it(built):
    """The MAST with a specimen at the platform centre: the explicit exchange (F = M rho_ddot + b one exchange late,
    the FMUs' before the condensed one) holds 8 kg and grows with 9 kg by the linear analysis, where its co-simulation
    ran 8 kg and left the stroke with 9 kg (docs/coupling.md); the condensed exchange of the FMUs runs 9 and 50 kg."""
    P = mechanism("MAST.ssd")
    radius = {
        kg: exchange(joint_space_mass({**P, "m_payload": kg}), [belt()] * 3, "acceleration").radius for kg in (8, 9)
    }
    assert radius[8] < 1.0 < radius[9]
    ssp = built / "ssp" / "MAST.ssp"
    motion = SineMotion("z", amplitude=0.005, frequency=2.0)
    for kg in (9.0, 50.0):
        result = simulate(ssp, motion, 0.3, {"mechanism": {"m_payload": kg}}, direct=True)
        assert result.error is None and np.abs(result["z_cmd"] - result["mechanism.z"]).max() < 0.005


@pytest.mark.parametrize("drive", [belt, screw, belt_leg], ids=["belt", "screw", "belt_leg"])
@pytest.mark.parametrize("n_dof", [1, 2])
def test_one_drive_on_a_rigid_mass_is_stable_at_every_mass_ratio_where_todays_exchange_grows_above_one(drive, n_dof):
    params = {**drive(), "n_dof": n_dof}
    m = Drive.of(params).m
    for ratio in np.logspace(-2, 3, 11):
        M = np.array([[ratio * m]])
        assert exchange(M, [params], "extrapolated").radius < 1.0, ratio
        if ratio >= 2.0:
            assert exchange(M, [params], "acceleration").radius > 1.0, ratio


def _poses(P: dict, stroke: tuple[float, float], count: int, seed: int) -> list[list[float]]:
    """``count`` poses inside the workspace of a mechanism parameter set: the strokes, and 0.05 m/m from a
    singularity (the engine's own margin), drawn around home."""
    eng = engine(P)
    top = eng.description.topology
    spans = {"x": 0.1, "y": 0.1, "z": 0.1, "psi": 0.35, "theta": 0.35, "phi": 0.5}
    rng = np.random.default_rng(seed)
    found = [list(top.home)]
    while len(found) < count:
        q = [h + rng.uniform(-1.0, 1.0) * spans[name] for h, name in zip(top.home, top.names)]
        rho = eng.description.evaluate(q).rho
        if not all(stroke[0] < r < stroke[1] for r in rho):
            continue
        try:
            margins = eng.margins(q)
        except Exception:  # noqa: BLE001 - a pose the kinematics refuses is outside the workspace
            continue
        if min(margins.parallel, margins.inverse) > 0.05:
            found.append(q)
    return found


@pytest.mark.parametrize(
    "ssd, drive, stroke, kgs",
    [
        ("MAST.ssd", belt, (0.0, 0.3), (0.0, 5.0, 20.0, 50.0, 500.0)),
        ("MAST_6UPS.ssd", belt_leg, (0.45, 0.75), (0.0, 20.0, 50.0)),
    ],
    ids=["mast", "belt_hexapod"],
)
def test_specimens_anywhere_in_the_workspace_are_stable_extrapolated_and_grow_otherwise(ssd, drive, stroke, kgs):
    P = mechanism(ssd)
    drives = [drive()] * len(engine(P).description.topology.joints)
    for kg, q in itertools.product(kgs, _poses(P, stroke, 4, seed=int(kgs[-1]))):
        M = joint_space_mass({**P, "m_payload": kg, "payload_z": 0.1, "I_payload_xx": 0.01 * kg}, q)
        assert exchange(M, drives, "extrapolated").radius < 1.0, (kg, q)
        # condensed without the extrapolation: the belt's mode (far above the loop) is fed by the other drives'
        # delayed spring forces
        grown = exchange(M, drives, "condensed")
        assert grown.radius > 1.0 and grown.frequency > 10.0 * BANDWIDTH, (kg, q)
