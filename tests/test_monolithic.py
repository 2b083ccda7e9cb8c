"""The monolithic reference (mast.analyses.monolithic): the drives and the mechanism integrated as one system, and
what the condensed exchange (docs/coupling.md) costs against it on the MAST."""

from __future__ import annotations

import numpy as np
import pytest

from mast.analyses.monolithic import simulate_monolithic
from mast.core.motion import SineMotion
from mast.core.run import simulate

MOTION = SineMotion("z", amplitude=0.005, frequency=2.0)
STOP = 0.04  # s: the start from rest (the carriages take the platform's weight) and 20 ms of the sine after it
SETTLED = 0.02  # s: the forces are compared after the start's transient of the belts' mode
DRIVES = (1, 2, 3)


def runs(kg: float, T: float, built) -> tuple:
    """(monolithic, co-simulated) direct runs of the MAST with a ``kg`` specimen at the platform centre, the drives,
    the controller and the exchange at ``T`` [s], the mechanism's full update every 10 T."""
    ssp = built / "ssp" / "MAST.ssp"
    parameters = {
        "mechanism": {"m_payload": kg, "T_mech": 10 * T},
        "controller": {"T_cur": T},
        **{f"actuator_{k}": {"T_cur": T} for k in DRIVES},
    }
    steps = {name: T for name in ("controller", "mechanism", *(f"actuator_{k}" for k in DRIVES))}
    common = dict(record_step=2 * T, base_step=T, step_sizes=steps)
    return (
        simulate_monolithic(ssp, MOTION, STOP, parameters, **common),
        simulate(ssp, MOTION, STOP, parameters, direct=True, **common),
    )


def errors(reference, run) -> dict[str, float]:
    """The largest differences: carriage positions over the motion's range, currents over their peak, forces after
    the start over the largest force."""
    late = reference.time >= SETTLED
    force = max(np.abs(reference[f"mechanism.F_{k}"]).max() for k in DRIVES)
    out = {"rho": 0.0, "i_m": 0.0, "F": 0.0}
    for k in DRIVES:
        rho, i_m, F = reference[f"actuator_{k}.rho"], reference[f"actuator_{k}.i_m"], reference[f"mechanism.F_{k}"]
        out["rho"] = max(out["rho"], np.abs(run[f"actuator_{k}.rho"] - rho).max() / np.ptp(rho))
        out["i_m"] = max(out["i_m"], np.abs(run[f"actuator_{k}.i_m"] - i_m).max() / np.abs(i_m).max())
        out["F"] = max(out["F"], np.abs(run[f"mechanism.F_{k}"] - F)[late].max() / force)
    return out


def test_the_reference_is_converged_in_its_tolerance(built):
    ssp = built / "ssp" / "MAST.ssp"
    tight = simulate_monolithic(ssp, MOTION, 0.01, record_step=1e-4)
    loose = simulate_monolithic(ssp, MOTION, 0.01, record_step=1e-4, rtol=1e-7)
    for k in DRIVES:
        rho = tight[f"actuator_{k}.rho"]
        assert np.abs(loose[f"actuator_{k}.rho"] - rho).max() < 1e-6 * np.ptp(rho)
        # and it moved: the carriages take the platform's weight from rest
        assert np.ptp(rho) > 1e-7


@pytest.mark.parametrize("kg", [0.0, 5.0])
def test_the_exchange_is_within_the_issues_bounds_of_the_reference(built, kg):
    e = errors(*runs(kg, 1e-4, built))
    assert e["rho"] < 1e-3 and e["i_m"] < 1e-2 and e["F"] < 1e-2, e


@pytest.mark.parametrize("kg", [0.0, 50.0])
def test_halving_the_exchange_halves_the_error(built, kg):
    """First order in the exchange step, with no specimen and with 50 kg (where the error at 100 us is above the
    issue's bounds: the start rings the belts' heave mode, which the exchange damps more than the reference,
    docs/coupling.md)."""
    coarse, fine = errors(*runs(kg, 1e-4, built)), errors(*runs(kg, 5e-5, built))
    assert coarse["rho"] >= 1.8 * fine["rho"] and coarse["i_m"] >= 1.5 * fine["i_m"], (coarse, fine)
