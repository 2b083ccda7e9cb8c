"""The actuator's side of the condensed coupling (fmus/actuator/model.py, docs/coupling.md): the mass it carries on its
load side (input M_carried) and the drive force it reports with two derivatives (outputs F_drive, F_drive_dot,
F_drive_ddot, m_drive), against independent routes: the exact discretisation of a heavier carriage, the closed-form
response of the rigid drive, finite differences along the model, the energy of the free chain."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import load_params
from scipy.linalg import expm

from fmus.actuator.model import ActuatorBlock, transmission_ratio
from fmus.common.block import ModelError

H = 1e-4


def quiet(**over) -> dict:
    """The paper's axis without friction and gravity: the carried mass alone decides (an actuator_1 set)."""
    return {**load_params("actuator"), "tau_c": 0.0, "g_guide": 0.0, **over}


def run(block: ActuatorBlock, u, F: float, D: float, steps: int, h: float = H) -> dict[str, np.ndarray]:
    """Step ``block`` with the voltage ``u(k)`` and the force F and carried mass D held; outputs after each step."""
    block.set(u=u(0), F=F, M_carried=D)
    block.initialize(0.0)
    values, n_in = block.values, len(block.INPUTS)
    rows = []
    for k in range(steps):
        values[0] = u(k)
        block.do_step(k * h, h)
        rows.append(list(values[n_in:]))
    data = np.array(rows)
    return {name: data[:, j] for j, name in enumerate(block.OUTPUTS)}


def load_mass(params: dict) -> float:
    """m [kg]: the load-side mass of the chain, from the paper's relations (Eqs. 1, 20-22) by hand."""
    i_R = params["p"] / (2.0 * math.pi * params["i_r"])
    J2 = params["J_guide"] / params["i_r"] ** 2 + params["M_load"] * i_R**2
    if params["n_dof"] == 1:
        J1 = params["J1_scale"] * (params["J_motor"] + params["J_gearbox"] + params["J_coupling"] + params["J_brake"])
        J2 += J1
    return J2 / i_R**2


@pytest.mark.parametrize("n_dof", [1, 2])
@pytest.mark.parametrize("ratio", [0.1, 10.0, 1000.0])
def test_a_carried_mass_moves_as_a_heavier_carriage_to_second_order_in_the_step(n_dof, ratio):
    """M_carried = D against the exact discretisation of a carriage D heavier (M_load + D: the model's other route,
    no implicit term), a 50 Hz voltage sine over 40 ms; the error falls with the step's square."""
    p = quiet(n_dof=n_dof)
    D = ratio * load_mass(p)
    errors = []
    for h in (H, H / 2):
        voltage = lambda k, h=h: 6.0 * math.sin(2.0 * math.pi * 50.0 * k * h)  # noqa: E731
        steps = round(0.04 / h)
        heavy = run(ActuatorBlock({**p, "M_load": p["M_load"] + D}), voltage, 0.0, 0.0, steps, h)["rho"]
        carried = run(ActuatorBlock(p), voltage, 0.0, D, steps, h)["rho"]
        errors.append(np.abs(carried - heavy).max() / np.ptp(heavy))
    assert errors[0] < (1e-2 if ratio > 100.0 else 1e-3), errors
    assert errors[0] >= 3.5 * errors[1], errors  # second order: the carried force is the exact mean over the step


@pytest.mark.parametrize("ratio", [0.01, 1.0, 100.0, 1000.0])
def test_the_rigid_drive_carrying_a_mass_follows_its_closed_form(ratio):
    """n_dof = 1, a voltage step, a force held: L di/dt = u - R i - k_E omega, (J + D i_R^2) domega/dt = k_T i - i_R F,
    solved by the matrix exponential written here."""
    p = quiet(n_dof=1)
    i_R = transmission_ratio(p["p"], p["i_r"])
    D, F, u = ratio * load_mass(p), 5.0, 12.0
    J = load_mass(p) * i_R**2 + D * i_R**2
    A = np.array([[-p["R"] / p["L"], 0.0, -p["k_E"] / p["L"]], [0.0, 0.0, 1.0], [p["k_T"] / J, 0.0, 0.0]])
    b = np.array([u / p["L"], 0.0, -i_R * F / J])
    G = np.zeros((4, 4))
    G[:3, :3], G[:3, 3] = A, b
    errors = []
    for h in (H, H / 2):
        steps = round(0.02 / h)
        closed = np.array([(expm(G * (k + 1) * h) @ [0.0, 0.0, 0.0, 1.0])[1] for k in range(steps)])
        theta = (run(ActuatorBlock(p), lambda k: u, F, D, steps, h)["rho"] - p["rho_0"]) / i_R
        errors.append(np.abs(theta - closed).max() / np.abs(closed).max())
    assert errors[0] < 5e-3 and errors[0] >= 1.8 * errors[1], errors


