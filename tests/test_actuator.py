"""Actuator model (fmus/actuator/model.py) against independent routes.

Every reference here is built in this file from the paper's equations (Eqs. 1-3, 20-23)
or from textbook solutions: python-control transfer functions, scipy solve_ivp on an
ODE written out by hand, closed-form DC-motor responses, energy bookkeeping. None of
them reuses the model's matrices or kernels.
"""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
from conftest import load_params
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from fmus.actuator.model import (
    ActuatorBlock,
    chain_frequencies,
    natural_frequencies,
    transfer_functions,
    transmission_ratio,
    two_inertia,
)
from fmus.common.block import ModelError
from fmus.common.parameters import ParameterError

H = 1e-4  # the actuator's step in the co-simulation (10 kHz)


# -- helpers: the paper's quantities, computed here from the raw parameter values -----------
def paper_inertias(p: dict) -> tuple[float, float, float]:
    """(J1, J2, i_R) straight from Eqs. 1, 20 (+ brake), 21, 22."""
    i_R = p["p"] / (2 * math.pi * p["i_r"])
    J1 = p["J1_scale"] * (p["J_motor"] + p["J_gearbox"] + p["J_coupling"] + p["J_brake"])
    J2 = p["J_guide"] / p["i_r"] ** 2 + p["M_load"] * i_R**2
    return J1, J2, i_R


def run(block: ActuatorBlock, u, F, h: float = H, n: int | None = None) -> dict[str, np.ndarray]:
    """Step ``block`` with per-step inputs (arrays or constants); outputs at t = 0, h, 2h, ..."""
    n = n if n is not None else len(u if np.ndim(u) else F)
    u = np.broadcast_to(np.asarray(u, dtype=float), (n,))
    F = np.broadcast_to(np.asarray(F, dtype=float), (n,))
    block.set(u=u[0], F=F[0])
    block.initialize(0.0)
    rows = [list(block.values[len(block.INPUTS) :])]
    values = block.values
    for k in range(n):
        values[0] = u[k]
        values[1] = F[k]
        block.do_step(k * h, h)
        rows.append(list(values[len(block.INPUTS) :]))
    data = np.array(rows)
    out = {name: data[:, j] for j, name in enumerate(block.OUTPUTS)}
    out["t"] = np.arange(n + 1) * h
    return out


def linear_params(p: dict, **over) -> dict:
    """No friction, no gravity, back-EMF bypassed (k_E -> 0): the pure Eq. 2-3 mechanics."""
    q = dict(p, tau_c=0.0, g_guide=0.0, b_v=0.0, k_E=1e-12)
    q.update(over)
    return q


def zoh_response(num, den, inputs: np.ndarray, h: float) -> np.ndarray:
    """python-control: continuous TF, exact ZOH sampling, response at t = 0, h, ... (len n+1)."""
    sysd = control.sample_system(control.tf(num, den), h, method="zoh")
    u = np.append(inputs, 0.0)
    return control.forced_response(sysd, np.arange(len(u)) * h, u).outputs


# -- Eqs. 1, 20-22 and the transfer functions --------------------------------------------------
def test_paper_relations(actuator_params):
    p = actuator_params
    J1, J2, i_R = paper_inertias(p)
    assert transmission_ratio(p["p"], p["i_r"]) == pytest.approx(i_R, rel=1e-15)
    assert i_R == pytest.approx(0.07 / (2 * math.pi * 91 / 6), rel=1e-12)
    assert two_inertia(p) == pytest.approx((J1, J2), rel=1e-15)
    assert J1 == pytest.approx(2.128e-5, rel=1e-12)  # 14.2 + 1.4 + 4.68 + 1.0 (brake) x 1e-6
    tfs = transfer_functions(p)
    k, c = p["K_t"], p["C_t"]
    den = [J1 * J2, (J1 + J2) * c, (J1 + J2) * k, 0, 0]  # Eq. 2 typed out
    expected = {
        "TF1": ([J2, c, k], den),
        "TF2": ([c, k], [J2, c, k]),
        "TF1d": ([J1, c, k], den),
        "TF2d": ([c, k], [J1, c, k]),
    }
    for name, (num, dn) in expected.items():
        np.testing.assert_allclose(tfs[name][0], num, rtol=1e-14, err_msg=name)
        np.testing.assert_allclose(tfs[name][1], dn, rtol=1e-14, err_msg=name)


