"""The controllers' tick, stated once: the source the Python controllers run and the native FMUs compile.

``tick_sources(cls, modes)`` writes a controller's ``start`` (``initialize``, after the reset), ``laws``
(the laws of tick n: ``DriveController``'s schedule, model.py) and ``steps`` (the ticks inside a step of m
ticks from tick n, the inputs held: those that run a loop) in the generated-code subset
(mast.core.native.translate: float arithmetic, ``if``, indexing, calls): which loop runs at which tick, the
pose command's inverse kinematics cached by pose, the joint reference's samples and rates (``REFERENCE_RATES``),
then the controller's own laws, which each controller class states as lines of the same subset
(``position_lines``, ``velocity_lines``). The tick is written for the class's n axes (``cls.COORDINATES``, the
mechanism's coordinates: DriveController.for_topology). The Python controllers compile it once per class
(``compiled``) and run it on their state ``S``, a list of floats laid out as ``layout(n, parameters)`` (the
class's ``LAYOUT``; ``LAYOUT`` here: the 3PRS's); the native generator (mast.core.native.models) translates the
same source to C, on the same layout. What the tick calls (q: the n pose coordinates, rho: the n joints):

- ``a, b = pi_step(...)``, ``rd, rdd = rates(...)``: functions that return a tuple (their own source, translated);
- ``c = ik_s(S, q_1, ..., q_n, R)`` (the inverse kinematics of the pose command, into R),
  ``c = currents(rho, rho_dot, rho_ddot (3n numbers), S, CUR)`` (the inverse model's currents),
  ``c = wsdk(rho (n numbers), S, QM)`` (the workspace controller's direct kinematics of the measured joints),
  ``c = ikjac_s(S, q_1, ..., q_n, JK)`` (drho/dq at q in JK[n:n + n^2]): 0, or a failure (the caller makes the
  message); in Python the controller's own methods, in C the traced engine's functions;
- the laws' arithmetic as value functions (``position_p_law``, ``pi_step``, ...: each controller's ``LAWS``).

A failed call ends the tick: it records the tick in ``S[failed]`` (and the arguments of a failed inverse model or
direct kinematics in ``S[model_args]``) and returns the call's code, ``MODEL_FAILED`` or ``DK_FAILED``.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Mapping, Sequence

from ..mechanism.designs import TRACED_PARAMETERS
from .inverse_model import CONSTANTS

__all__ = ["layout", "size", "LAYOUT", "SIZE", "DK_FAILED", "MODEL_FAILED", "TARGET_FAILED", "tick_sources", "compiled"]


def layout(n: int, parameters: int) -> dict[str, int]:
    """The offsets of a controller's state S (doubles) for ``n`` axes and a kinematic model traced with
    ``parameters`` numbers: tick count, t0, IK cache (valid, pose: n), the velocity PI's states (n), 2n free,
    the commands rho_cmd, omega_cmd, i_cmd (n each; "failed": the tick whose call failed, for the message),
    then the gains computed at initialisation from the parameters (``gains``: cascade_gains, then i_max); the
    operating mode (``MODES``' index: Python's ``set_mode``), two free; the joint reference's last four samples
    (4n, newest first) and their count, i_ff (n), the inverse model's direct-kinematics guess (valid flag,
    pose: n) and the arguments of a failed evaluation (3n: rho, rho_dot, rho_ddot); the reference's rates
    (rho_dot_ref, rho_ddot_ref: 2n), kept between ticks; the controller's own gains computed at initialisation
    (feedforward_gains: 2, error_gains: 2, pose_gains: n); from the parameters at initialisation: the schedule
    (T_pos / T_cur, T_vel / T_cur, T_cur, T_pos), the transmission i_R, two places "cb", "sb" no one writes
    now (the 3PRS's cold start's, before the native controllers took the mechanism's), attached (the inverse
    model's) and the kinematic model's traced parameters (``parameters`` of them, the arguments of its generated
    functions), then the inverse model's actuator constants
    (inverse_model.CONSTANTS, by its model_constants), then the coordinates' lengths (Engine.lengths: n, the
    native FMUs'). For n = 3 and the 3PRS's 24 traced parameters: the state every 3PRS controller has had
    (the free places kept: the native FMUs' state is the same). ``size(n, parameters)``: its length."""
    if n < 1:
        raise ValueError(f"state layout for n = {n!r} axes: expected n >= 1")
    fields = (
        ("n", 1),
        ("t0", 1),
        ("ik", 1),
        ("pose", n),
        ("x_v", n),
        (None, 2 * n),
        ("rho_cmd", n),
        ("omega_cmd", n),
        ("i_cmd", n),
        ("failed", 1),
        ("gains", 4),
        ("mode", 1),
        (None, 2),
        ("hist", 4 * n),
        ("k", 1),
        ("i_ff", n),
        ("warm", 1),
        ("guess", n),
        ("model_args", 3 * n),
        ("rates", 2 * n),
        ("own", max(2, n)),
        ("N_pos", 1),
        ("N_vel", 1),
        ("T_cur", 1),
        ("T_pos", 1),
        ("i_R", 1),
        ("cb", 1),
        ("sb", 1),
        ("attached", 1),
        ("P", parameters),
        ("model", len(CONSTANTS)),
        ("lengths", n),
    )
    out, at = {}, 0
    for name, length in fields:
        if name is not None:
            out[name] = at
        at += length
    out["size"] = at
    return out


def size(n: int, parameters: int) -> int:
    """The length of the state ``layout(n, parameters)``."""
    return layout(n, parameters)["size"]


#: the 3PRS's layout (n = 3, designs.TRACED_PARAMETERS), the Python controllers' (their tick reads no field from "P"
#: on; a native controller sizes that slot by its own traced parameters: mast.core.native.models)
LAYOUT = layout(3, len(TRACED_PARAMETERS))
#: the state's size (the native FMUs keep the coordinate lengths in the last three)
SIZE = size(3, len(TRACED_PARAMETERS))
#: a failure of the inverse model (its direct kinematics or dynamics)
MODEL_FAILED = 1000
#: a failure of the workspace controller's direct kinematics of the measured joints
DK_FAILED = 2000
#: a failure of the workspace controller's direct kinematics of the joint command ("joint" mode)
TARGET_FAILED = 3000


def _commands(n: int) -> dict[str, list[str]]:
    """The tick's locals of the velocity PI's states and the commands, per axis j = 0..n-1."""
    return {
        k: [f"{p}{j}" for j in range(n)]
        for k, p in (("x_v", "xv"), ("rho_cmd", "rc"), ("omega_cmd", "oc"), ("i_cmd", "ic"))
    }


def _indented(lines: Sequence[str], indent: str) -> list[str]:
    return [indent + line for line in lines]


def _tuple(items: Sequence[str]) -> str:
    """A tuple display of ``items`` (one item: with its comma)."""
    return f"({items[0]},)" if len(items) == 1 else f"({', '.join(items)})"


def _ik_lines(L: Mapping[str, int], n: int) -> list[str]:
    """DriveController's inverse kinematics of the pose command, cached by pose (the pose of the last one)."""
    P = L["pose"]
    pose = [f"values[{k}]" for k in range(n)]
    same = " and ".join(f"values[{k}] == S[{P + k}]" for k in range(n))
    return [
        f"if not (S[{L['ik']}] == 1.0 and {same}):",
        f"    c = ik_s(S, {', '.join(pose)}, R)",
        "    if c != 0:",
        f"        S[{L['failed']}] = n",
        "        return c",
        *(f"    rc{j} = R[{j}]" for j in range(n)),
        f"    S[{L['ik']}:{L['ik'] + n + 1}] = (1.0, {', '.join(pose)})",
    ]


def _reference_lines(L: Mapping[str, int], n: int) -> list[str]:
    """The joint reference at a position tick (after the IK): the new sample rho_cmd, newest first, then the
    rates of the last (at most four) samples, ``reference.rates``, kept in S[rates]."""
    H, K, Q, T = L["hist"], L["k"], L["rates"], L["T_pos"]
    old = ", ".join(f"S[{H + k}]" for k in range(3 * n))
    lines = [
        f"S[{H + n}:{H + 4 * n}] = ({old})",
        f"S[{H}:{H + n}] = {_tuple([f'rc{j}' for j in range(n)])}",
        f"k = S[{K}] + 1.0",
        "if k > 4.0:",
        "    k = 4.0",
        f"S[{K}] = k",
    ]
    for j in range(n):
        lines += [
            f"rd{j}, rdd{j} = rates(k, rc{j}, S[{H + n + j}], S[{H + 2 * n + j}], S[{H + 3 * n + j}], S[{T}])",
            f"S[{Q + j}] = rd{j}",
            f"S[{Q + n + j}] = rdd{j}",
        ]
    return lines


def failed_call(L: Mapping[str, int], call: str, args: Sequence[str], code: int) -> list[str]:
    """``c = call`` whose failure ends the tick with ``code``, the arguments ``args`` kept for the message
    (in S[model_args], of the layout ``L``)."""
    return [
        f"c = {call}",
        "if c != 0:",
        f"    S[{L['failed']}] = n",
        f"    S[{L['model_args']}:{L['model_args'] + len(args)}] = {_tuple(args)}",
        f"    return {code}",
    ]


def pi_lines(L: Mapping[str, int], n: int, offset: Sequence[str]) -> list[str]:
    """The velocity PI of the n axes (``pi_step``) with the offsets (feed-forward currents) ``offset``."""
    kp, kiT, i_max = (f"S[{L['gains'] + k}]" for k in (1, 2, 3))
    return [
        f"ic{j}, xv{j} = pi_step(oc{j} - values[{2 * n + j}], xv{j}, {kp}, {kiT}, {i_max}, {offset[j]})"
        for j in range(n)
    ]


def tick_sources(cls: type, modes: Sequence[str] = ("pose",)) -> tuple[str, str, str]:
    """``(start, laws, steps)`` of the controller class ``cls`` (module docstring; its axes ``cls.COORDINATES``
    and state ``cls.LAYOUT``) for its operating ``modes``: with "pose" alone (the native FMUs: the modes are no
    FMU variables) the tick has no mode test."""
    S, ff, n = cls.LAYOUT, cls.FEEDFORWARD_CURRENT, len(cls.COORDINATES)
    moded = tuple(modes) != ("pose",)
    named = _commands(n)
    unpack = [f"{v} = S[{S[k] + j}]" for k, vs in named.items() for j, v in enumerate(vs)]
    unpack += [f"if{j} = S[{S['i_ff'] + j}]" for j in range(n)] if ff else []
    commands = ", ".join(named["rho_cmd"] + named["omega_cmd"] + named["i_cmd"])
    store = [
        f"S[{S['x_v']}:{S['x_v'] + n}] = {_tuple(named['x_v'])}",
        f"S[{S['rho_cmd']}:{S['rho_cmd'] + 3 * n}] = ({commands})",
        *([f"S[{S['i_ff']}:{S['i_ff'] + n}] = {_tuple([f'if{j}' for j in range(n)])}"] if ff else []),
        f"values[{3 * n}:] = ({commands})",
        "return 0",
    ]
    ik = _ik_lines(S, n)
    if moded:
        ik = [f"if S[{S['mode']}] == 0.0:", *_indented(ik, "    ")]
    start = ["def start(values, S, R):", *_indented(["n = 0.0", *unpack, *ik, *store], "    ")]
    position = [*ik, *(_reference_lines(S, n) if cls.REFERENCE_RATES else []), *cls.position_lines(moded)]
    velocity = cls.velocity_lines()
    if moded:
        body = [
            f"mode = S[{S['mode']}]",
            f"if mode <= 1.0 and n % S[{S['N_pos']}] == 0.0:",
            *_indented(position, "    "),
            f"if mode <= 2.0 and n % S[{S['N_vel']}] == 0.0:",
            *_indented(velocity, "    "),
        ]
    else:
        body = [
            f"if n % S[{S['N_pos']}] == 0.0:",
            *_indented(position, "    "),
            f"if n % S[{S['N_vel']}] == 0.0:",
            *_indented(velocity, "    "),
        ]
    laws = ["def laws(values, S, R, CUR, QM, JK, n):", *_indented([*unpack, *body, *store], "    ")]
    steps = [
        "def steps(values, S, R, CUR, QM, JK, n, m):",
        "    k = n + 1",
        "    inner = m - 1",
        "    for _ in range(inner):",
        f"        if k % S[{S['N_pos']}] == 0.0 or k % S[{S['N_vel']}] == 0.0:",
        "            c = laws(values, S, R, CUR, QM, JK, k)",
        "            if c != 0:",
        "                return c",
        "        k += 1",
        "    return 0",
    ]
    return tuple("\n".join(lines) + "\n" for lines in (start, laws, steps))


@lru_cache(maxsize=None)
def compiled(cls: type, modes: tuple[str, ...]) -> tuple:
    """The code objects of ``tick_sources(cls, modes)`` for Python (compiled once per class)."""
    return tuple(
        compile(source, f"<{cls.__name__} tick: {name}>", "exec")
        for name, source in zip(("start", "laws", "steps"), tick_sources(cls, modes))
    )
