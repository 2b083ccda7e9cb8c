"""The drive under every MAST controller, and the joint-space cascade (paper Fig. 2 and 6).

``DriveController`` is what all controllers share: the interface (pose commands and the
n axes' position and speed measurements in, the loop commands out), the drive's
multi-rate schedule of the position and velocity loops, the joint reference and the operating
modes. The drive's current loop runs inside each actuator (fmus/actuator/drive.py): the
current command ``i_cmd_k`` is its input. The outer
law is the subclass's: ``ControllerBlock`` here (the paper's joint-space cascade),
``WorkspaceController`` (workspace.py), ``FeedForwardController`` (feedforward.py) and
``ComputedTorqueController`` (computed_torque.py).

The axes are the mechanism's (its topology, fmus/mechanism/topology.py): one per coordinate c, each with a
linear drive k = 1..n. The classes here control the 3PRS's (z, psi, theta); ``for_topology`` gives each for
another mechanism, with the inputs ``<c>_cmd``, ``rho_k``, ``omega_m_k`` and the outputs ``rho_cmd_k``,
``omega_cmd_k``, ``i_cmd_k`` (``interface``: the connector convention) and its state's layout for n
(tick.layout). A rotary drive is refused: the transmission i_R below is a linear guide's.

Joint-space cascade, per axis j, all loops sampled, forward-Euler integrators:

position (every T_pos = N_pos T_cur, P):
    rho_cmd_j  = IK_j(q_cmd)                            controller's own geometry (3PRS: q = z, psi, theta)
    omega_cmd_j = k_v (rho_cmd_j - rho_j) / i_R         i_R = p / (2 pi i_r)  (paper Eq. 1)
velocity (every T_vel = N_vel T_cur, PI, limit i_max):
    e = omega_cmd_j - omega_m_j
    v = k_p e + x_v + i_ff_j                            i_ff: a feed-forward current (0 here)
    i_cmd_j = sat(v, i_max)
    x_v <- x_v + k_i T_vel e      unless saturated and e pushes further into the limit
current (every T_cur, PI, limit u_max): in the actuator (fmus/actuator/drive.py)

So each PI is C(z) = K_P + K_I T / (z - 1) while it does not saturate, and the
anti-windup is conditional integration (clamping).

Timing: the block counts ticks of T_cur n = 0, 1, 2, ... from ``initialize``
(tick n belongs to t0 + n T_cur); tick n runs the position loop if n % N_pos == 0,
then the velocity loop if n % N_vel == 0, each using the command just computed by the
outer loop. The outputs are not direct feedthrough (``FEEDTHROUGH`` empty): they change in
``do_step`` only, so every host that follows FMI 2.0's calling sequence (no get after a set
without a doStep) reads the same values. ``do_step(t, h)`` with h = m T_cur runs the laws of
the tick at t from the samples set at t (``evaluate``), then those of the ticks inside the step
with the inputs held; the outputs after it are the commands of those ticks. Stepped every
T_cur with the actuators (the MAST systems' step sizes, docs/interfaces.md "Timing"), the
current command computed from the samples at t reaches the actuators' current loop at
t + T_cur, whose voltage acts one T_cur later again: the computation delays of a real drive.
``evaluate`` runs once per tick: called again at the same point it starts over from the state
before the tick's laws. For the laws that use them
(``REFERENCE_RATES``), every position tick also updates the velocity and acceleration of
the joint reference (reference.py).

The laws of a tick are stated once, as source in the generated-code subset (tick.py: the
schedule above with each controller's ``position_lines`` and ``velocity_lines``): the block
compiles it once per class and runs it on its state ``S`` (a list of floats, ``tick.LAYOUT``);
the native FMUs translate the same source to C (mast.core.native.models).

For commissioning and for tests, ``set_mode`` switches the drive's operating
mode: "pose" (default), "joint" (rho_cmd given, the IK bypassed), "velocity"
(omega_cmd given, the position loop off) or "current" (i_cmd given, position and
velocity loops off), like a drive's position/velocity/current modes.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Mapping, Optional, Sequence

from ..actuator.drive import pi_step
from ..actuator.model import transmission_ratio
from ..common.block import Block, ModelError
from ..common.parameters import ParameterError, Value, nonnegative, positive
from ..mechanism.designs import (
    KINEMATIC_PARAMETERS,
    TRACED_PARAMETERS,
    describe,
    description,
    kinematic_engine,
    parameters_for,
)
from ..mechanism.engine import Engine
from ..mechanism.kinematics import KinematicsError
from ..mechanism.topology import POSE_UNITS, Topology, TopologyError
from .reference import rates
from .tick import MODEL_FAILED, compiled, layout, pi_lines

#: operating modes, outermost first; the value is the first loop that runs
MODES = ("pose", "joint", "velocity", "current")
_MODE_COMMAND = {"joint": "rho_cmd", "velocity": "omega_cmd", "current": "i_cmd"}
_COUNTS = ("no", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten")


def count_text(n: int) -> str:
    """``n`` in words up to ten ("three"), else in digits: the messages' way of counting axes."""
    return _COUNTS[n] if 0 <= n < len(_COUNTS) else str(n)