def test_tf2_resonance_is_at_sqrt_Kt_over_J2(actuator_params):
    """|TF2(j w)| peaks at sqrt(K_t/J2): 733 Hz with Eq. 21 and p = 70 mm, not Table 1's 986.5 Hz."""
    p = actuator_params
    J1, J2, _ = paper_inertias(p)
    tfs = transfer_functions(p)
    f_expected = math.sqrt(p["K_t"] / J2) / (2 * math.pi)
    f = np.linspace(500.0, 1100.0, 120_001)  # 5 mHz grid
    mag = control.frequency_response(control.tf(*tfs["TF2"]), 2 * np.pi * f).magnitude
    f_peak = f[np.argmax(mag)]
    assert f_peak == pytest.approx(f_expected, abs=0.01)
    assert f_peak == pytest.approx(733.0, abs=0.5)
    assert abs(f_peak - 986.5) > 200  # Table 1's f_n is not what Eqs. 20-22 give (see docs)
    # TF1's resonance (its poles) is the free-free mode; its antiresonance is TF2's peak
    f_tf1 = np.abs(control.poles(control.tf(*tfs["TF1"]))).max() / (2 * math.pi)
    assert f_tf1 == pytest.approx(math.sqrt(p["K_t"] * (J1 + J2) / (J1 * J2)) / (2 * math.pi), rel=1e-6)
    nf = natural_frequencies(p)
    assert nf["TF1"] == pytest.approx(f_tf1, rel=1e-6)
    assert nf["TF2"] == pytest.approx(f_expected, rel=1e-12)
    assert nf["TF2d"] == pytest.approx(math.sqrt(p["K_t"] / J1) / (2 * math.pi), rel=1e-12)
    assert chain_frequencies([J1, J2], [p["K_t"]])[0] == pytest.approx(f_tf1, rel=1e-9)


# -- time domain vs python-control (Eqs. 2-3) --------------------------------------------------
@pytest.mark.parametrize("C_t", [3e-8, 2e-3])
def test_disturbance_path_matches_TF1d_TF2d(actuator_params, C_t):
    """Force on the carriage only: theta_rho = TF1d tau_d, theta_m = TF2d TF1d tau_d, tau_d = -i_R F."""
    p = linear_params(actuator_params, C_t=C_t)
    J1, J2, i_R = paper_inertias(p)
    tfs = transfer_functions(p)
    rng = np.random.default_rng(1)
    F = rng.normal(0.0, 20.0, 400)
    out = run(ActuatorBlock(p), 0.0, F)
    tau_d = -i_R * F
    theta_rho = zoh_response(*tfs["TF1d"], tau_d, H)
    num = np.polymul(tfs["TF1d"][0], tfs["TF2d"][0])
    den = np.polymul(tfs["TF1d"][1], tfs["TF2d"][1])
    theta_m = zoh_response(num, den, tau_d, H)
    scale = np.abs(theta_rho).max()
    np.testing.assert_allclose((out["rho"] - p["rho_0"]) / i_R, theta_rho, atol=1e-7 * scale)
    np.testing.assert_allclose(out["theta_m"], theta_m, atol=1e-7 * scale)
    assert np.abs(out["i_m"]).max() < 1e-6  # back-EMF bypassed: no current


@pytest.mark.parametrize("n_dof", [1, 2])
def test_voltage_path_matches_TF1_TF2(actuator_params, n_dof):
    """u -> k_T/(L s + R) -> TF1 -> TF2 (back-EMF bypassed); 1-DOF: 1/((J1 + J2) s^2)."""
    p = linear_params(actuator_params, n_dof=n_dof, C_t=1e-3)
    J1, J2, i_R = paper_inertias(p)
    tfs = transfer_functions(p)
    el = ([p["k_T"]], [p["L"], p["R"]])
    rng = np.random.default_rng(2)
    u = rng.uniform(-3.0, 3.0, 400)
    out = run(ActuatorBlock(p), u, 0.0)
    if n_dof == 2:
        tf1 = tfs["TF1"]
        tf12 = (np.polymul(tf1[0], tfs["TF2"][0]), np.polymul(tf1[1], tfs["TF2"][1]))
    else:
        tf1 = tf12 = ([1.0], [J1 + J2, 0.0, 0.0])
    theta_m = zoh_response(np.polymul(el[0], tf1[0]), np.polymul(el[1], tf1[1]), u, H)
    theta_rho = zoh_response(np.polymul(el[0], tf12[0]), np.polymul(el[1], tf12[1]), u, H)
    current = zoh_response([1.0], el[1], u, H)
    scale = np.abs(theta_m).max()
    np.testing.assert_allclose(out["theta_m"], theta_m, atol=1e-7 * scale)
    np.testing.assert_allclose((out["rho"] - p["rho_0"]) / i_R, theta_rho, atol=1e-7 * scale)
    np.testing.assert_allclose(out["i_m"], current, atol=1e-9 * np.abs(current).max())
    np.testing.assert_allclose(out["tau_m"], p["k_T"] * out["i_m"], rtol=1e-15)


