"""What a test plan must excite for each effect to be identifiable, and whether the user's plan does.

Read from the commanded joint motion of every test (not from its labels): its reversal frequency
(velocity sign changes per second / 2), whether the axes (drives) move alike (z) or differently (a
rotation, a sideways motion), and its role. The thresholds follow the effects' signatures (effects.py) and the
cascade's bandwidth (about 4 Hz, ssp/resources/controller_joint.ssv); the frequencies are
engineering judgement, stated with each requirement.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Optional, Sequence

import numpy as np


@dataclass
class Excitation:
    """One test's motion as an identification experiment."""

    name: str
    role: str
    frequency: float  # Hz: reversals per second / 2 (0 without reversals)
    alike: bool  # every axis moves alike (a z motion)
    moving: tuple = (True, True, True)  # which axes move (one flag per drive)

    def on_axis(self, j: int) -> "Excitation":
        """The test as seen by axis j (0-based): no reversals if that axis stands still or the machine has no
        axis j (a per-axis effect of a drive it lacks: no test excites it)."""
        moves = j < len(self.moving) and self.moving[j]
        return Excitation(self.name, self.role, self.frequency if moves else 0.0, self.alike, self.moving)


def excitation(name: str, role: str, t: np.ndarray, rho_cmd: np.ndarray) -> Excitation:
    v = np.gradient(rho_cmd, t, axis=0)
    scale = np.abs(v).max(axis=0)
    moving = scale > 1e-3 * float(scale.max())  # an axis that stands still (its commands' rounding is no motion)
    reversals = [
        int(np.count_nonzero(np.diff(np.sign(v[np.abs(v[:, j]) > 0.05 * scale[j], j])) != 0))
        for j in range(rho_cmd.shape[1])
        if moving[j]
    ]
    duration = float(t[-1] - t[0]) or 1.0
    frequency = max(reversals) / (2 * duration) if reversals else 0.0
    spread = np.ptp(rho_cmd, axis=0)
    d = rho_cmd - rho_cmd.mean(axis=0)
    alike = bool(np.allclose(d, d[:, :1], atol=0.05 * float(spread.max() or 1.0)))
    return Excitation(name, role, frequency, alike, tuple(bool(m) for m in moving))


def _both_roles(tests: Sequence[Excitation], ok: Callable[[Excitation], bool]) -> Optional[str]:
    roles = {x.role for x in tests}
    missing = [r for r in sorted(roles) if not any(ok(x) for x in tests if x.role == r)]
    return f"no such {' or '.join(missing)} test" if missing else None


def _two(tests: Sequence[Excitation], ok: Callable[[Excitation], bool]) -> Optional[str]:
    have = [x.name for x in tests if ok(x)]
    return (
        None
        if len(have) >= 2
        else (
            "no such test in the plan"
            if not have
            else f"only one such test in the plan ({have[0]}): one to fit it and another to check it are needed"
        )
    )


@dataclass(frozen=True)
class InBothRoles:
    """A requirement of the split: a test for which ``ok`` holds among the training and among the held-out tests
    (calling it checks a split). The whole plan can meet it (``whole``) when two tests qualify, whatever their
    roles: a split can then put one on each side (``choose_split``)."""

    ok: Callable[[Excitation], bool]

    def __call__(self, tests: Sequence[Excitation]) -> Optional[str]:
        return _both_roles(tests, self.ok)

    def whole(self, tests: Sequence[Excitation]) -> Optional[str]:
        return _two(tests, self.ok)


def _fast(tests: Sequence[Excitation]) -> Optional[str]:
    """Two or more fast tests (>= FAST_HZ) of one kind of motion, whatever their roles: backlash makes the
    loop hunt on the fast tests, a rotation loads the axes differently from z and need not hunt alike, and
    its leave-one-test-out check predicts each hunting test from another one."""
    fast = [x for x in tests if x.frequency >= FAST_HZ]
    if max(sum(x.alike == kind for x in fast) for kind in (True, False)) >= 2:
        return None
    return (
        f"no test at {FAST_HZ:g} Hz or above"
        if not fast
        else f"only one test at {FAST_HZ:g} Hz or above ({fast[0].name})"
        if len(fast) == 1
        else f"one z and one rotation test at {FAST_HZ:g} Hz or above, not two of one kind"
    )


#: reversal rate [Hz] from which a test is fast for backlash (near the cascade's bandwidth, about 4 Hz, the
#: torque reverses sharply enough for the loop to hunt: engineering judgement, see docs/diagnose.md)
FAST_HZ = 3.0


def _speeds(tests: Sequence[Excitation]) -> Optional[str]:
    f = [x.frequency for x in tests if x.frequency > 0]
    return None if f and max(f) >= 2 * min(f) else "all tests reverse at about one rate"


