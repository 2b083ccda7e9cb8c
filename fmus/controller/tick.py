"""The controllers' tick, stated once: the source the Python controllers run and the native FMUs compile.

``tick_sources(cls, modes)`` writes a controller's ``start`` (``initialize``, after the reset), ``laws``
(the laws of tick n: ``DriveController``'s schedule, model.py) and ``steps`` (the ticks inside a step of m
ticks from tick n, the inputs held: those that run a loop) in the generated-code subset
(mast.core.native.translate: float arithmetic, ``if``, indexing, calls): which loop runs at which tick, the
pose command's inverse kinematics cached by pose, the joint reference's samples and rates (``REFERENCE_RATES``),
then the controller's own laws, which each controller class states as lines of the same subset
(``position_lines``, ``velocity_lines``). The Python controllers compile it once per class (``compiled``) and
run it on their state ``S``, a list of floats laid out as ``LAYOUT``; the native generator
(mast.core.native.models) translates the same source to C, on the same layout. What the tick calls:

- ``a, b = pi_step(...)``, ``rd, rdd = rates(...)``: functions that return a tuple (their own source, translated);
- ``c = ik_s(S, z, psi, theta, R)`` (the inverse kinematics of the pose command, into R),
  ``c = currents(rho, rho_dot, rho_ddot (nine numbers), S, CUR)`` (the inverse model's currents),
  ``c = wsdk(rho (three numbers), S, QM)`` (the workspace controller's direct kinematics of the measured joints),
  ``c = ikjac_s(S, q0, q1, q2, JK)`` (drho/dq at q in JK[3:12]): 0, or a failure (the caller makes the
  message); in Python the controller's own methods, in C the traced engine's functions;
- the laws' arithmetic as value functions (``position_p_law``, ``pi_step``, ...: each controller's ``LAWS``).

A failed call ends the tick: it records the tick in ``S[failed]`` (and the arguments of a failed inverse model or
direct kinematics in ``S[model_args]``) and returns the call's code, ``MODEL_FAILED`` or ``DK_FAILED``.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Sequence

__all__ = ["LAYOUT", "SIZE", "DK_FAILED", "MODEL_FAILED", "TARGET_FAILED", "tick_sources", "compiled"]

#: layout of a controller's state S (doubles): tick count, t0, IK cache (valid, pose), the velocity PI's states,
#: commands ("failed": the tick whose call failed, for the message), then the gains computed at initialisation
#: from the parameters (``gains``: cascade_gains, then i_max); the operating mode (``MODES``' index: Python's
#: ``set_mode``); 9..14, 30 and 31 free
LAYOUT = {"n": 0, "t0": 1, "ik": 2, "pose": 3, "x_v": 6, "rho_cmd": 15, "omega_cmd": 18, "i_cmd": 21,
          "failed": 24, "gains": 25, "mode": 29,
          # the joint reference's last four samples (newest first) and their count, i_ff, the
          # inverse model's direct-kinematics guess (valid flag, pose) and the arguments of a failed evaluation
          "hist": 32, "k": 44, "i_ff": 45, "warm": 48, "guess": 49, "model_args": 52,
          # the reference's rates (rho_dot_ref, rho_ddot_ref), kept between ticks
          "rates": 61,
          # the controller's own gains computed at initialisation (feedforward_gains, error_gains, pose_gains)
          "own": 67,
          # from the parameters at initialisation: the schedule (T_pos / T_cur, T_vel / T_cur, T_cur, T_pos), the
          # transmission i_R, cos and sin of beta (the cold start), attached (the inverse model's) and the kinematic
          # model's traced parameters (designs.TRACED_PARAMETERS: the arguments of its generated functions),
          # then the inverse model's actuator constants (inverse_model.CONSTANTS, by its model_constants)
          "N_pos": 70, "N_vel": 71, "T_cur": 72, "T_pos": 73, "i_R": 74, "cb": 75, "sb": 76, "attached": 77, "P": 78,
          "model": 102}
#: the state's size (the native FMUs keep the coordinate lengths in the last three)
SIZE = 114
#: a failure of the inverse model (its direct kinematics or dynamics)
MODEL_FAILED = 1000
#: a failure of the workspace controller's direct kinematics of the measured joints
DK_FAILED = 2000
#: a failure of the workspace controller's direct kinematics of the joint command ("joint" mode)
TARGET_FAILED = 3000

_COMMANDS = {k: [f"{p}{j}" for j in range(3)] for k, p in (("x_v", "xv"), ("rho_cmd", "rc"), ("omega_cmd", "oc"),
                                                           ("i_cmd", "ic"))}


def _indented(lines: Sequence[str], indent: str) -> list[str]:
    return [indent + line for line in lines]


def _ik_lines() -> list[str]:
    """DriveController's inverse kinematics of the pose command, cached by pose (the pose of the last one)."""
    S, P = LAYOUT, LAYOUT["pose"]
    return [f"if not (S[{S['ik']}] == 1.0 and values[0] == S[{P}] and values[1] == S[{P + 1}] "
            f"and values[2] == S[{P + 2}]):",
            "    c = ik_s(S, values[0], values[1], values[2], R)",
            "    if c != 0:",
            f"        S[{S['failed']}] = n",
            "        return c",
            "    rc0 = R[0]", "    rc1 = R[1]", "    rc2 = R[2]",
            f"    S[{S['ik']}:{S['ik'] + 4}] = (1.0, values[0], values[1], values[2])"]