def command_description(coordinate: str) -> str:
    """The description of the pose command input of ``coordinate`` (a component of topology.POSE)."""
    if coordinate == "z":
        return "Platform height command"
    what = "rotation" if POSE_UNITS[coordinate] == "rad" else "position"
    return f"Platform {what} command {coordinate}"


def interface(coordinates: Sequence[str]) -> dict:
    """What a controller of the axes ``coordinates`` (the mechanism's coordinate names, topology.Topology.names;
    one linear drive each) declares: its inputs (the pose command ``<c>_cmd`` per coordinate, ``rho_k``,
    ``omega_m_k``), outputs (``rho_cmd_k``, ``omega_cmd_k``, ``i_cmd_k``), their units and descriptions, the
    direct feedthrough (none), and its state's layout and size (tick.layout)."""
    n = len(coordinates)
    axes = range(1, n + 1)
    inputs = (*(f"{c}_cmd" for c in coordinates), *(f"rho_{j}" for j in axes), *(f"omega_m_{j}" for j in axes))
    outputs = (*(f"rho_cmd_{j}" for j in axes), *(f"omega_cmd_{j}" for j in axes), *(f"i_cmd_{j}" for j in axes))
    units = {
        **{f"{c}_cmd": POSE_UNITS[c] for c in coordinates},
        **{f"rho_{j}": "m" for j in axes},
        **{f"omega_m_{j}": "rad/s" for j in axes},
        **{f"rho_cmd_{j}": "m" for j in axes},
        **{f"omega_cmd_{j}": "rad/s" for j in axes},
        **{f"i_cmd_{j}": "A" for j in axes},
    }
    descriptions = {
        **{f"{c}_cmd": command_description(c) for c in coordinates},
        **{f"rho_{j}": f"Measured position of guide {j} (linear encoder)" for j in axes},
        **{f"omega_m_{j}": f"Measured speed of motor {j} (motor encoder)" for j in axes},
        **{f"rho_cmd_{j}": f"Joint position command of axis {j} (inverse kinematics)" for j in axes},
        **{f"omega_cmd_{j}": f"Motor speed command of axis {j} (position loop output)" for j in axes},
        **{f"i_cmd_{j}": f"Current command of axis {j} (velocity loop output)" for j in axes},
    }
    state = layout(n, len(TRACED_PARAMETERS))  # the tick's fields (a native FMU sizes its parameter slot itself)
    return {
        "INPUTS": inputs,
        "OUTPUTS": outputs,
        "UNITS": units,
        "DESCRIPTIONS": descriptions,
        "FEEDTHROUGH": {},  # the commands change in do_step only (module docstring: Timing)
        "LAYOUT": state,
        "SIZE": state["size"],
    }


def position_p_law(rho_cmd: float, rho: float, kv_iR: float) -> float:
    """The joint cascade's position law, one axis: omega_cmd = k_v (rho_cmd - rho) / i_R [rad/s] (``kv_iR`` =
    k_v / i_R). Written in the generated-code subset: the native FMU's tick calls this source."""
    return kv_iR * (rho_cmd - rho)


def cascade_gains(k_v: float, k_p: float, k_i: float, T_vel: float, i_R: float) -> tuple[float, float, float]:
    """The joint cascade's outer gains: (k_v / i_R [rad/(m.s)], k_p [A.s/rad], k_i T_vel [A.s/rad]).

    Written in the generated-code subset, as ``drive_gains``."""
    return (k_v / i_R, k_p, k_i * T_vel)