def test_back_emf_closes_the_loop(actuator_params):
    """With k_E: theta_m/u = G / (1 + G k_E s), G = k_T/(L s + R) TF1 (python-control feedback)."""
    p = dict(actuator_params, tau_c=0.0, g_guide=0.0, b_v=0.0, C_t=1e-3)
    tfs = transfer_functions(p)
    G = control.tf([p["k_T"]], [p["L"], p["R"]]) * control.tf(*tfs["TF1"])
    T = control.minreal(control.feedback(G * control.tf([1, 0], [1]), p["k_E"]), verbose=False)
    T = T * control.tf([1], [1, 0])  # back to position: theta_m = (s theta_m) / s
    rng = np.random.default_rng(3)
    u = rng.uniform(-3.0, 3.0, 600)
    out = run(ActuatorBlock(p), u, 0.0)
    ref = zoh_response(T.num[0][0], T.den[0][0], u, H)
    np.testing.assert_allclose(out["theta_m"], ref, atol=1e-6 * np.abs(ref).max())


def test_rho_ddot_is_the_derivative_of_rho_dot(actuator_params):
    p = load_params("actuator_identified")
    h = 1e-5
    t = np.arange(20000) * h
    u = 3.0 * np.sin(2 * np.pi * 15 * t) + 0.5
    F = 10.0 * np.sin(2 * np.pi * 40 * t)
    out = run(ActuatorBlock(p), u, F, h=h)
    fd = (out["rho_dot"][2:] - out["rho_dot"][:-2]) / (2 * h)
    acc = out["rho_ddot"][1:-1]
    moving = np.abs(out["rho_dot"][1:-1]) > 10 * p["omega_c"] * paper_inertias(p)[2]
    assert moving.mean() > 0.5
    err = np.abs(fd - acc)[moving]
    assert np.percentile(err, 99) < 0.02 * np.abs(acc).max()


# -- DC motor, analytic -------------------------------------------------------------------------
@pytest.mark.parametrize("n_dof", [1, 2])
def test_steady_speed_under_constant_voltage(actuator_params, n_dof):
    """omega = u / (k_E + R b / k_T) with viscous b only."""
    b = 2e-4
    p = dict(actuator_params, n_dof=n_dof, tau_c=0.0, g_guide=0.0, b_v=b, C_t=1e-3)
    u = 1.0
    out = run(ActuatorBlock(p), u, 0.0, n=5000)  # 0.5 s >> R (J1 + J2) / (k_T k_E + R b) ~ 7.5 ms
    omega = u / (p["k_E"] + p["R"] * b / p["k_T"])
    assert out["omega_m"][-1] == pytest.approx(omega, rel=1e-9)
    _, _, i_R = paper_inertias(p)
    assert out["rho_dot"][-1] == pytest.approx(i_R * omega, rel=1e-9)
    assert out["i_m"][-1] == pytest.approx(b * omega / p["k_T"], rel=1e-7)


def test_current_step_response_closed_form(actuator_params):
    """Rigid axis, no friction: i(t) = (u/L) (e^{s1 t} - e^{s2 t}) / (s1 - s2),
    s1,2 roots of L J s^2 + R J s + k_T k_E."""
    p = dict(actuator_params, n_dof=1, tau_c=0.0, g_guide=0.0, b_v=0.0)
    J1, J2, _ = paper_inertias(p)
    J = J1 + J2
    u = 2.0
    out = run(ActuatorBlock(p), u, 0.0, n=300)
    s1, s2 = np.roots([p["L"] * J, p["R"] * J, p["k_T"] * p["k_E"]])
    assert np.isreal(s1) and np.isreal(s2)
    t = out["t"]
    i_exact = (u / p["L"]) * (np.exp(s1 * t) - np.exp(s2 * t)) / (s1 - s2)
    np.testing.assert_allclose(out["i_m"], i_exact.real, atol=1e-9 * np.abs(i_exact).max())
    assert out["i_m"].max() == pytest.approx(np.abs(i_exact).max(), rel=1e-6)


def test_voltage_is_clipped_to_the_supply(actuator_params):
    p = dict(actuator_params, tau_c=0.0, g_guide=0.0)
    a = run(ActuatorBlock(p), 100.0, 0.0, n=50)
    b = run(ActuatorBlock(p), p["u_supply"], 0.0, n=50)
    np.testing.assert_array_equal(a["i_m"], b["i_m"])