def _kinds(tests: Sequence[Excitation]) -> Optional[str]:
    kinds = {x.alike for x in tests if x.frequency > 0}
    return (
        None
        if kinds == {True, False}
        else ("only motions of the axes alike (z)" if kinds == {True} else "no motion of the axes alike (z)")
    )


#: effect keys -> (what the plan must excite, the check: None when met, else why not)
REQUIREMENTS: dict[tuple[str, ...], tuple[str, Callable[[Sequence[Excitation]], Optional[str]]]] = {
    ("coulomb", "offset"): (
        "velocity reversals in a training and a held-out test",
        InBothRoles(lambda x: x.frequency > 0),
    ),
    ("viscous",): (
        "reversal rates (speeds) differing by 2 x or more across tests: viscous grows with speed, "
        "Coulomb friction does not",
        _speeds,
    ),
    ("stribeck",): (
        "a slow test (<= 1 Hz), where the motion lingers near standstill at each reversal",
        lambda ts: None if any(0 < x.frequency <= 1.0 for x in ts) else "no test at 1 Hz or below",
    ),
    ("inertia_motor", "inertia_guide"): (
        "a training and a held-out test at >= 2 Hz: the inertia torque grows with f^2 and is small below",
        InBothRoles(lambda x: x.frequency >= 2.0),
    ),
    ("carriage_mass",): (
        "motions of the axes alike (z) and differently (a rotation): on z alone a heavier "
        "carriage and more inertia plus an offset look alike",
        _kinds,
    ),
    ("lag",): (
        "a test at >= 3 Hz: the phase lag grows with f",
        lambda ts: None if any(x.frequency >= 3.0 for x in ts) else "no test at 3 Hz or above",
    ),
    ("velocity_gain", "position_gain", "velocity_integral"): (
        "a training and a held-out test at >= 2 Hz, near the cascade's bandwidth "
        "(about 4 Hz): well below it the loop follows whatever its gains",
        InBothRoles(lambda x: x.frequency >= 2.0),
    ),
    ("velocity_cycle",): (
        "a training and a held-out test at >= 2 Hz: a longer cycle is a delay inside the velocity "
        "loop, which grows as the tests approach the cascade's bandwidth (about 4 Hz)",
        InBothRoles(lambda x: x.frequency >= 2.0),
    ),
    ("stiffness",): (
        "a training and a held-out test at >= 2 Hz: the spring's deflection (a phase lag inside the "
        "position loop) grows as the tests approach the cascade's bandwidth (about 4 Hz)",
        InBothRoles(lambda x: x.frequency >= 2.0),
    ),
    ("current_limit",): (
        "tests whose torque reaches the limit (the fastest, largest motions): below it the limit "
        "leaves no trace (and does no harm to that plan); the commands alone cannot tell whether a "
        "test reaches it, the diagnosis tries it when the data's torque peak stays below the "
        "model's",
        lambda ts: None,
    ),
    ("backlash",): (
        f"two or more tests at >= {FAST_HZ:g} Hz of one kind of motion (z, or rotations), in any "
        "roles: the loop hunts on the fast tests, and leave-one-test-out predicts each from another",
        _fast,
    ),
}
#: effects on one axis only ("<key>_axis<j>") need what the all-axes effect needs, in tests where that axis moves
PER_AXIS_NOTE = "; in tests where that axis moves"


def identifiability(tests: Sequence[Excitation], library: Sequence[str]) -> dict[str, dict]:
    """For every effect of ``library``: what the plan must excite, whether the plan does whatever the split
    (``plan_meets``: some split of its tests into training and held-out ones can fit and check it), and whether
    the tests' roles do (``split_meets``: a training and a held-out test of what it needs)."""
    out = {}
    for key in library:
        base, _, axis = key.partition("_axis")
        for keys, (needs, check) in REQUIREMENTS.items():
            if base in keys:
                seen = [x.on_axis(int(axis) - 1) for x in tests] if axis else list(tests)
                whole = check.whole(seen) if isinstance(check, InBothRoles) else check(seen)
                split = check(seen) if whole is None else whole
                out[key] = {
                    "requires": needs + (PER_AXIS_NOTE if axis else ""),
                    "plan_meets": whole is None,
                    "why_not": whole,
                    "split_meets": split is None,
                    "split_why_not": split,
                }
    return out


#: ``choose_split`` enumerates every split of plans up to this many tests (2^n splits, a few milliseconds each)
MAX_SPLIT_SEARCH = 10


