"""A check the mechanisms' tests share: random walks of the joints from home keep the direct kinematics on the
branch of home (tests/test_rps.py, tests/test_hexapod.py)."""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from fmus.mechanism.kinematics import KinematicsError


def walk_keeps_branch(
    eng,
    joints_of: Callable[[np.ndarray], np.ndarray],
    home: Sequence[float],
    stroke: tuple[float, float],
    *,
    sigma: float,
    seed: int,
    walks: int,
    length: int,
    cold_start: bool = True,
) -> int:
    """Walk the joints from ``home`` by normal steps of ``sigma`` [m] (a step leaving ``stroke`` skipped; a step the
    direct kinematics refuses, at its margin, skipped too: a refusal is allowed, a jump is not) and assert at every
    step that the pose ``eng.dk`` finds gives the joints back by ``joints_of`` (an independent route) to 1e-11 m, lies
    on the branch of home (the sign of det drho/dq) and, with ``cold_start``, that a cold start finds it too.
    Returns the number of steps taken."""
    home = np.asarray(home, dtype=float)
    lo, hi = stroke
    det_home = eng.margins(home).det
    rng = np.random.default_rng(seed)
    steps = 0
    for _ in range(walks):
        rho, q = joints_of(home), home
        for _ in range(length):
            step = rng.normal(0.0, sigma, len(rho))
            if np.any(rho + step < lo) or np.any(rho + step > hi):
                continue
            try:
                q_next = np.asarray(eng.dk(rho + step, guess=q)[0])
            except KinematicsError:
                continue
            rho, q, steps = rho + step, q_next, steps + 1
            np.testing.assert_allclose(joints_of(q), rho, rtol=0.0, atol=1e-11)
            assert np.sign(eng.margins(q).det) == np.sign(det_home)
            if cold_start:
                np.testing.assert_allclose(eng.dk(rho)[0], q, rtol=0.0, atol=1e-9)
    return steps