# -- energy ---------------------------------------------------------------------------------------
def test_energy_balance(actuator_params):
    """Integral of u i = R i^2 + L i^2/2 + kinetic + spring + damper + friction losses + work on F + M g rho.

    k_E = k_T here: with the catalogue constants (k_T = 30.2 mNm/A, k_E = 30.12 mV s/rad)
    the motor itself creates or destroys (k_T - k_E) i omega of power.
    """
    p = dict(load_params("actuator_identified"), k_E=actuator_params["k_T"], C_t=5e-4, b_v=1e-4)
    J1, J2, i_R = paper_inertias(p)
    h = 2e-5
    t = np.arange(25000) * h  # 0.5 s, several reversals and standstills
    u = 2.5 * np.sin(2 * np.pi * 3 * t) + 0.8 * np.sin(2 * np.pi * 37 * t)
    F = 15.0 * np.sin(2 * np.pi * 5 * t)
    out = run(ActuatorBlock(p), u, F, h=h)
    i, w1 = out["i_m"], out["omega_m"]
    th2 = (out["rho"] - p["rho_0"]) / i_R
    w2 = out["rho_dot"] / i_R
    dth = out["theta_m"] - th2

    def integral(y_left, y_right):  # trapezoid of a product over each step
        return np.sum(0.5 * (y_left + y_right)) * h

    u_held = u  # ZOH: constant over the step
    e_in = np.sum(u_held * 0.5 * (i[:-1] + i[1:])) * h
    f_held = F
    e_force = np.sum(f_held * 0.5 * (out["rho_dot"][:-1] + out["rho_dot"][1:])) * h
    loss = p["R"] * i**2 + p["C_t"] * (w1 - w2) ** 2 + p["b_v"] * w2**2 + p["tau_c"] * np.tanh(w2 / p["omega_c"]) * w2
    e_loss = integral(loss[:-1], loss[1:])
    stored = (
        0.5 * p["L"] * i**2
        + 0.5 * J1 * w1**2
        + 0.5 * J2 * w2**2
        + 0.5 * p["K_t"] * dth**2
        + p["M_load"] * p["g_guide"] * out["rho"]
    )
    residual = e_in - e_loss - e_force - (stored[-1] - stored[0])
    assert e_in > 0.5 and e_loss > 0.5  # a real exchange took place (joules)
    assert np.count_nonzero(np.diff(np.sign(w2[np.abs(w2) > 1.0]))) >= 2  # reversals happened
    assert abs(residual) < 1e-4 * e_in  # measured 4.5e-6 (2.5 mJ quadrature of 2.5 J)


# -- friction ----------------------------------------------------------------------------------------
def test_breakaway_torque(actuator_params):
    """A slow voltage ramp: the carriage starts to slide when k_T i reaches tau_c + i_R M g (up)
    or i_R M g - tau_c (down)."""
    p = load_params("actuator_identified")
    _, _, i_R = paper_inertias(p)
    weight = i_R * p["M_load"] * p["g_guide"]
    slide = 3 * p["omega_c"] * i_R  # tanh(3) = 0.995 of tau_c
    for sign, expected in ((1, p["tau_c"] + weight), (-1, weight - p["tau_c"])):
        n = 10000
        u = sign * np.linspace(0.0, 1.0, n)  # 1 V/s: quasi-static
        out = run(ActuatorBlock(p), u, 0.0)
        k = np.argmax(sign * out["rho_dot"] > slide)
        assert k > 0
        assert out["tau_m"][k] == pytest.approx(expected, rel=0.02)
        # before breakaway the carriage only creeps, at the speed the tanh law gives for the
        # torque then applied (quasi-static: inertia negligible on this ramp)
        j = k // 2
        net = out["tau_m"][j] - weight
        creep = brentq(lambda w, net=net: p["tau_c"] * math.tanh(w / p["omega_c"]) + p["b_v"] * w - net, -50, 50)
        assert abs(creep) < p["omega_c"]
        assert out["rho_dot"][j] == pytest.approx(i_R * creep, rel=0.01)