#: the servo drive's loops in the controller (ssp/resources/drive.ssv: the actuators take the current loop's
#: parameters from the same set) and the machine's transmission
DRIVE_PARAMETERS = (
    positive("T_pos", "s", "Position loop cycle time (integer multiple of T_cur)"),
    positive("T_vel", "s", "Velocity loop cycle time (integer multiple of T_cur)"),
    positive("T_cur", "s", "Current loop cycle time: the controller's tick (the actuators run the current loop)"),
    positive("i_max", "A", "Current command limit (symmetric)"),
    positive("i_r", "1", "Gear ratio (motor turns per output turn)"),
    positive("p", "m", "Linear guide feed per output revolution"),
    *KINEMATIC_PARAMETERS,  # the controller's own kinematic model of the machine (designs.py)
)

#: the joint-space cascade's outer gains (ssp/resources/controller_joint.ssv)
CASCADE_PARAMETERS = (
    nonnegative("k_v", "1/s", "Position P gain: linear velocity command per metre of joint error"),
    nonnegative("k_p", "A.s/rad", "Velocity PI proportional gain: current per motor speed error"),
    nonnegative("k_i", "A/rad", "Velocity PI integral gain"),
)


class DriveController(Block):
    """The shared part of every MAST controller (module docstring); subclasses give their laws as lines of the
    tick (``position_lines``, ``velocity_lines``: tick.py) and the constants they read (``_constants``)."""

    #: the axes: the coordinates of the mechanism the class controls (the 3PRS's; another mechanism's:
    #: ``for_topology``), from which ``interface`` gives INPUTS, OUTPUTS, UNITS, DESCRIPTIONS, FEEDTHROUGH (none:
    #: the commands change in ``do_step``), LAYOUT, SIZE
    COORDINATES: tuple[str, ...] = description("3PRS").coordinates
    LAYOUT: dict[str, int]
    SIZE: int
    PARAMETERS = DRIVE_PARAMETERS
    CYCLE_TIME = "T_cur"
    #: operating modes this controller offers (one without a velocity loop has no "velocity" mode)
    MODES: tuple[str, ...] = MODES
    #: whether the laws use the reference velocity and acceleration (S[rates], updated every position tick)
    REFERENCE_RATES = False
    #: whether the velocity PI adds the feed-forward current i_ff (S[i_ff], set by the position law)
    FEEDFORWARD_CURRENT = False
    #: the laws' arithmetic the tick calls (value functions in the generated-code subset)
    LAWS: tuple = ()
    #: the description whose parameters ``PARAMETERS`` holds ("3PRS": a controller takes those of the description
    #: its geometry set's ``kinematics`` names, ``designs.parameters_for``; another: ``for_parameters``' class)
    MECHANISM: str = "3PRS"

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        _declare(cls)

    @classmethod
    def _interface(cls) -> dict:
        """The class's declarations for its axes (``interface``; subclasses add theirs)."""
        return interface(cls.COORDINATES)

    @classmethod
    def for_topology(cls, topology: Topology) -> type:
        """This controller for the mechanism ``topology`` (its coordinates, one linear drive each): ``cls``
        itself for the 3PRS's, else a subclass with those axes (made once). TopologyError for a rotary drive."""
        rotary = [d.name for d in topology.drives if d.kind != "linear"]
        if rotary:
            raise TopologyError(
                f"{cls.__name__}: {topology.name}'s drive(s) {', '.join(rotary)} are rotary: the controllers' "
                "transmission i_R = p / (2 pi i_r) [m/rad] (paper Eq. 1) and their joint units [m] are a linear "
                "guide's; a rotary drive needs its own transmission"
            )
        return _specialised(cls, topology.names)

    @classmethod
    def input_starts(cls, params: Mapping[str, Value]) -> dict[str, float]:
        """The pose commands at the home pose of the mechanism ``params`` describe, the joints at its inverse
        kinematics: a host that leaves the inputs at their start values commands home (a pose of zeros may be
        no pose at all)."""
        desc = describe(params, masses=False)
        top = desc.topology
        rho = desc.evaluate(list(top.home)).rho
        return {
            **{f"{c}_cmd": v for c, v in zip(top.names, top.home)},
            **{j: float(r) for j, r in zip(top.joints, rho)},
        }

    @classmethod
    def for_parameters(cls, params: Mapping[str, Value]) -> type:
        """The class whose variables a controller of ``params`` has: ``for_topology`` of the mechanism their
        geometry set describes (an FMU fixes its variables with its built-in parameters, ``Block.for_parameters``);
        this class when they describe none (the block built with them says why)."""
        if not params:
            return cls
        try:
            topology = describe(params, masses=False).topology
        except Exception:  # noqa: BLE001 - the block's own construction reports what is wrong with them
            return cls
        return _with_parameters(cls.for_topology(topology), params.get("kinematics", "3PRS"))

    def __init__(self, params: Mapping[str, Value], name: str = "", kinematics: Optional[Engine] = None) -> None:
        """``kinematics``: the controller's kinematic model, by default the description its geometry parameter
        set selects (designs.kinematic_engine); its topology must have this class's axes (``for_topology``). The
        parameters of that description are the controller's (``MECHANISM``)."""
        if self.MECHANISM == "3PRS":
            self.PARAMETERS = parameters_for(self.PARAMETERS, params.get("kinematics", "3PRS"))
        super().__init__(params, name)
        P = self.params
        T_cur = float(P["T_cur"])
        self._N_pos = self._ratio("T_pos", float(P["T_pos"]), T_cur)
        self._N_vel = self._ratio("T_vel", float(P["T_vel"]), T_cur)
        self.T_cur = T_cur
        #: i_R = p / (2 pi i_r), metres of guide travel per motor radian (paper Eq. 1)
        self.i_R = transmission_ratio(P["p"], P["i_r"])
        #: the controller's kinematic model: the description its geometry set selects (``kinematics``),
        #: the same code as the mechanism's
        self.kinematics = kinematics if kinematics is not None else kinematic_engine(P, self.name)
        #: the mechanism's interface shape (its coordinates are this controller's axes)
        self.topology = self._checked_topology(self.kinematics.description.topology)
        self._ik = self.kinematics.ik
        self._i_max = float(P["i_max"])
        self._mode = 0
        self._override: tuple[float, ...] | None = None
        self._t0 = 0.0
        self._step_ticks = (math.nan, 0)  # (the step size do_step checked last, its ticks of T_cur)
        self._n_in = len(self.INPUTS)
        #: the state the tick runs on (``LAYOUT``), its scratch arrays, and the exception of a failed call
        n = self.n
        self._S = [0.0] * self.SIZE
        self._R, self._CUR, self._QM, self._JK = [0.0] * n, [0.0] * n, [0.0] * n, [0.0] * (n + n * n)
        self._failure: Exception | None = None
        self._bind_tick()
        self._reset()

    def _checked_topology(self, topology: Topology) -> Topology:
        """``topology``, if this class controls its coordinates (``for_topology``); else ParameterError."""
        if topology.names != self.COORDINATES:
            raise ParameterError(
                f"{self.name}: the kinematic model is a {topology.name} with coordinates {', '.join(topology.names)} "
                f"({count_text(topology.n)} drives), this {type(self).__name__} controls "
                f"{', '.join(self.COORDINATES)}: use {type(self).__name__}.for_topology(its topology)"
            )
        self.for_topology(topology)  # a rotary drive refused
        return topology

    @property
    def n(self) -> int:
        """The number of axes (drives)."""
        return len(self.COORDINATES)

    def _ratio(self, name: str, T: float, T_cur: float) -> int:
        ratio = T / T_cur
        n = round(ratio)
        if n < 1 or abs(ratio - n) > 1e-6 * n:
            raise ParameterError(
                f"{self.name}: parameter '{name}' = {T!r} s must be an integer multiple of "
                f"T_cur = {T_cur!r} s (ratio {ratio:.9g})"
            )
        return int(n)

    def _bind_tick(self) -> None:
        """The tick (tick.py), compiled once per class, its calls bound to this controller (``_calls``)."""
        namespace = self._calls()
        for code in compiled(type(self), self.MODES):
            exec(code, namespace)
        self._start, self._tick, self._steps = namespace["start"], namespace["laws"], namespace["steps"]

    def _calls(self) -> dict:
        """What the tick calls (tick.py): the laws' functions and this controller's kinematics."""
        return {"pi_step": pi_step, "rates": rates, "ik_s": self._ik_s, **{f.__name__: f for f in self.LAWS}}

    def _reset(self) -> None:
        """Tick 0, every state and command 0 (the IK cache and the reference empty), the constants in S."""
        self._n = 0
        self._evaluated = -1  # the tick whose laws ran at its communication point
        self._before: tuple = ()  # the law state before them (``_law_state``)
        S = self._S
        S[:] = [0.0] * self.SIZE
        self._constants(S)
        S[self.LAYOUT["mode"]] = float(self._mode)

    def _constants(self, S: list[float]) -> None:
        """The numbers the tick reads from S that the parameters fix (``LAYOUT``)."""
        L = self.LAYOUT
        S[L["N_pos"]], S[L["N_vel"]] = float(self._N_pos), float(self._N_vel)
        S[L["T_cur"]], S[L["T_pos"]] = self.T_cur, float(self.params["T_pos"])
        S[L["i_R"]] = self.i_R
        S[L["gains"] + 3] = self._i_max

    def set_state(self, state: object) -> None:
        super().set_state(state)
        self._bind_tick()  # the tick's calls bound to this controller, not to the snapshot's

    # -- properties -----------------------------------------------------------
    @property
    def ticks(self) -> int:
        """Number of current-loop ticks run since ``initialize``."""
        return self._n

    @property
    def ticks_per_position(self) -> int:
        return self._N_pos

    @property
    def ticks_per_velocity(self) -> int:
        return self._N_vel

    @property
    def mode(self) -> str:
        return MODES[self._mode]

    # -- operating mode (drive modes; commissioning and tests) -----------------
    def set_mode(self, mode: str, commands: Sequence[float] | None = None) -> None:
        """Choose where the cascade starts.

        ``"pose"``: normal operation, rho_cmd from the IK of the pose inputs.
        ``"joint"``: rho_cmd = ``commands`` [m] (IK bypassed).
        ``"velocity"``: omega_cmd = ``commands`` [rad/s] (position loop off).
        ``"current"``: i_cmd = ``commands`` [A] (position and velocity loops off).

        The given commands are sampled by the next loop at its next tick, as an
        outer loop's output would be. Call again to change them. Integrator
        states are kept.
        """
        if mode not in self.MODES:
            raise ValueError(f"{self.name}: unknown mode {mode!r}; modes are {', '.join(self.MODES)}")
        if mode == "pose":
            if commands is not None:
                raise ValueError(f"{self.name}: mode 'pose' takes its commands from the inputs")
            self._mode = 0
            self._override = None
            self._S[self.LAYOUT["mode"]] = 0.0
            self._S[self.LAYOUT["ik"]] = 0.0  # the IK cache forgotten
            return
        if commands is None or len(commands) != self.n:
            raise ValueError(
                f"{self.name}: mode {mode!r} needs {count_text(self.n)} {_MODE_COMMAND[mode]} values (one per axis)"
            )
        values = tuple(float(c) for c in commands)
        for j, c in enumerate(values, 1):
            if not math.isfinite(c):
                raise ModelError(f"{self.name}: {_MODE_COMMAND[mode]}_{j} = {c!r} is not finite")
        self._mode = MODES.index(mode)
        self._override = values  # type: ignore[assignment]
        self._S[self.LAYOUT["mode"]] = float(self._mode)
        self._apply_override()
        self._write_outputs()

    def _apply_override(self) -> None:
        at = self.LAYOUT[("rho_cmd", "omega_cmd", "i_cmd")[self._mode - 1]]
        self._S[at : at + self.n] = self._override

    # -- life cycle -------------------------------------------------------------
    def initialize(self, t0: float) -> None:
        """Reset the integrators and the tick counter; rho_cmd = IK(pose) at t0, other commands 0."""
        self._reset()
        self._t0 = float(t0)
        self._check_inputs(t0)
        if self._mode and self._override is not None:
            self._apply_override()
        code = self._start(self.values, self._S, self._R)
        if code:
            raise self._failed(code, t0)

    def evaluate(self) -> None:
        """The laws of the communication point's tick from the inputs as they are (module docstring): once
        per tick; called again at the same tick, from the state before its laws."""
        n = self._n
        if self._evaluated == n:
            self._set_law_state(self._before)
        else:
            self._before = self._law_state()
            self._evaluated = n
        t = self._t0 + n * self.T_cur
        s = sum(self.values[: len(self.INPUTS)])
        if s - s != 0.0:  # NaN or inf among the inputs
            self._check_inputs(t)
        self._laws(n, t)

    def do_step(self, t: float, h: float) -> None:
        T = self.T_cur
        if h != self._step_ticks[0]:  # checked once per step size
            m = round(h / T)
            if m < 1 or abs(h - m * T) > 1e-6 * T:
                raise ModelError(
                    f"{self.name}: step size h = {h!r} s is not a positive integer multiple of T_cur = {T!r} s"
                )
            self._step_ticks = (h, m)
        m = self._step_ticks[1]
        n = self._n
        if abs(t - (self._t0 + n * T)) > 0.5 * T:
            raise ModelError(
                f"{self.name}: do_step at t = {t!r} s, but tick {n} belongs to t = {self._t0 + n * T!r} s "
                "(steps must be contiguous from initialize)"
            )
        if m == 1 and self._evaluated != n and n % self._N_pos and n % self._N_vel:
            # a tick that runs no loop: its laws would change nothing (tick.py), the inputs are checked alone
            s = sum(self.values[: self._n_in])
            if s - s != 0.0:
                self._check_inputs(t)
            self._n = n + 1
            return
        if self._evaluated != n:  # no input set at this communication point: the inputs held
            self.evaluate()
        S = self._S
        code = self._steps(self.values, S, self._R, self._CUR, self._QM, self._JK, n, m)  # the ticks inside
        if code:
            raise self._failed(code, self._t0 + S[self.LAYOUT["failed"]] * T)
        self._n = n + m
        self._before = ()

    def _laws(self, n: int, t: float) -> None:
        """Tick n (at t): the tick's laws (tick.py: the position loop if n % N_pos == 0, then the velocity loop
        if n % N_vel == 0), the outputs too."""
        code = self._tick(self.values, self._S, self._R, self._CUR, self._QM, self._JK, n)
        if code:
            raise self._failed(code, t)

    def _law_state(self) -> tuple:
        """What the laws change, copied (``evaluate`` starts a tick over from it); subclasses add theirs."""
        return (self._S[:],)

    def _set_law_state(self, state: tuple) -> None:
        self._S[:] = state[0]
        self._S[self.LAYOUT["mode"]] = float(self._mode)

    # -- the laws (subclasses): lines of the tick (tick.py), the commands rc_j, oc_j, ic_j as locals ----------
    @classmethod
    def position_lines(cls, moded: bool) -> list[str]:
        """At a position tick, with rho_cmd (rc_j) and the reference's rates up to date: set omega_cmd (oc_j)
        and i_ff (if_j); ``moded``: the tick has operating modes (its local ``mode``)."""
        raise NotImplementedError

    @classmethod
    def velocity_lines(cls) -> list[str]:
        """At a velocity tick (or in velocity mode): set i_cmd (ic_j)."""
        raise NotImplementedError

    # -- what the tick calls, and the messages of its failures -------------------------
    def _ik_s(self, S: list[float], *q_out) -> int:
        """``ik_s(S, q_1, ..., q_n, out)``: the inverse kinematics of the pose command q into ``out``; 1 if it
        fails (``_failure``)."""
        try:
            rho = self._ik(q_out[:-1])
        except KinematicsError as exc:
            self._failure = exc
            return 1
        out = q_out[-1]
        for j, r in enumerate(rho):
            out[j] = float(r)
        return 0

    def _currents(self, *args) -> int:
        """``currents(rho_1..n, rho_dot_1..n, rho_ddot_1..n, S, out)``: the inverse model's currents (``model``:
        the feed-forward and computed-torque controllers) into ``out``; 1 if it fails (``_failure``)."""
        n, a, out = self.n, args[:-2], args[-1]
        try:
            out[:] = self.model.currents(a[:n], a[n : 2 * n], a[2 * n :])
        except KinematicsError as exc:
            self._failure = exc
            return 1
        return 0

    def _failed(self, code: int, t: float) -> Exception:
        """The exception of the tick's failure ``code`` at t [s]."""
        exc = self._failure
        if code == MODEL_FAILED:
            return exc
        pose = ", ".join(f"{c} = {v!r} {POSE_UNITS[c]}" for c, v in zip(self.COORDINATES, self.values))
        error = KinematicsError(
            f"{self.name}: inverse kinematics of the pose command {pose} failed at t = {t!r} s: {exc}"
        )
        error.__cause__ = exc
        return error

    # -- helpers ------------------------------------------------------------------
    def _write_outputs(self) -> None:
        n, at = self.n, self.LAYOUT["rho_cmd"]
        self.values[3 * n : 6 * n] = self._S[at : at + 3 * n]

    def _check_inputs(self, t: float) -> None:
        for name, value in zip(self.INPUTS, self.values):
            if not math.isfinite(value):
                raise ModelError(f"{self.name}: input '{name}' = {value!r} is not finite at t = {t!r} s")