@pytest.mark.parametrize("n_dof", [1, 2])
@pytest.mark.parametrize("ratio", [0.01, 1.0, 1000.0])
def test_no_energy_grows_in_the_free_chain_carrying_any_mass_over_1e5_steps(n_dof, ratio):
    """A force pulse, then the drive short-circuited (u = 0): its kinetic and spring energy, the carried mass's
    included, only falls (the winding dissipates it)."""
    p = quiet(n_dof=n_dof)
    block = ActuatorBlock(p)
    i_R = transmission_ratio(p["p"], p["i_r"])
    D = ratio * load_mass(p)
    block.set(u=0.0, F=50.0, M_carried=D)
    block.initialize(0.0)
    J = list(block.J)
    J[-1] += D * i_R**2

    def energy() -> float:
        s = block.state()
        N = len(J)
        kinetic = sum(0.5 * J[k] * s[f"omega_{k + 1}"] ** 2 for k in range(N))
        spring = sum(0.5 * K * (s[f"theta_{k + 1}"] - s[f"theta_{k + 2}"]) ** 2 for k, K in enumerate(block.K))
        return kinetic + spring + 0.5 * p["L"] * s["i"] ** 2

    for k in range(20):
        block.do_step(k * H, H)
    block.values[1] = 0.0
    start = energy()
    worst = start
    for k in range(20, 100_000):
        block.do_step(k * H, H)
        if k % 1000 == 0:
            worst = max(worst, energy())
    assert start > 0.0 and worst <= start * (1.0 + 1e-9) and energy() < start


@pytest.mark.parametrize("D", [0.0, 3.0])
def test_the_drive_force_derivatives_are_its_rates_along_the_model(D):
    """F_drive_dot and F_drive_ddot against central differences of F_drive over steps of 1 us (two-inertia chain,
    no friction: the model's rates with its inputs held)."""
    p = quiet(n_dof=2)
    h = 1e-6
    out = run(ActuatorBlock(p), lambda k: 8.0, 20.0, D, 3000, h)
    T = out["F_drive"]
    k = np.arange(100, 2900, 97)
    d1 = (T[k + 1] - T[k - 1]) / (2 * h)
    d2 = (T[k + 1] - 2 * T[k] + T[k - 1]) / h**2
    assert np.abs(d1 - out["F_drive_dot"][k]).max() < 1e-3 * np.abs(out["F_drive_dot"]).max()
    assert np.abs(d2 - out["F_drive_ddot"][k]).max() < 1e-2 * np.abs(out["F_drive_ddot"]).max()
    # the load side's balance: m a = F_drive - (F + D a) at the end of every step
    m = out["m_drive"][0]
    assert m == pytest.approx(load_mass(p), rel=1e-12)
    a = out["rho_ddot"]
    assert np.abs(m * a - (T - 20.0 - D * a)).max() < 1e-9 * np.abs(T).max()


@pytest.mark.parametrize("bad", [-1.0, math.nan, math.inf])
def test_a_carried_mass_that_is_no_mass_is_refused_naming_it(bad):
    p = quiet()
    block = ActuatorBlock(p)
    block.set(u=0.0, F=0.0, M_carried=bad)
    with pytest.raises(ModelError, match=r"input 'M_carried' = .* at t=0 s is not a finite mass >= 0 kg"):
        block.initialize(0.0)
    block.set(M_carried=0.0)
    block.initialize(0.0)
    block.set(M_carried=bad)
    with pytest.raises(ModelError, match=r"input 'M_carried' = .* at t=0 s is not a finite mass >= 0 kg"):
        block.do_step(0.0, H)