def test_square_torque_at_low_frequency(actuator_params):
    """Slow sine motion: motor torque ~ i_R M g + tau_c sign(rho_dot), a square wave (paper Fig. 11, 0.4 Hz)."""
    p = load_params("actuator_identified")
    _, _, i_R = paper_inertias(p)
    weight = i_R * p["M_load"] * p["g_guide"]
    t = np.arange(30000) * H  # 3 s
    u = 2.0 * np.sin(2 * np.pi * 0.4 * t)
    out = run(ActuatorBlock(p), u, 0.0)
    v = out["rho_dot"]
    sliding = np.abs(v) > 5 * p["omega_c"] * i_R
    assert sliding.mean() > 0.6
    up = sliding & (v > 0)
    down = sliding & (v < 0)
    assert up.any() and down.any()
    np.testing.assert_allclose(out["tau_m"][up], weight + p["tau_c"], atol=0.05 * p["tau_c"])
    np.testing.assert_allclose(out["tau_m"][down], weight - p["tau_c"], atol=0.05 * p["tau_c"])


@pytest.mark.parametrize("setname", ["actuator", "actuator_identified"])
def test_standstill_below_friction(actuator_params, setname):
    """|gravity + F| < tau_c, no voltage: no chatter, and the only motion is the tanh law's creep,
    omega from i_R (M g + F) = tau_c tanh(omega/omega_c) + (k_T k_E / R + b_v) omega."""
    p = load_params(setname)
    _, _, i_R = paper_inertias(p)
    F = -0.3 * (p["M_load"] * p["g_guide"])  # helps gravity a little: load torque below friction
    load = i_R * (p["M_load"] * p["g_guide"] + F)
    assert 0 < load < p["tau_c"]
    out = run(ActuatorBlock(p), 0.0, F, n=10000)  # 1 s
    c_emf = p["k_T"] * p["k_E"] / p["R"] + p["b_v"]
    omega = -brentq(lambda w: p["tau_c"] * math.tanh(w / p["omega_c"]) + c_emf * w - load, 0, 100)
    v = out["rho_dot"][2000:]
    assert np.all(np.sign(v) == -1)  # no chatter: one direction only
    np.testing.assert_allclose(v, i_R * omega, rtol=1e-3)
    assert np.abs(np.diff(v)).max() < 1e-6 * np.abs(v).max()
    # creep speed is the regularisation's: with omega_c 100 x smaller the carriage stays put
    creep = p["rho_0"] - out["rho"][-1]
    q = dict(p, omega_c=p["omega_c"] / 100)
    out = run(ActuatorBlock(q), 0.0, F, n=10000)
    assert 0 <= p["rho_0"] - out["rho"][-1] < 0.02 * creep
    assert np.all(out["rho_dot"][2000:] <= 0)


def test_no_chatter_at_reversals_with_stiff_friction(actuator_params):
    """omega_c 1000 x smaller than the default (friction 45 million 1/s stiff at the guide): still smooth."""
    p = dict(load_params("actuator_identified"), omega_c=5e-4)
    t = np.arange(20000) * H
    out = run(ActuatorBlock(p), 1.5 * np.sin(2 * np.pi * 2 * t), 0.0)
    assert np.all(np.isfinite(out["rho_ddot"]))
    v = out["rho_dot"]
    flips = np.count_nonzero(np.diff(np.sign(v[np.abs(v) > 1e-7])))
    assert flips <= 10  # 2 Hz over 2 s: ~8 reversals, no step-to-step sign alternation


# -- convergence -------------------------------------------------------------------------------
CHUNK = 0.015
SCENARIO = [(2.0, 0.0), (-2.0, 5.0), (0.3, -5.0), (-1.0, 10.0)]  # (u [V], F [N]) held 15 ms each


def reference_solution(p: dict, samples: int) -> np.ndarray:
    """solve_ivp (Radau, rtol 1e-11) on the two-inertia ODE written out here."""
    J1, J2, i_R = paper_inertias(p)
    R, L, kT, kE, K, C, tc, wc = (p[k] for k in ("R", "L", "k_T", "k_E", "K_t", "C_t", "tau_c", "omega_c"))
    W = i_R * p["M_load"] * p["g_guide"]

    def rhs(_t, x, u, F):
        i, t1, t2, w1, w2 = x
        spring = K * (t1 - t2) + C * (w1 - w2)
        return [
            (u - R * i - kE * w1) / L,
            w1,
            w2,
            (kT * i - spring) / J1,
            (spring - i_R * F - W - tc * math.tanh(w2 / wc) - p["b_v"] * w2) / J2,
        ]

    def jac(_t, x, u, F):
        d = tc / wc / math.cosh(x[4] / wc) ** 2 + p["b_v"]
        return [
            [-R / L, 0, 0, -kE / L, 0],
            [0, 0, 0, 1, 0],
            [0, 0, 0, 0, 1],
            [kT / J1, -K / J1, K / J1, -C / J1, C / J1],
            [0, K / J2, -K / J2, C / J2, (-C - d) / J2],
        ]

    x = np.zeros(5)
    rows = [x]
    for u, F in SCENARIO:
        sol = solve_ivp(
            rhs,
            (0, CHUNK),
            x,
            method="Radau",
            rtol=1e-11,
            atol=[1e-12, 1e-12, 1e-12, 1e-9, 1e-9],
            jac=jac,
            args=(u, F),
            t_eval=np.linspace(0, CHUNK, samples + 1)[1:],
        )
        assert sol.success
        rows += list(sol.y.T)
        x = sol.y[:, -1]
    return np.array(rows)