def _declare(cls: type) -> None:
    """Set the declarations of ``cls``'s axes (``_interface``): on DriveController here, on its subclasses as they
    are made (``__init_subclass__``); what a class states in its own body stays (e.g. FEEDTHROUGH = {})."""
    for key, value in cls._interface().items():
        if key not in vars(cls):
            setattr(cls, key, value)


_declare(DriveController)


@lru_cache(maxsize=None)
def _specialised(cls: type, coordinates: tuple[str, ...]) -> type:
    """``cls`` for the axes ``coordinates`` (``DriveController.for_topology``): itself if they are its own, else
    its subclass with them (its declarations by ``__init_subclass__``), made once per class and axes."""
    if coordinates == cls.COORDINATES:
        return cls
    return type(
        cls.__name__,
        (cls,),
        {
            "COORDINATES": coordinates,
            "__module__": cls.__module__,
            "__qualname__": f"{cls.__qualname__}[{', '.join(coordinates)}]",
            "__doc__": cls.__doc__,
        },
    )


@lru_cache(maxsize=None)
def _with_parameters(cls: type, kind: str) -> type:
    """``cls`` with the parameters of the description ``kind`` in place of the 3PRS's (``parameters_for``; what an
    FMU registers): itself for the 3PRS's, else its subclass of the same name, made once per class and kind."""
    parameters = parameters_for(cls.PARAMETERS, kind) if cls.MECHANISM == "3PRS" else cls.PARAMETERS
    if parameters == cls.PARAMETERS:
        return cls
    return type(
        cls.__name__,
        (cls,),
        {
            "PARAMETERS": parameters,
            "MECHANISM": kind,
            "__module__": cls.__module__,
            "__qualname__": f"{cls.__qualname__}[{kind}]",
            "__doc__": cls.__doc__,
        },
    )


