"""The initial values of a co-simulation: the fixed point of the components' algebraic loops.

In initialization mode every component's outputs are algebraic functions of its inputs (and
parameters); the inputs are other components' outputs. The consistent initial point is the fixed
point v = G(v) of the exchange map G (set every member's inputs from the values v, read its
outputs). ``settle`` finds it:

1. Jacobi passes v <- G(v), as long as they contract. A loop through an actuator and the mechanism
   (rho_ddot -> F -> rho_ddot) has the gain -M/m, the mechanism's joint-space mass M over the
   actuator's load-side mass m (paper Eq. 1: m = J_2 / i_R^2): 0.25 for the 3PRS, 0.83 for the
   3-RPS; the passes converge when |M/m| < 1, and then give the values they always gave.
2. When the passes stop contracting (a pass's change exceeds the one two passes before, ``GROWING``
   passes in a row; a 6-UPS on the paper's belt axes: M/m = 11.68 kg / 3.6 kg) or the pass budget
   runs out: Newton's method on the residual r(v) = G(v) - v from the start values, its Jacobian by
   forward differences (one evaluation per unknown), which solves a linear loop of any gain in one
   step and a nonlinear one in a few.

The Jacobian's columns are computed only for the values some member reads (the others' are zero).
"""

from __future__ import annotations

import math
from typing import Callable, Optional, Sequence

import numpy as np

#: passes in a row whose change exceeds the change two passes before: Jacobi gives way to Newton
GROWING = 5
#: Newton iterations before giving up
NEWTON_ITERATIONS = 20


class SettleError(RuntimeError):
    """The initial values do not settle: the message names the components whose values still change."""


def _changed(new: Sequence[float], old: Sequence[float], tol: float) -> float:
    """The largest change of ``new`` against ``old`` relative to 1 + |old|, over ``tol`` (> 1: not settled)."""
    worst = 0.0
    for a, b in zip(new, old):
        d = abs(a - b) / (tol * (1.0 + abs(b)))
        if not d <= worst:  # NaN counts as a change
            worst = d if math.isfinite(d) else math.inf
    return worst


def settle(
    evaluate: Callable[[Sequence[float]], list[float]],
    start: Sequence[float],
    owners: Sequence[str],
    read: Optional[Sequence[int]] = None,
    passes: int = 1000,
    tol: float = 1e-13,
) -> list[float]:
    """The fixed point v = ``evaluate``(v) from ``start`` (module docstring): Jacobi passes while they contract,
    Newton otherwise. ``owners[j]`` names the component that produces value j (for the error message); ``read``:
    the indices of the values ``evaluate`` depends on (None: all; the others' Jacobian columns are zero and not
    computed); a value settles when it changes by at most ``tol`` (1 + |v|). Raises SettleError naming the
    components whose values did not settle."""
    values = list(start)
    growth, changes = 0, [math.inf, math.inf]
    for _ in range(passes):
        new = evaluate(values)
        change = _changed(new, values, tol)
        values = new
        if change <= 1.0:
            return values
        growth = growth + 1 if change > changes[-2] else 0  # over two passes: a loop through two components
        changes.append(change)
        if growth >= GROWING or not math.isfinite(change):
            break
    return _newton(evaluate, list(start), owners, range(len(values)) if read is None else read, tol)


def _newton(
    evaluate: Callable[[Sequence[float]], list[float]],
    values: list[float],
    owners: Sequence[str],
    read: Sequence[int],
    tol: float,
) -> list[float]:
    """Newton's method on r(v) = evaluate(v) - v, the Jacobian by forward differences in the ``read`` values."""
    v = np.array(values, dtype=float)
    n = len(v)
    for _ in range(NEWTON_ITERATIONS):
        g = np.array(evaluate(list(v)), dtype=float)
        r = g - v
        if _changed(g, v, tol) <= 1.0:
            return list(g)
        jacobian = np.zeros((n, n))
        for j in read:
            h = 1e-7 * (1.0 + abs(v[j]))
            probe = v.copy()
            probe[j] += h
            jacobian[:, j] = (np.array(evaluate(list(probe)), dtype=float) - g) / h
        jacobian -= np.eye(n)
        try:
            step = np.linalg.solve(jacobian, -r)
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(step)):
            break
        v = v + step
    g = np.array(evaluate(list(v)), dtype=float)
    bad = sorted({owners[j] for j in range(n) if not abs(g[j] - v[j]) <= tol * (1.0 + abs(v[j]))})
    raise SettleError(
        f"initialization: the initial values of {', '.join(bad) or 'the loop'} did not settle (Jacobi passes "
        f"diverge and {NEWTON_ITERATIONS} Newton iterations did not converge: an algebraic loop without a solution)"
    )