def model_at_samples(p: dict, h: float, samples: int) -> np.ndarray:
    block = ActuatorBlock(p)
    block.initialize(0.0)
    per = round(CHUNK / h)
    every = per // samples
    rows = [list(block.state().values())]
    t = 0.0
    for u, F in SCENARIO:
        block.set(u=u, F=F)
        for k in range(per):
            block.do_step(t, h)
            t += h
            if (k + 1) % every == 0:
                rows.append(list(block.state().values()))
    return np.array(rows)


def test_convergence_against_solve_ivp():
    """Identified set (tau_c = 0.0718 N m) through reversals and a near-standstill phase.

    Measured (max over 61 samples), h = 100 us: rho 0.34 um, omega_m 0.21 rad/s, omega_N 0.35 rad/s,
    i 0.016 A, for ranges 0.51 mm, 80 rad/s, 15 A; h = 25 us: 0.06 um, 0.038 rad/s, 0.065 rad/s,
    0.003 A: about first order in h (the friction is implicit Euler).
    """
    p = load_params("actuator_identified")
    _, _, i_R = paper_inertias(p)
    samples = 15
    ref = reference_solution(p, samples)
    errors = {}
    for h in (1e-4, 2.5e-5):
        x = model_at_samples(p, h, samples)
        e = np.abs(x - ref).max(axis=0)
        errors[h] = {"i": e[0], "rho": e[2] * i_R, "omega_m": e[3], "omega_N": e[4]}
    e = errors[1e-4]
    assert np.ptp(ref[:, 3]) > 50 and np.count_nonzero(np.diff(np.sign(ref[:, 4]))) >= 2
    assert e["rho"] < 1e-6  # m
    assert e["omega_m"] < 0.3  # rad/s, of a 146 rad/s range
    assert e["omega_N"] < 0.8  # rad/s
    assert e["i"] < 0.03  # A, of a 21 A range
    for key in e:
        assert errors[2.5e-5][key] < 0.6 * e[key], key  # decreases with h (about first order)


def test_linear_part_is_exact_at_any_step(actuator_params):
    """Without friction the discretisation is exact: h = 100 us, 1 ms (with substeps) and
    solve_ivp agree to the reference's own accuracy."""
    p = dict(actuator_params, tau_c=0.0)
    J1, J2, i_R = paper_inertias(p)
    ref = reference_solution(dict(p, omega_c=1.0), 15)
    for h in (1e-4, 1e-3):
        x = model_at_samples(p, h, 15)
        scale = np.abs(ref).max(axis=0)
        assert np.all(np.abs(x - ref).max(axis=0) < 1e-7 * scale + 1e-12)
    block = ActuatorBlock(p)
    block.initialize(0.0)
    block.do_step(0.0, 1e-3)
    assert block.substeps > 1  # 786 Hz mode x 1 ms > 2 rad


# -- 1, 2 and N DOF -------------------------------------------------------------------------------
def test_three_inertias_with_stiff_spring_reproduce_two(actuator_params):
    p = load_params("actuator_identified")
    J1_raw = p["J_motor"] + p["J_gearbox"] + p["J_coupling"] + p["J_brake"]
    _, J2, _ = paper_inertias(p)
    # the guide side split in two halves joined by a spring 1000 x K_t (a 46 kHz mode)
    chain3 = dict(
        p,
        n_dof=3,
        J_chain=f"{J1_raw!r} {J2 / 2!r} {J2 / 2!r}",
        K_chain=f"{p['K_t']!r} {1e3 * p['K_t']!r}",
        C_chain=f"{p['C_t']!r} 0.0",
    )
    f3 = chain_frequencies([J1_raw * p["J1_scale"], J2 / 2, J2 / 2], [p["K_t"], 1e3 * p["K_t"]])
    assert f3[0] == pytest.approx(natural_frequencies(p)["TF1"], rel=2e-3)
    t = np.arange(5000) * H
    u = 2.0 * np.sin(2 * np.pi * 5 * t)
    F = 8.0 * np.sin(2 * np.pi * 3 * t)
    two = run(ActuatorBlock(p), u, F)
    block3 = ActuatorBlock(chain3)
    three = run(block3, u, F)
    assert block3.substeps > 1
    for key, tol in (("rho", 2e-4), ("omega_m", 2e-3), ("i_m", 2e-3)):  # measured 4e-5, 5e-4, 7e-4
        dev = np.abs(three[key] - two[key]).max() / np.ptp(two[key])
        assert dev < tol, (key, dev)
    # and a rigid axis is the 2-DOF without its resonance: close at 5 Hz
    one = run(ActuatorBlock(dict(p, n_dof=1)), u, F)
    assert np.abs(one["rho"] - two["rho"]).max() < 0.02 * np.ptp(two["rho"])