class ControllerBlock(DriveController):
    """Joint-space P/PI/PI cascade of the n axes (paper Fig. 2 and 6), with its own inverse kinematics."""

    PARAMETERS = (*CASCADE_PARAMETERS, *DRIVE_PARAMETERS)
    LAWS = (position_p_law,)

    def _constants(self, S: list[float]) -> None:
        super()._constants(S)
        P, at = self.params, self.LAYOUT["gains"]
        S[at : at + 3] = cascade_gains(float(P["k_v"]), float(P["k_p"]), float(P["k_i"]), float(P["T_vel"]), self.i_R)

    @classmethod
    def position_lines(cls, moded: bool) -> list[str]:
        """omega_cmd = k_v (rho_cmd - rho) / i_R."""
        n = len(cls.COORDINATES)
        return [f"oc{j} = position_p_law(rc{j}, values[{n + j}], S[{cls.LAYOUT['gains']}])" for j in range(n)]

    @classmethod
    def velocity_lines(cls) -> list[str]:
        """i_cmd = PI(omega_cmd - omega_m) + i_ff, limited to i_max."""
        n = len(cls.COORDINATES)
        return pi_lines(cls.LAYOUT, n, [f"if{j}" for j in range(n)] if cls.FEEDFORWARD_CURRENT else ["0.0"] * n)