def choose_split(tests: Sequence[Excitation], library: Sequence[str]) -> dict[str, str]:
    """The roles of the tests: the split (the tests' own roles, ``Excitation.role``, as the default) changed as
    little as possible so that the effects of ``library`` the whole plan can fit and check get a training and a
    held-out test of what it needs (``REQUIREMENTS``). Ranked by the effects on all axes met, then the effects
    on one axis, then the fewest tests moved from the default, then the number of tests held out closest to the
    default's; at least one test held out, and no more than the default holds out (the fit keeps at least as
    many tests), and the fastest training test of each kind of motion (z, a rotation) stays in training: the
    effects that grow with frequency (inertia, lags, the drive's gains) are fitted mostly on it. The default is
    kept when it already meets them all, or for plans of more than MAX_SPLIT_SEARCH tests."""
    default = {x.name: x.role for x in tests}
    names = [x.name for x in tests]
    wanted = [k for k, p in identifiability(tests, library).items() if p["plan_meets"]]
    n_held = sum(r == "held-out" for r in default.values())
    keep = {
        max((x for x in tests if x.role != "held-out" and x.alike == kind), key=lambda x: x.frequency).name
        for kind in (True, False)
        if any(x.role != "held-out" and x.alike == kind for x in tests)
    }

    def rank(roles: Mapping[str, str]) -> tuple:
        split = [Excitation(x.name, roles[x.name], x.frequency, x.alike, x.moving) for x in tests]
        met = [k for k, p in identifiability(split, wanted).items() if p["split_meets"]]
        held = sum(r == "held-out" for r in roles.values())
        return (
            -sum("_axis" not in k for k in met),
            -sum("_axis" in k for k in met),
            sum(roles[n] != default[n] for n in names),
            abs(held - n_held),
        )

    best = rank(default)
    if (
        best[:2] == (-sum("_axis" not in k for k in wanted), -sum("_axis" in k for k in wanted))
        or len(names) > MAX_SPLIT_SEARCH
        or n_held < 1
    ):
        return default
    chosen = default
    for mask in range(1, 2 ** len(names) - 1):
        if not 1 <= bin(mask).count("1") <= n_held:
            continue
        roles = {n: ("held-out" if mask >> k & 1 else "training") for k, n in enumerate(names)}
        if any(roles[n] == "held-out" for n in keep):
            continue
        r = rank(roles)
        if r < best:
            chosen, best = roles, r
    return chosen


#: at most this many folds: a plan of more tests is cut into MAX_FOLDS groups (every MAX_FOLDS-th test in frequency
#: order together), each held out once
MAX_FOLDS = 8


def fold_meets(tests: Sequence[Excitation], keys: Sequence[str]) -> dict[str, Optional[str]]:
    """For one fold (``tests`` with their roles in it): None for every effect of ``keys`` the fold can check, else
    why not. It can when its training tests alone identify the effect (what the whole plan must excite,
    ``REQUIREMENTS``, met by the training tests; for a requirement of both roles, a training test of that kind) and
    its held-out tests include one of the kind a requirement of both roles names."""
    training = [x for x in tests if x.role != "held-out"]
    out: dict[str, Optional[str]] = {}
    for key in keys:
        base, _, axis = key.partition("_axis")
        for group, (_, check) in REQUIREMENTS.items():
            if base not in group:
                continue
            seen = [x.on_axis(int(axis) - 1) for x in tests] if axis else list(tests)
            if isinstance(check, InBothRoles):
                out[key] = check(seen)
            else:
                why = check([x for x in seen if x.role != "held-out"])
                out[key] = None if why is None else f"its training tests: {why}"
    for key in keys:
        out.setdefault(key, None if training else "no training test")
    return out


def folds(tests: Sequence[Excitation], keys: Sequence[str]) -> list[dict]:
    """The folds of the cross-validation: every test held out in one fold and trained on in all the others
    (leave-one-test-out; plans of more than MAX_FOLDS tests in MAX_FOLDS groups). Each fold: its held-out and
    training tests, and which effects of ``keys`` it can check (``fold_meets``): an effect is judged on the folds
    whose training tests identify it; a plan that cannot identify it has no such fold."""
    order = sorted(tests, key=lambda x: (x.frequency, x.name))
    k = min(len(order), MAX_FOLDS)
    out = []
    for g in range(k):
        held = [x.name for i, x in enumerate(order) if i % k == g]
        seen = [
            Excitation(x.name, "held-out" if x.name in held else "training", x.frequency, x.alike, x.moving)
            for x in tests
        ]
        meets = fold_meets(seen, keys)
        out.append(
            {
                "held_out": held,
                "training": [x.name for x in tests if x.name not in held],
                "checks": [key for key in keys if meets[key] is None],
                "cannot_check": {key: why for key, why in meets.items() if why is not None},
            }
        )
    return out


def excitations(prepared: Mapping, roles: Mapping[str, str]) -> list[Excitation]:
    return [excitation(n, roles[n], p.test.time, p.test.rho_cmd) for n, p in prepared.items()]