# -- outputs at initialisation, errors ----------------------------------------------------------
def test_initialize_outputs(actuator_params):
    p = actuator_params
    J1, J2, i_R = paper_inertias(p)
    block = ActuatorBlock(p)
    block.set(u=5.0, F=12.0)
    block.initialize(0.0)
    out = block.outputs()
    assert out["rho"] == p["rho_0"] and out["rho_dot"] == 0 and out["i_m"] == 0
    # at rest until the first step: the acceleration 0 whatever the force, so that the outputs at
    # initialisation follow from the parameters (no algebraic loop with the mechanism's forces)
    assert out["rho_ddot"] == 0.0
    other = ActuatorBlock(p)
    other.set(u=0.0, F=-40.0)
    other.initialize(0.0)
    assert other.outputs() == out
    # the first step sets it moving: undeflected springs at the start, the guide side alone takes the force
    # and the weight, so the carriage's acceleration starts at -i_R^2 (F + M g) / J2 and the step's end
    # acceleration is of that sign and at most that size (the springs and the motor take part of it)
    block.do_step(0.0, H)
    start = -(i_R**2) * (12.0 + p["M_load"] * p["g_guide"]) / J2
    assert start < block.outputs()["rho_ddot"] < 0.0
    block.initialize(0.0)  # restarts
    assert block.outputs() == out


def test_parameter_errors(actuator_params):
    p = actuator_params
    with pytest.raises(ParameterError, match="unknown parameter.*J_rotor"):
        ActuatorBlock(dict(p, J_rotor=1e-5))
    with pytest.raises(ParameterError, match="M_load.*-2.27.*expected"):
        ActuatorBlock(dict(p, M_load=-2.27))
    with pytest.raises(ParameterError, match="missing.*K_t"):
        ActuatorBlock({k: v for k, v in p.items() if k != "K_t"})
    with pytest.raises(ParameterError, match="rho_0.*0.35.*stroke"):
        ActuatorBlock(dict(p, rho_0=0.35))
    with pytest.raises(ParameterError, match="rho_max"):
        ActuatorBlock(dict(p, rho_min=0.3, rho_max=0.0, rho_0=0.1))
    with pytest.raises(ParameterError, match="omega_c"):
        ActuatorBlock(dict(p, omega_c=0.0))
    with pytest.raises(ParameterError, match="n_dof"):
        ActuatorBlock(dict(p, n_dof=2.5))
    with pytest.raises(ParameterError, match="J_chain.*expected 3"):
        ActuatorBlock(dict(p, n_dof=3))
    with pytest.raises(ParameterError, match="K_chain.*'x'"):
        ActuatorBlock(dict(p, n_dof=3, J_chain="1e-5 1e-6 1e-6", K_chain="60 x", C_chain="0 0"))
    with pytest.raises(ParameterError, match="J_chain.*'-1e-6'"):
        ActuatorBlock(dict(p, n_dof=3, J_chain="1e-5 -1e-6 1e-6", K_chain="60 60", C_chain="0 0"))
    ActuatorBlock(dict(p, n_dof=2, J_chain="ignored", K_chain="", C_chain=""))  # n_dof < 3: not read


def test_runtime_errors(actuator_params):
    block = ActuatorBlock(actuator_params)
    block.initialize(0.0)
    block.set(u=float("nan"))
    with pytest.raises(ModelError, match="input 'u' = nan at t=0.0002"):
        block.do_step(2e-4, H)
    block.set(u=0.0, F=float("inf"))
    with pytest.raises(ModelError, match="input 'F' = inf"):
        block.do_step(0.0, H)
    with pytest.raises(ModelError, match="input 'F'"):
        block.initialize(0.0)
    block.set(F=0.0)
    block._x[3] = math.inf  # a passive model cannot diverge from inputs: corrupt the state
    with pytest.raises(ModelError, match="diverged at t=0.0011"):
        block.do_step(1e-3, H)
    with pytest.raises(ModelError, match="h = 0"):
        ActuatorBlock(actuator_params).do_step(0.0, 0.0)