def _reference_lines() -> list[str]:
    """The joint reference at a position tick (after the IK): the new sample rho_cmd, newest first, then the
    rates of the last (at most four) samples, ``reference.rates``, kept in S[rates]."""
    H, K, Q, T = LAYOUT["hist"], LAYOUT["k"], LAYOUT["rates"], LAYOUT["T_pos"]
    old = ", ".join(f"S[{H + k}]" for k in range(9))
    lines = [f"S[{H + 3}:{H + 12}] = ({old})", f"S[{H}:{H + 3}] = (rc0, rc1, rc2)",
             f"k = S[{K}] + 1.0", "if k > 4.0:", "    k = 4.0", f"S[{K}] = k"]
    for j in range(3):
        lines += [f"rd{j}, rdd{j} = rates(k, rc{j}, S[{H + 3 + j}], S[{H + 6 + j}], S[{H + 9 + j}], S[{T}])",
                  f"S[{Q + j}] = rd{j}", f"S[{Q + 3 + j}] = rdd{j}"]
    return lines


def failed_call(call: str, args: str, code: int) -> list[str]:
    """``c = call`` whose failure ends the tick with ``code``, the arguments ``args`` kept for the message."""
    S = LAYOUT
    n_args = args.count(",") + 1
    return [f"c = {call}", "if c != 0:", f"    S[{S['failed']}] = n",
            f"    S[{S['model_args']}:{S['model_args'] + n_args}] = ({args})", f"    return {code}"]


def pi_lines(offset: Sequence[str]) -> list[str]:
    """The velocity PI of the three axes (``pi_step``) with the offsets (feed-forward currents) ``offset``."""
    kp, kiT, i_max = (f"S[{LAYOUT['gains'] + k}]" for k in (1, 2, 3))
    return [f"ic{j}, xv{j} = pi_step(oc{j} - values[{6 + j}], xv{j}, {kp}, {kiT}, {i_max}, {offset[j]})"
            for j in range(3)]


def tick_sources(cls: type, modes: Sequence[str] = ("pose",)) -> tuple[str, str, str]:
    """``(start, laws, steps)`` of the controller class ``cls`` (module docstring) for its operating ``modes``:
    with "pose" alone (the native FMUs: the modes are no FMU variables) the tick has no mode test."""
    S, ff = LAYOUT, cls.FEEDFORWARD_CURRENT
    moded = tuple(modes) != ("pose",)
    unpack = [f"{v} = S[{S[k] + j}]" for k, vs in _COMMANDS.items() for j, v in enumerate(vs)]
    unpack += [f"if{j} = S[{S['i_ff'] + j}]" for j in range(3)] if ff else []
    commands = ", ".join(_COMMANDS["rho_cmd"] + _COMMANDS["omega_cmd"] + _COMMANDS["i_cmd"])
    store = [f"S[{S['x_v']}:{S['x_v'] + 3}] = ({', '.join(_COMMANDS['x_v'])})",
             f"S[{S['rho_cmd']}:{S['rho_cmd'] + 9}] = ({commands})",
             *([f"S[{S['i_ff']}:{S['i_ff'] + 3}] = (if0, if1, if2)"] if ff else []),
             f"values[9:] = ({commands})",
             "return 0"]
    ik = _ik_lines()
    if moded:
        ik = [f"if S[{S['mode']}] == 0.0:", *_indented(ik, "    ")]
    start = ["def start(values, S, R):", *_indented(["n = 0.0", *unpack, *ik, *store], "    ")]
    position = [*ik, *(_reference_lines() if cls.REFERENCE_RATES else []), *cls.position_lines(moded)]
    velocity = cls.velocity_lines()
    if moded:
        body = [f"mode = S[{S['mode']}]",
                f"if mode <= 1.0 and n % S[{S['N_pos']}] == 0.0:", *_indented(position, "    "),
                f"if mode <= 2.0 and n % S[{S['N_vel']}] == 0.0:", *_indented(velocity, "    ")]
    else:
        body = [f"if n % S[{S['N_pos']}] == 0.0:", *_indented(position, "    "),
                f"if n % S[{S['N_vel']}] == 0.0:", *_indented(velocity, "    ")]
    laws = ["def laws(values, S, R, CUR, QM, JK, n):", *_indented([*unpack, *body, *store], "    ")]
    steps = ["def steps(values, S, R, CUR, QM, JK, n, m):",
             "    k = n + 1", "    inner = m - 1",
             "    for _ in range(inner):",
             f"        if k % S[{S['N_pos']}] == 0.0 or k % S[{S['N_vel']}] == 0.0:",
             "            c = laws(values, S, R, CUR, QM, JK, k)",
             "            if c != 0:", "                return c",
             "        k += 1",
             "    return 0"]
    return tuple("\n".join(lines) + "\n" for lines in (start, laws, steps))


@lru_cache(maxsize=None)
def compiled(cls: type, modes: tuple[str, ...]) -> tuple:
    """The code objects of ``tick_sources(cls, modes)`` for Python (compiled once per class)."""
    return tuple(compile(source, f"<{cls.__name__} tick: {name}>", "exec")
                 for name, source in zip(("start", "laws", "steps"), tick_sources(cls, modes)))
