"""The workspace and the assembly branch, against a route that shares no code with the engine.

The independent route is test_designs.Own (its own rotation matrix, parasitic motion by Newton,
slider positions as the root of a quadratic) with drho/dq by central differences: its
determinant tells the branches apart, its singular values (tilts scaled by r) give the margins.

- the two-branch example of issue 17 (inclined guides): two poses with the same carriage
  positions, determinants of opposite sign; the DK from the level pose finds the positive one,
  and the mechanism block driven towards the other one stops with an error naming the pose
  instead of jumping;
- the singular pose of issue 17 is refused (DK and workspace);
- brute force: random walks along the workspace's edges, each edge sampled finely, never change
  the sign of the determinant nor leave the strokes;
- the T and 120 deg designs' workspaces contain the paper's test motions around home;
- the engine's kinematics on arrays (the workspace's route) give the scalar route's floats.
Grids are coarse here (25 mm, 4 deg): the figures of the docs come from the default grid.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_designs import Own

import fmus.common.tracer as E
from fmus.mechanism.engine import MARGIN, Body, Description, Engine, Evaluation, KinematicsError, SingularityError
from fmus.mechanism.model import MechanismBlock
from mast.analyses import paper
from mast.analyses import workspace as W
from mast.cli import main as cli

DEG = math.pi / 180.0
COARSE = dict(step_z=0.025, step_tilt=4.0 * DEG)  # 0.15 m (half the stroke) is 6 steps
RHO_TWO = (0.14736, 0.16332, 0.04250)  # issue 17
PLUS = (0.2603, 16.02 * DEG, -15.79 * DEG)  # det > 0, found by the DK from the level pose
MINUS = (0.2445, 18.47 * DEG, -18.97 * DEG)  # det < 0, same carriage positions
SINGULAR = (0.252056, 17.30 * DEG, -17.45 * DEG)


def own_jacobian(own: Own, q, h: float = 1e-6) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    cols = [(own.rho(q + h * e) - own.rho(q - h * e)) / (2 * h) for e in np.eye(3)]
    return np.column_stack(cols)


def own_margins(own: Own, q) -> tuple[float, float, float]:
    """(det drho/dq, parallel margin, inverse margin) by the independent route."""
    A = own_jacobian(own, q)
    sv = np.linalg.svd(A / np.array([1.0, own.r, own.r]), compute_uv=False)
    return float(np.linalg.det(A)), float(sv[-1]), float(1.0 / sv[0])


@pytest.fixture(scope="module")
def inclined():
    m = W.machine("3PRS_inclined")
    return m, m.engine(), Own({**m.params, "g": 9.81})


@pytest.fixture(scope="module")
def inclined_ws(inclined):
    return W.compute(inclined[0], **COARSE)


def test_two_branches_with_the_same_carriages(inclined):
    m, eng, own = inclined
    plus = eng.dk(RHO_TWO)[0]  # cold start: the level pose
    minus = eng.dk(RHO_TWO, guess=MINUS)[0]  # a start on the other branch stays there
    np.testing.assert_allclose(plus, PLUS, atol=2e-4)
    np.testing.assert_allclose(minus, MINUS, atol=2e-4)
    for q in (plus, minus):
        np.testing.assert_allclose(own.rho(q), RHO_TWO, atol=1e-10)
        assert all(lo <= r <= hi for r, lo, hi in zip(RHO_TWO, m.rho_min, m.rho_max))
    det_plus, par_plus, _ = own_margins(own, plus)
    det_minus, par_minus, _ = own_margins(own, minus)
    det_home = own_margins(own, eng.dk(m.rho_home)[0])[0]
    assert det_home > 0 and det_plus > 0 > det_minus
    assert det_plus == pytest.approx(0.036, abs=2e-3) and det_minus == pytest.approx(-0.044, abs=2e-3)
    # a condition-number scan cannot tell them apart: both are well conditioned
    assert par_plus > 3 * MARGIN and par_minus > 3 * MARGIN
    # plain Newton from this start on the home branch lands on the negative pose: refused, the pose named
    start = (0.20198, 0.44212, -0.12533)
    assert own_margins(own, start)[0] > 0
    with pytest.raises(
        SingularityError,
        match=r"the solution z = 0\.2445\d* m, psi = .*\(18\.47 deg\).* lies on "
        r"another assembly branch than the start z = 0\.20198 m",
    ):
        eng.dk(RHO_TWO, guess=start)


def test_block_driven_across_the_singularity_stops_instead_of_jumping(inclined):
    """Carriages follow the IK of a straight pose path home -> singular pose -> the negative pose."""
    m, eng, own = inclined
    home = np.array(eng.dk(m.rho_home)[0])
    path = [home + s * (np.array(SINGULAR) - home) for s in np.linspace(0.0, 1.0, 400)]
    path += [np.array(SINGULAR) + s * (np.array(MINUS) - np.array(SINGULAR)) for s in np.linspace(0.0, 1.0, 40)[1:]]
    block = MechanismBlock({**m.params, "attached": 1}, "mechanism")
    block.values[0:9] = [*own.rho(path[0]), 0, 0, 0, 0, 0, 0]
    block.initialize(0.0)
    reached = []
    with pytest.raises(SingularityError, match=r"z = .* m, psi = .* deg\), theta = .* deg\)") as err:
        for k, q in enumerate(path[1:]):
            block.values[0:3] = own.rho(q)
            block.do_step(k * 1e-3, 1e-3)
            out = block.outputs()
            reached.append(np.array([out["z"], out["psi"], out["theta"]]))
    assert "singularity" in str(err.value)
    assert len(reached) > 300  # it went most of the way first
    for q in reached:  # and every pose it gave is on the home branch
        det, par, inv = own_margins(own, q)
        assert det > 0 and min(par, inv) > 0.9 * MARGIN


def test_the_singular_pose_is_refused(inclined, inclined_ws):
    m, eng, own = inclined
    det, par, _ = own_margins(own, SINGULAR)
    assert abs(det) < 1e-3 and par < 1e-3  # singular by the independent route
    with pytest.raises(SingularityError, match=r"z = 0\.252056 m, psi = .*17\.3 deg\), theta = .*-17\.45 deg\)"):
        eng.dk(own.rho(SINGULAR))
    answer = W.classify(inclined_ws, SINGULAR)
    assert not answer["inside"] and answer["reason"] == W.STATUS[W.SINGULAR]
    assert not W.classify(inclined_ws, MINUS)["inside"]
    assert W.classify(inclined_ws, eng.dk(RHO_TWO)[0])["inside"]


def test_no_path_inside_the_workspace_crosses_a_sign_change(inclined, inclined_ws):
    m, eng, own = inclined
    ws = inclined_ws
    rng = np.random.default_rng(17)
    home_det = own_margins(own, ws.home)[0]
    node = lambda i: np.array([ws.axes[d][i[d]] for d in range(3)])  # noqa: E731
    crossed_nodes = 0
    for _ in range(8):  # random walks along kept edges from home
        i = list(ws.home_index)
        for _ in range(20):
            moves = []
            for axis in range(3):
                if i[axis] < ws.status.shape[axis] - 1 and ws.kept[axis][tuple(i)]:
                    moves.append((axis, 1))
                lo = list(i)
                lo[axis] -= 1
                if i[axis] > 0 and ws.kept[axis][tuple(lo)]:
                    moves.append((axis, -1))
            axis, step = moves[rng.integers(len(moves))]
            a = node(i)
            i[axis] += step
            b = node(i)
            for s in np.linspace(0.0, 1.0, 7)[1:]:
                q = a + s * (b - a)
                rho = own.rho(q)
                assert np.all(rho >= np.array(m.rho_min) - 1e-9) and np.all(rho <= np.array(m.rho_max) + 1e-9), q
                assert own_margins(own, q)[0] * home_det > 0, f"sign change inside the workspace at {q}"
            crossed_nodes += 1
    assert crossed_nodes == 160
    # the workspace's nodes on the other branch exist in the box: the walk had somewhere to go wrong
    assert (ws.status == W.BRANCH).any()


@pytest.mark.parametrize("design", ["3PRS_T", "3PRS_120"])
def test_the_paper_motions_lie_inside(design):
    ws = W.compute(W.machine(design), **COARSE)
    s = W.summarize(ws)
    home = np.array(ws.home)
    for axis, name in enumerate(("z", "psi", "theta")):
        amplitude = paper.AMPLITUDE[name]
        for t in np.linspace(0.0, 1.0, 9):
            q = home.copy()
            q[axis] += amplitude * math.sin(2 * math.pi * t)
            assert W.classify(ws, q)["inside"], (design, name, t)
    # the whole stroke in z through home, and the paper's largest tilt (20 deg, section 3.3) around home
    assert s["ranges_through_home"]["z_m"] == pytest.approx([home[0] - 0.15, home[0] + 0.15], abs=1e-9)
    for name in ("psi_deg", "theta_deg"):
        lo, hi = s["ranges_through_home"][name]
        assert lo <= -20.0 and hi >= 20.0, (design, name, lo, hi)
    assert s["smallest_margin"]["value"] >= MARGIN


def test_cli_workspace(tmp_path, capsys):
    out = tmp_path / "ws"
    args = ["workspace", "3PRS_T", "--step-z", "0.025", "--step-tilt", "4", "--no-plots"]
    assert cli(args + ["--out", str(out), "--payload", "2"]) == 0
    s = json.loads((out / "workspace.json").read_text())
    assert s["payload_kg"] == 2 and s["poses_inside"] > 100 and s["volume_m_deg2"] > 0
    # home static forces: the platform (2.06 kg) and 2 kg on legs 1 and 3, leg 2 its own weight (T layout)
    assert s["static_forces"]["home_N"][0] == pytest.approx(10.791 + 9.81, abs=1e-6)
    header = (out / "workspace.csv").read_text().splitlines()[0]
    assert header.startswith("z_m,psi_deg,theta_deg,status,inside")
    assert cli(args + ["--pose", "0.405,5,-3"]) == 0
    assert cli(args + ["--pose", "0.405,0,45"]) == 1
    assert cli(args + ["--pose", "0.405,five,0"]) == 2
    assert "expected Z,PSI_DEG,THETA_DEG" in capsys.readouterr().err


def test_arrays_give_the_scalar_floats(inclined):
    """Engine.evaluate_many (the generated code on arrays, checks as masks) against the scalar route."""
    m, eng, _ = inclined
    rng = np.random.default_rng(3)
    q = [rng.uniform(0.1, 0.6, 300), rng.uniform(-70, 70, 300) * DEG, rng.uniform(-70, 70, 300) * DEG]
    rho, Jinv, ok = eng.evaluate_many(q)
    assert 30 < ok.sum() < 270  # both kinds present
    for k in range(300):
        qk = [v[k] for v in q]
        try:
            Jk = eng.jacobian(qk, check=False)[0]
        except Exception:
            assert not ok[k], qk
            continue
        assert ok[k], qk
        assert tuple(rho[:, k]) == eng.ik(qk) and list(Jinv[k].ravel()) == Jk  # the same floats

    class Plain(Description):  # a check without an array form: point by point
        bodies = (Body("b", 1.0),)

        def evaluate(self, q):
            def reach(w2):
                if not w2 > 0.0:
                    raise KinematicsError("reach lost")

            w2 = 1.0 - q[1] * q[1]
            E.require(reach, w2)
            return Evaluation([q[0], E.sqrt(w2), q[2]], [0.0] * 6, [((q[0], 0.0, 0.0), np.eye(3))])

    rho, _, ok = Engine(Plain()).evaluate_many([np.zeros(3), np.array([0.5, 1.5, -0.2]), np.zeros(3)])
    assert list(ok) == [True, False, True] and rho[1, 0] == math.sqrt(0.75)


def test_a_mechanism_without_body_masses_gets_a_kinematic_workspace():
    """A user's own mechanism (docs/interfaces.md's lumped FMU gives the geometry, not the legs' and platform's
    masses): the workspace and its margins are computed from the geometry, the static forces are said to be
    unknown, not filled with a zero-mass answer or a bare KeyError."""
    from mast.analyses.workspace import BODY_MASSES, compute, machine, summarize
    from mast.core.designs import DESIGNS
    from mast.core.ssp import read_ssd

    full = dict(read_ssd(DESIGNS[0].ssd).components["mechanism"].parameters)
    lumped = {k: v for k, v in full.items() if k not in BODY_MASSES}
    kinematic = summarize(compute(machine("3PRS_T", mechanism=lumped), 0.025, math.radians(4)))
    reference = summarize(compute(machine("3PRS_T"), 0.025, math.radians(4)))
    assert kinematic["volume_m_deg2"] == reference["volume_m_deg2"]  # the same geometry, the same poses
    assert kinematic["smallest_margin"]["value"] == pytest.approx(reference["smallest_margin"]["value"])
    assert "m_leg" in kinematic["static_forces"]["not_computed"] and "home_N" not in kinematic["static_forces"]
    assert "home_N" in reference["static_forces"]