def test_leaving_the_stroke(actuator_params):
    block = ActuatorBlock(actuator_params)
    block.set(u=24.0, F=0.0)
    block.initialize(0.0)
    with pytest.raises(ModelError, match=r"left the stroke \[0, 0.3\] m: rho = 0.300\d* m at t="):
        for k in range(100000):
            block.do_step(k * H, H)
    block = ActuatorBlock(actuator_params)
    block.set(u=-24.0, F=0.0)
    block.initialize(0.0)
    with pytest.raises(ModelError, match=r"rho = -\d"):
        for k in range(100000):
            block.do_step(k * H, H)


# -- a varying communication step ---------------------------------------------------------------------
@pytest.mark.parametrize(
    "variant",
    [
        "manufacturer",
        "identified (Coulomb friction)",
        "Stribeck",
        "backlash",
        "three inertias",
        "1 ms steps (substeps)",
    ],
)
def test_a_varying_step_compiles_nothing_per_step_and_matches_a_kernel_compiled_per_step(monkeypatch, variant):
    """A host that varies its step: after the first few step sizes each new one is bound to a kernel
    compiled once (no compilation per step); its results equal those of a kernel compiled for
    every step size (the route every step size used to take) to rounding."""
    import fmus.actuator.model as model

    p = load_params("actuator_identified" if variant != "manufacturer" else "actuator")
    p = {
        "Stribeck": dict(p, tau_s=0.02, omega_s=2.0),
        "backlash": dict(p, backlash=2e-4),
        "three inertias": dict(
            p, n_dof=3, J_chain=f"{p['J_motor']!r} 1e-4 1e-4", K_chain="800.0 2000.0", C_chain="0.01 0.0"
        ),
    }.get(variant, p)
    scale = 10.0 if variant.startswith("1 ms") else 1.0
    steps = np.random.default_rng(3).uniform(0.5e-4, 1.5e-4, 30) * scale
    t = np.concatenate([[0.0], np.cumsum(steps)[:-1]])
    u = 12.0 * np.sin(2 * np.pi * 200 / scale * t)
    F = 8.0 * np.sin(2 * np.pi * 130 / scale * t)

    def states(compiled: int) -> tuple[np.ndarray, ActuatorBlock]:
        monkeypatch.setattr(model, "_COMPILED_STEP_SIZES", compiled)
        block = ActuatorBlock(p)
        block.values[:2] = [u[0], F[0]]
        block.initialize(0.0)
        rows = []
        for k, h in enumerate(steps):
            block.values[:2] = [u[k], F[k]]
            block.do_step(t[k], h)
            rows.append(list(block._x) + list(block.values[len(block.INPUTS) :]))
        return np.array(rows), block

    few = model._COMPILED_STEP_SIZES
    bound, block = states(few)
    compiled, _ = states(len(steps))  # a kernel compiled for each step size, constants inlined
    assert block._compiled == few < len(steps) and block._bound is not None
    assert block.substeps > 1 or scale == 1.0
    size = np.abs(compiled).max(axis=0) + 1e-300
    assert np.ptp(compiled[:, 0]) > 0.1  # the current moved
    np.testing.assert_array_less(np.abs(bound - compiled).max(axis=0) / size, 1e-9)


@pytest.mark.parametrize("variant", ["identified (Coulomb friction)", "backlash (contact and gap)"])
def test_the_discretisation_for_any_step_size_equals_scipys_exponential(variant):
    """A varying step's [Phi Gamma] (``_ZohSeries``: reference exponentials and a Taylor series around
    them) against scipy.linalg.expm of [[A B], [0 0]] h at 25 step sizes from 1 us to 2 ms: equal to
    1e-12 of each row's largest entry (the two routes' own rounding is about 1e-13)."""
    from scipy.linalg import expm

    import fmus.actuator.model as model

    p = load_params("actuator_identified")
    block = ActuatorBlock(dict(p, backlash=2e-4) if variant.startswith("backlash") else p)
    n = 2 * block.N + 1
    steps = np.exp(np.random.default_rng(7).uniform(np.log(1e-6), np.log(2e-3), 25))
    for M in block._generators():
        series = model._ZohSeries(M, n)
        for h in steps:
            exact = expm(M * h)[:n]
            error = np.abs(series(h).reshape(n, -1) - exact).max(axis=1) / np.abs(exact).max(axis=1)
            assert error.max() < 1e-12, (h, error)
        assert len(series._references) < 100  # a handful of exponentials per octave, not one per step size
