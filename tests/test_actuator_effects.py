"""The actuator's effects with neutral defaults (issue 5): Stribeck friction, backlash,
position ripple, and the torque measurement model (tau_meas). Checked against closed-form
results; the defaults leave the generated step code and every number unchanged."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import load_params
from test_actuator import run

from fmus.actuator.model import ActuatorBlock, transmission_ratio
from fmus.actuator.sensor import TorqueSensor, filter_coefficients, measure
from fmus.common.parameters import ParameterError

H = 1e-4


def test_neutral_defaults_generate_the_plain_step():
    """Manufacturer and identified sets: no Stribeck/backlash/ripple code, tau_meas = tau_m exactly."""
    for name in ("actuator", "actuator_identified"):
        p = load_params(name)
        assert p["tau_s"] == p["backlash"] == p["tau_ripple"] == p["T_meas"] == p["delay_meas"] == p["tau_offset"] == 0
        block = ActuatorBlock(p)
        out = run(block, 2.0 * np.sin(np.linspace(0, 20, 3000)), 10.0)
        src = block._kernel.source
        assert "exp(" not in src and "sin(" not in src and "pl" not in src
        assert block.substeps == 1
        np.testing.assert_array_equal(out["tau_meas"], out["tau_m"])


def test_measurement_model_in_the_fmu_equals_the_array_version():
    p = dict(load_params("actuator_identified"), T_meas=3e-3, delay_meas=2.5e-3, tau_offset=0.01)
    out = run(ActuatorBlock(p), 2.0 * np.sin(np.linspace(0, 30, 5000)), 10.0)
    expect = measure(out["tau_m"], H, 3e-3, 2.5e-3, 0.01)
    assert np.abs(out["tau_meas"] - expect).max() < 1e-15
    assert np.abs(out["tau_meas"] - out["tau_m"]).max() > 1e-3  # it does something


def test_filter_is_exact_for_a_ramp_and_the_delay_shifts():
    """First-order low-pass of a ramp a t (steady before 0): a (t - T (1 - e^(-t/T))), exactly at the samples."""
    T, h, a = 2e-3, 1e-4, 3.0
    t = np.arange(400) * h
    y = measure(a * t, h, T=T)
    np.testing.assert_allclose(y, a * (t - T * (1 - np.exp(-t / T))), atol=1e-13)
    # the sample-by-sample sensor does the same
    s = TorqueSensor(T, 0.0, 0.0)
    s.reset(0.0)
    y2 = [0.0] + [s.step(a * tk, h) for tk in t[1:]]
    np.testing.assert_allclose(y2, y, atol=1e-15)
    # delay: integer and fractional multiples of the step
    u = np.sin(np.arange(1000) * 0.01)
    np.testing.assert_allclose(measure(u, h, delay=30 * h)[30:], u[:-30], atol=1e-15)
    d = measure(u, h, delay=30.5 * h)
    np.testing.assert_allclose(d[31:], 0.5 * (u[1:-30] + u[:-31]), atol=1e-15)
    assert filter_coefficients(0.0, h) == (0.0, 1.0, 0.0)


def test_stribeck_breakaway_torque():
    """Slow voltage ramp up: the carriage breaks away at the peak of the friction law plus the weight torque
    (the peak is (tau_c + tau_s e^(-(w/omega_s)^2)) tanh(w/omega_c) at its maximum: below tau_c + tau_s
    because of the tanh regularisation)."""
    p = dict(load_params("actuator_identified"), tau_s=0.03, omega_s=2.0)
    i_R = transmission_ratio(p["p"], p["i_r"])
    weight = i_R * p["M_load"] * p["g_guide"]
    out = run(ActuatorBlock(p), np.linspace(0.0, 1.5, 15000), 0.0)
    slide = 3 * p["omega_c"] * i_R
    k = int(np.argmax(out["rho_dot"] > slide))
    assert k > 0
    w = np.linspace(0, 10, 100001)
    peak = float(np.max((p["tau_c"] + p["tau_s"] * np.exp(-((w / p["omega_s"]) ** 2))) * np.tanh(w / p["omega_c"])))
    assert peak > p["tau_c"] + 0.5 * p["tau_s"]
    assert out["tau_m"][: k + 1].max() == pytest.approx(peak + weight, rel=0.02)
    # once sliding fast, the friction falls back to tau_c: constant voltage, steady speed
    fast = run(ActuatorBlock(p), 3.0, 0.0, n=20000)
    plain = run(ActuatorBlock(dict(p, tau_s=0.0)), 3.0, 0.0, n=20000)
    assert fast["omega_m"][-1] == pytest.approx(plain["omega_m"][-1], rel=1e-6)


def test_stribeck_steep_fall_is_stable():
    """A steep Stribeck fall (b tau_s / omega_s large) refines the substeps: no NaN, no chatter at standstill."""
    p = dict(load_params("actuator_identified"), tau_s=0.2, omega_s=0.6)
    block = ActuatorBlock(p)
    out = run(block, 0.3 * np.sin(np.linspace(0, 12, 20000)), 0.0)
    assert np.isfinite(out["rho"]).all()
    assert block.substeps >= 1


def test_backlash_dead_zone():
    """Guide held by a large friction (it only creeps, tanh law): the motor turns freely through half the
    gap (it starts centred), then the spring takes the motor torque: deflection hb + k_T i / K_t."""
    b = 0.02
    p = dict(load_params("actuator_identified"), backlash=b, tau_c=30.0, g_guide=0.0)
    block = ActuatorBlock(p)
    out = run(block, 0.3, 0.0, n=10000)
    st = block.state()
    defl = st["theta_1"] - st["theta_2"]
    tau = p["k_T"] * st["i"]
    assert abs(st["theta_2"]) < b / 20  # the guide only crept
    assert defl == pytest.approx(b / 2 + tau / p["K_t"], rel=1e-3)
    assert block.substeps == 10  # 10 us substeps at the 100 us step
    # before contact the motor accelerates freely: no spring torque on it
    assert np.abs(out["theta_m"][:5]).max() < b / 2


def test_tiny_backlash_converges_to_the_plain_model():
    p = load_params("actuator_identified")
    u = 2.0 * np.sin(np.linspace(0, 20, 5000))
    plain = run(ActuatorBlock(p), u, 10.0)
    tiny = run(ActuatorBlock(dict(p, backlash=1e-9)), u, 10.0)
    assert np.abs(tiny["rho"] - plain["rho"]).max() < 1e-3 * np.ptp(plain["rho"])
    assert np.abs(tiny["tau_m"] - plain["tau_m"]).max() < 1e-3 * np.ptp(plain["tau_m"])


def test_backlash_needs_two_inertias():
    p = dict(load_params("actuator"), backlash=0.01, n_dof=1)
    with pytest.raises(ParameterError, match="backlash"):
        ActuatorBlock(p)


def test_ripple_torque_depends_on_position():
    """Friction-free, no gravity, motor driven at constant voltage: the speed ripples with the
    carriage position at the ripple period."""
    p = dict(load_params("actuator_identified"), tau_c=0.0, g_guide=0.0, tau_ripple=0.01, ripple_period=0.002)
    out = run(ActuatorBlock(p), 2.0, 0.0, n=20000)
    keep = out["t"] > 0.5
    rho, w = out["rho"][keep], out["omega_m"][keep]
    phase = 2 * math.pi * (rho - p["rho_0"]) / p["ripple_period"]
    basis = np.column_stack([np.ones_like(rho), rho, np.sin(phase), np.cos(phase)])
    coef, res, *_ = np.linalg.lstsq(basis, w, rcond=None)
    assert math.hypot(coef[2], coef[3]) > 0.05  # rad/s of ripple at the position period
    plain = run(ActuatorBlock(dict(p, tau_ripple=0.0)), 2.0, 0.0, n=20000)
    assert np.std(np.diff(plain["omega_m"][keep])) < 0.1 * np.std(np.diff(w))
