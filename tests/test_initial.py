"""The initial values' fixed point (mast.core.initial.settle): Jacobi passes where they contract, Newton where they
do not (an actuator's load side lighter than the mechanism's joint-space mass), a clear error where there is none."""

from __future__ import annotations

import numpy as np
import pytest

from mast.core.initial import SettleError, settle


def mass_loop(M: float, m: float, tau: float = 2.0, G: float = 5.0):
    """An actuator and a mechanism in initialization: the actuator's acceleration a = (tau - F) / m from the force F
    the mechanism returns, the mechanism's F = M a + G from the acceleration (values [a, F]); loop gain -M/m. The
    consistent point by hand: a = (tau - G) / (m + M)."""

    def evaluate(v):
        a, F = v
        return [(tau - F) / m, M * a + G]

    exact = (tau - G) / (m + M)
    return evaluate, [exact, M * exact + G]


@pytest.mark.parametrize("M, m", [(11.68, 3.6), (3.0, 1.0), (100.0, 1.0)])
def test_a_loop_of_gain_above_one_settles_by_newton(M, m):
    """Gain 3.2 (the 6-UPS's joint-space mass on the paper's belt axis), 3 and 100: the plain passes diverge (checked
    here), settle finds the point the equations give by hand."""
    evaluate, exact = mass_loop(M, m)
    v = [0.0, 0.0]
    for _ in range(40):
        v = evaluate(v)
    assert abs(v[0] - exact[0]) > 1e3  # the Jacobi passes alone run away
    got = settle(evaluate, [0.0, 0.0], ["actuator", "mechanism"])
    np.testing.assert_allclose(got, exact, rtol=1e-12)


def test_a_contracting_loop_gives_the_passes_own_values():
    """Gain 0.25 (the 3PRS): the values are those of the plain passes, stopped where they stop changing."""
    evaluate, exact = mass_loop(0.25 * 5.9, 5.9)
    v = [0.0, 0.0]
    while True:
        new = evaluate(v)
        if all(abs(a - b) <= 1e-13 * (1 + abs(b)) for a, b in zip(new, v)):
            break
        v = new
    assert settle(evaluate, [0.0, 0.0], ["actuator", "mechanism"]) == new
    np.testing.assert_allclose(new, exact, rtol=1e-12)


def test_a_loop_without_a_fixed_point_is_refused_naming_its_components():
    def evaluate(v):
        a, F, x = v
        return [F + 1.0, a, 7.0]  # a = a + 1: no solution; x settles

    with pytest.raises(SettleError, match=r"initial values of actuator, mechanism did not settle") as err:
        settle(evaluate, [0.0, 0.0, 0.0], ["actuator", "mechanism", "controller"])
    assert "controller" not in str(err.value)
