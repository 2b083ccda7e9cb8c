"""Mechanism block: direct kinematics + inverse dynamics (paper sections 2.1, 3.3).

An algebraic block: from the slider motion (rho, rho_dot, rho_ddot) held over the step
it computes the platform pose (direct kinematics, Newton warm-started from the previous
pose, on its assembly branch and at least ``engine.MARGIN`` from a singularity: a step that
would cross or approach one stops with an error naming the pose, never a silent jump;
docs/mechanism.md) and the forces F_i = t_rho_i each actuator applies to the mechanism along its
guide, positive upward (inverse dynamics). The actuators feel -F_i: the mechanism is
their disturbance (paper section 2).

Update period ``T_mech`` [s] (a parameter of the block in a system, ssp/resources/attached.ssv): a host
steps the block with the drive's fast cycle (T_cur), and the block splits its work by what changes fast. At
t0 + k T_mech it samples all its inputs and makes the full update (direct kinematics, the pose, the joint-space
mass matrix M_k and bias b_k = Coriolis/centrifugal + gravity at q_k and rho_dot_k: ``Engine.inertial``); at
every step it returns the inertial reaction of the accelerations set now, F = M_k rho_ddot + b_k (the stiff,
algebraic part of the coupling with the actuators), the pose held. Between updates q moves by rho_dot T_mech and
M, b follow it slowly; the accelerations change at the current loop's rate. T_mech = 0 (a set that does not
name it): the full update at every step, the algebraic block itself.

The mechanism is the one its parameters describe (``designs.py``: the geometry set with its
``kinematics`` model, the bodies, an optional payload), computed by the generic engine
(``engine.py``). With ``attached = 0`` (actuators alone, paper Fig. 10) the block exerts no
force and reports the kinematics of the mechanism as if it were massless.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Callable, ClassVar, Mapping, Sequence

from ..common.block import Block, ModelError
from ..common.codegen import compile_generated
from ..common.fixed_order import eig_max
from ..common.parameters import Param, ParameterError, Value
from .coupling import EXTRAPOLATION, condense
from .designs import (
    KINEMATIC_PARAMETERS,
    MASS_PARAMETERS,
    PAYLOAD_PARAMETERS,
    describe,
    description,
    engine,
    parameters_for,
)
from .engine import SingularityError
from .kinematics import KinematicsError
from .topology import DRIVE_UNITS, POSE, POSE_UNITS, Topology

#: the block's update period (module docstring); a set without it updates at every step (T_mech = 0)
UPDATE_PERIOD = Param(
    "T_mech",
    "s",
    "Update period of the block: kinematics, pose, mass matrix and bias recomputed at t0 + k T_mech; between, "
    "the forces F = M rho_ddot + b from the accelerations of every step (0: the full update at every step)",
    minimum=0.0,
    maximum=1.0,
)

#: the mechanism condenses (docs/coupling.md) once its joint-space mass reaches this share of the drives' load-side
#: masses (the largest eigenvalue of m^-1/2 M m^-1/2, from then on for the run): below it the explicit exchange is
#: stable (on the MAST to about 0.9) and damps the drives' transmission modes as a lighter mechanism does
CONDENSE_ABOVE = 0.5

#: the code of a direct kinematics refused at (or near) a singularity (mast_model.h: MAST_SINGULARITY_ERROR)
SINGULAR = 4


def dk(rho, warm: float, S, out) -> int:
    """One attempt of the direct kinematics of the joint positions ``rho`` (rho_1..n, in the drives' units: m or
    rad) by ``S`` (a MechanismBlock or an InverseModel: its ``engine``), from its last solution ``S._guess`` when
    ``warm`` (1.0), else from the description's guess: 0 (the solution in ``S._found``: q, dq/drho and what
    ``Engine.forces_kept`` reuses of the pose, ``Engine.dk_kept``), SINGULAR or 1 (the exception in
    ``S._failure``). ``restarted_dk`` calls it; the native models' C has its own (``mast_dk3``)."""
    try:
        q, J, _, kept = S.engine.dk_kept(rho, S._guess if warm == 1.0 else None)
    except SingularityError as exc:
        S._failure = exc
        return SINGULAR
    except KinematicsError as exc:
        S._failure = exc
        return 1
    S._found = (q, J, kept)
    return 0


def restarted_dk(rho, warm: float, S, out) -> int:
    """The direct kinematics of the joint positions ``rho`` (an array of n; ``dk``, its solution in ``out``), from
    the last solution when ``warm`` (1.0), else from the description's guess; a warm start that fails starts again
    from the guess, but never after a singularity (a cold start could jump to another pose). 0, or the last
    attempt's code. Written in the generated-code subset: the native mechanism and controllers run this source."""
    c = dk(rho, warm, S, out)
    if c != 0 and c != SINGULAR and warm == 1.0:
        c = dk(rho, 0.0, S, out)
    return c


@functools.cache
def reaction(n: int) -> Callable[..., bool]:
    """The inertial reaction of n drives in straight-line Python (``MechanismBlock.inertial_forces``):
    ``reaction(values, M, b, checked=False)`` writes F_a = b_a + M_a1 rho_ddot_1 + ... + M_an rho_ddot_n (summed in
    this order) into the block's ``values`` (the inputs, ``Variables``, then F: n each), M row-major; it returns
    False and writes nothing when the accelerations' sum is not finite (a NaN or inf among them), unless
    ``checked``."""
    r = [f"r{c}" for c in range(n)]
    rows = ", ".join(" + ".join([f"b[{a}]", *(f"M[{a * n + c}]*r{c}" for c in range(n))]) for a in range(n))
    source = (
        "def reaction(values, M, b, checked=False):\n"
        f"    {', '.join(r)}, = values[{2 * n}:{3 * n}]\n"
        f"    s = {' + '.join(r)}\n"
        "    if s - s != 0.0 and not checked:\n"
        "        return False\n"
        f"    values[{INPUT_KINDS * n}:{(INPUT_KINDS + 1) * n}] = ({rows},)\n"
        "    return True\n"
    )
    return compile_generated(source, "reaction", f"mechanism: inertial reaction of {n} drives", {})


#: per drive kind: the units of its velocity, acceleration, force (torque), its rates and its mass (inertia)
_KIND_UNITS = {
    "linear": ("m/s", "m/s2", "N", "N/s", "N/s2", "kg"),
    "rotary": ("rad/s", "rad/s2", "N.m", "N.m/s", "N.m/s2", "kg.m2"),
}

#: the mechanism's inputs per drive, in order (``Variables``): its motion, then its drive's force, the force's two
#: derivatives and its load-side mass (the condensed interface, fmus/mechanism/coupling.py)
INPUT_NAMES = ("rho", "rho_dot", "rho_ddot", "F_drive", "F_drive_dot", "F_drive_ddot", "m_drive")
INPUT_KINDS = len(INPUT_NAMES)

#: what each pose output is (the parasitic ones, those not among the coordinates, say so)
_POSE_DESCRIPTIONS = {
    "x": "Platform centre P, x",
    "y": "Platform centre P, y",
    "z": "Platform centre P, height above the base plane",
    "psi": "Platform roll about x (R = Rz(phi) Ry(theta) Rx(psi))",
    "theta": "Platform pitch about y",
    "phi": "Platform yaw about z",
}


@dataclass(frozen=True)
class Variables:
    """The mechanism block's variables for a topology (docs/interfaces.md, the connector convention): inputs
    ``rho_k``, ``rho_dot_k``, ``rho_ddot_k`` and the drive's ``F_drive_k``, ``F_drive_dot_k``, ``F_drive_ddot_k``,
    ``m_drive_k`` for k = 1..n, outputs ``F_k``, the six pose components, then the condensed interface ``Fc_k``,
    ``Mc_k`` (docs/coupling.md), with their units (a linear drive's m, m/s, m/s2, N, N/s, N/s2, kg; a rotary
    drive's rad, rad/s, rad/s2, N.m, N.m/s, N.m/s2, kg.m2) and descriptions."""

    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    units: Mapping[str, str]
    descriptions: Mapping[str, str]

    @classmethod
    def of(cls, coordinates: Sequence[str], kinds: Sequence[str]) -> "Variables":
        """The variables of a mechanism with the independent ``coordinates`` (pose components) and drives of
        ``kinds`` ("linear" or "rotary", in order): ``Topology.names`` and the drives' kinds."""
        ks = range(1, len(kinds) + 1)
        inputs = tuple(f"{name}_{k}" for name in INPUT_NAMES for k in ks)
        outputs = (*(f"F_{k}" for k in ks), *POSE, *(f"Fc_{k}" for k in ks), *(f"Mc_{k}" for k in ks))
        units, text = {}, {}
        for k, kind in zip(ks, kinds):
            rate, acceleration, force, force_rate, force_acceleration, mass = _KIND_UNITS[kind]
            units.update(
                {
                    f"rho_{k}": DRIVE_UNITS[kind],
                    f"rho_dot_{k}": rate,
                    f"rho_ddot_{k}": acceleration,
                    f"F_{k}": force,
                    f"F_drive_{k}": force,
                    f"F_drive_dot_{k}": force_rate,
                    f"F_drive_ddot_{k}": force_acceleration,
                    f"m_drive_{k}": mass,
                    f"Fc_{k}": force,
                    f"Mc_{k}": mass,
                }
            )
            text.update(
                {
                    f"F_drive_{k}": f"Force of drive {k} on its load side: all but the load side's inertia and the "
                    f"mechanism (the actuator's F_drive)",
                    f"F_drive_dot_{k}": f"Time derivative of F_drive_{k}",
                    f"F_drive_ddot_{k}": f"Second time derivative of F_drive_{k}",
                    f"m_drive_{k}": f"Load-side mass of drive {k}, which F_drive_{k} accelerates (0: not connected, "
                    f"no condensation)",
                    f"Fc_{k}": f"Force to apply to drive {k} beyond Mc_{k} times its own acceleration: the mechanism "
                    f"condensed on the other drives, their forces extrapolated 1.5 steps (docs/coupling.md)",
                    f"Mc_{k}": f"Mass of the mechanism and the other drives that drive {k} carries on its load side",
                }
            )
            if kind == "linear":
                text.update(
                    {
                        f"rho_{k}": f"Position of slider {k} along its guide from the base plane (vertical guides: "
                        f"its height)",
                        f"rho_dot_{k}": f"Velocity of slider {k} along its guide (up positive)",
                        f"rho_ddot_{k}": f"Acceleration of slider {k} along its guide (up positive)",
                        f"F_{k}": f"Force actuator {k} applies to the mechanism along its guide, positive upward "
                        f"(inverse dynamics t_rho_{k})",
                    }
                )
            else:
                text.update(
                    {
                        f"rho_{k}": f"Angle of the driven joint {k}",
                        f"rho_dot_{k}": f"Angular velocity of the driven joint {k}",
                        f"rho_ddot_{k}": f"Angular acceleration of the driven joint {k}",
                        f"F_{k}": f"Torque actuator {k} applies to the mechanism about its joint, positive along "
                        f"rho_{k} (inverse dynamics t_rho_{k})",
                    }
                )
        units.update(POSE_UNITS)
        text.update({p: _POSE_DESCRIPTIONS[p] + ("" if p in coordinates else " (parasitic)") for p in POSE})
        return cls(inputs, outputs, units, text)

    def required(self) -> "Variables":
        """The variables a mechanism must have to plug in (docs/interfaces.md): the joint motion in, F_k and the
        pose out; the condensed interface (F_drive_k ... m_drive_k in, Fc_k and Mc_k out) is optional."""
        n = len(self.inputs) // INPUT_KINDS
        inputs, outputs = self.inputs[: 3 * n], self.outputs[: n + 6]
        keep = set(inputs) | set(outputs)
        return Variables(
            inputs,
            outputs,
            {k: v for k, v in self.units.items() if k in keep},
            {k: v for k, v in self.descriptions.items() if k in keep},
        )

    @classmethod
    def of_topology(cls, topology: Topology) -> "Variables":
        return cls.of(topology.names, [d.kind for d in topology.drives])


#: the variables of the class ``MechanismBlock``: the 3PRS's (z, psi, theta; three linear drives), from its file
_PRS3 = Variables.of_topology(description("3PRS").describe().topology)


class MechanismBlock(Block):
    """A parallel mechanism (the one its parameters describe): DK and IDP; outputs the actuator forces and the
    platform pose.

    Its variables follow the topology of its description (``Variables``, ``Topology``): n drives give 3 n
    inputs and n + 6 outputs. Its parameters are its description file's (``designs.parameters_for``: name,
    unit, source, range), with ``kinematics`` and ``attached``. The class's own are the 3PRS's; a block of
    another mechanism has its own (instance attributes), and a class made for one topology and schema
    (``for_topology``: an FMU's, whose variables are fixed when it is built) refuses parameters of another.
    """

    INPUTS = _PRS3.inputs
    OUTPUTS = _PRS3.outputs
    PARAMETERS = (*KINEMATIC_PARAMETERS, *MASS_PARAMETERS, *PAYLOAD_PARAMETERS, UPDATE_PERIOD)
    UNITS = _PRS3.units
    DESCRIPTIONS = _PRS3.descriptions
    #: True for a class whose variables are fixed to one topology (``for_topology``)
    fixed: ClassVar[bool] = False
    #: the description whose parameters ``PARAMETERS`` holds ("3PRS": a block takes those of the description its
    #: ``kinematics`` names, ``parameters_for``)
    MECHANISM: ClassVar[str] = "3PRS"
    _classes: ClassVar[dict] = {}

    @classmethod
    def for_topology(cls, topology: Topology, kind: str = "3PRS") -> type["MechanismBlock"]:
        """The block class with the variables of ``topology`` and the parameters of the description ``kind``
        (``parameters_for``; one class per set of variables and parameters)."""
        io = Variables.of_topology(topology)
        parameters = parameters_for(MechanismBlock.PARAMETERS, kind)
        key = (io.inputs, tuple(io.units.items()), parameters)
        found = cls._classes.get(key)
        if found is None:
            found = cls._classes[key] = type(
                f"MechanismBlock{topology.n}",
                (MechanismBlock,),
                {
                    "__doc__": f"{cls.__doc__.strip().splitlines()[0]} Variables of {topology.name}: drives "
                    f"{', '.join(topology.joints)}, coordinates {', '.join(topology.names)}.",
                    "__module__": __name__,
                    "INPUTS": io.inputs,
                    "OUTPUTS": io.outputs,
                    "UNITS": io.units,
                    "DESCRIPTIONS": io.descriptions,
                    "fixed": True,
                    "PARAMETERS": parameters,
                    "MECHANISM": kind if parameters != MechanismBlock.PARAMETERS else "3PRS",
                },
            )
        return found

    @classmethod
    def for_parameters(cls, params: Mapping[str, Value]) -> type["MechanismBlock"]:
        """The class whose variables and parameters a block of ``params`` has (``for_topology`` of their
        description); this class when they describe no mechanism (the block built with them says why)."""
        if not params:
            return cls
        try:
            return cls.for_topology(describe(params, masses=False).topology, params.get("kinematics", "3PRS"))
        except Exception:  # noqa: BLE001 - the block's own construction reports what is wrong with them
            return cls

    @classmethod
    def input_starts(cls, params: Mapping[str, Value]) -> dict[str, float]:
        """The joints at the home pose (``Topology.home``'s inverse kinematics): a host that leaves the joint
        inputs at their start values finds the mechanism at home (a joint coordinate of 0 may be no pose at
        all, a leg of zero length)."""
        desc = describe(params, masses=False)
        top = desc.topology
        return dict(zip(top.joints, (float(v) for v in desc.evaluate(list(top.home)).rho)))

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        if self.MECHANISM == "3PRS":  # the parameters of the description the set names (``parameters_for``)
            kind = params.get("kinematics", "3PRS")
            self.PARAMETERS = parameters_for(self.PARAMETERS, kind)
            foreign = sorted(set(params) - {p.name for p in self.PARAMETERS})
            if kind != "3PRS" and foreign:
                raise ParameterError(
                    f"{name or type(self).__name__}: unknown parameter(s) {', '.join(foreign)}; expected names: "
                    f"{', '.join(sorted(p.name for p in self.PARAMETERS))} (those of the mechanism parameter "
                    f"'kinematics' = {kind!r} names: a set of another mechanism's parameters?)"
                )
        super().__init__({UPDATE_PERIOD.name: 0.0, **params}, name)
        self.engine = engine(self.params, self.name)
        self.topology = self.engine.description.topology
        io = Variables.of_topology(self.topology)
        if io.inputs != self.INPUTS or dict(io.units) != dict(self.UNITS):
            if self.fixed:
                raise ParameterError(
                    f"{self.name}: the parameters describe {self.topology.name} (drives "
                    f"{', '.join(f'{d.name} {d.kind}' for d in self.topology.drives)}; coordinates "
                    f"{', '.join(self.topology.names)}), whose variables are not this FMU's "
                    f"({', '.join(self.INPUTS)}): a mechanism of another topology needs its own FMU"
                )
            self.INPUTS, self.OUTPUTS, self.UNITS, self.DESCRIPTIONS = io.inputs, io.outputs, io.units, io.descriptions
            self.values = [0.0] * (len(self.INPUTS) + len(self.OUTPUTS))
        self.n = self.topology.n
        self.attached = bool(self.params["attached"])
        self._guess = None
        self._found = self._failure = None  # the last direct kinematics' solution, or failure (``dk``)
        self._t0 = 0.0  # update instants t0 + k T_mech (module docstring)
        self._T_mech = float(self.params[UPDATE_PERIOD.name])
        self._M: tuple[float, ...] = ()  # M_k (row-major) and b_k of the last full update (``inertial_forces``)
        self._b: tuple[float, ...] = ()
        self._W: list[float] | None = None  # the condensed interface of the last full update (``_condense``)
        self._latched = False  # the mass ratio reached CONDENSE_ABOVE in this run
        self._D: list[float] = [0.0] * self.n
        self._reaction = reaction(self.n)

    # -------------------------------------------------------------------------------------
    def _compute(self, t: float, h: float) -> None:
        """The full update at ``t`` (module docstring), the drives' forces extrapolated over the step ``h`` [s]."""
        vals = self.values
        n = self.n
        for k in range(INPUT_KINDS * n):
            v = vals[k]
            if not math.isfinite(v):
                raise ModelError(f"{self.name}: input '{self.INPUTS[k]}' = {v!r} is not finite at t = {t!r} s")
        for k in range((INPUT_KINDS - 1) * n, INPUT_KINDS * n):
            if vals[k] < 0.0:
                raise ModelError(
                    f"{self.name}: input '{self.INPUTS[k]}' = {vals[k]!r} at t = {t!r} s: expected a load-side "
                    f"mass >= 0 (0: not connected)"
                )
        rho = tuple(vals[:n])
        eng = self.engine
        try:
            if restarted_dk(rho, 0.0 if self._guess is None else 1.0, self, None):
                raise self._failure
            q, J, kept = self._found
            if self.attached:  # the forces reuse the pose's geometry the direct kinematics computed at q
                out = eng.forces_kept(kept, q, J, vals[n : 2 * n], vals[2 * n : 3 * n])
                self._M, self._b = out[n + 6 : n + 6 + n * n], out[n + 6 + n * n :]
                out = out[: n + 6]
            else:
                out = (0.0,) * n + eng.pose(q)
        except KinematicsError as exc:
            raise type(exc)(
                f"{self.name}: at t = {t!r} s, rho = {rho!r} {self._rho_unit}: {exc}"
            ) from exc  # SingularityError stays one
        except OverflowError as exc:  # the equations built for these parameters (engine.overflow_hint)
            raise ParameterError(f"{self.name}: {exc}") from None
        self._guess = q
        vals[INPUT_KINDS * n : (INPUT_KINDS + 1) * n + 6] = out
        self._condense()
        self._tell(h)

    def _condense(self) -> None:
        """The condensed interface of the last full update's M to the drives' load-side masses (``coupling.condense``);
        none while a drive reports no mass (its m_drive not connected: the whole force, nothing carried), detached,
        or while the mass ratio has stayed below ``CONDENSE_ABOVE`` in this run."""
        n = self.n
        m = self.values[(INPUT_KINDS - 1) * n : INPUT_KINDS * n]
        if not self.attached or not all(v > 0.0 for v in m):
            self._W, self._D = None, [0.0] * n
            return
        if not self._latched:
            inv = [1.0 / math.sqrt(v) for v in m]
            if eig_max([[self._M[i * n + j] * (inv[i] * inv[j]) for j in range(n)] for i in range(n)]) < CONDENSE_ABOVE:
                self._W, self._D = None, [0.0] * n
                return
            self._latched = True
        self._W, self._D = condense(self._M, m)

    def _tell(self, h: float) -> None:
        """Fc and Mc for the step ``h`` [s] (``Variables``): the bias plus the weighted other drives' forces,
        extrapolated ``coupling.EXTRAPOLATION`` steps of h ahead by their derivatives; without a condensed interface
        the whole force F, nothing carried."""
        vals, n = self.values, self.n
        at = (INPUT_KINDS + 1) * n + 6
        if self._W is None:
            vals[at : at + n] = vals[INPUT_KINDS * n : (INPUT_KINDS + 1) * n]
            vals[at + n : at + 2 * n] = self._D
            return
        tau = EXTRAPOLATION * h
        half = 0.5 * tau * tau
        T = [vals[3 * n + j] + tau * vals[4 * n + j] + half * vals[5 * n + j] for j in range(n)]
        b, W = self._b, self._W
        for k in range(n):
            acc = b[k]
            for j in range(n):
                if j != k:
                    acc += W[k * n + j] * (T[j] - b[j])
            vals[at + k] = acc
        vals[at + n : at + 2 * n] = self._D

    @property
    def _rho_unit(self) -> str:
        units = {d.unit for d in self.topology.drives}
        return units.pop() if len(units) == 1 else "(m or rad)"

    def initialize(self, t0: float) -> None:
        """Outputs at t0 from the current inputs (direct kinematics from the level pose); nothing condensed until
        the first step, so that the initial point follows from the parameters whatever a host's initialisation
        passes (the actuators' at-rest outputs reach the mechanism in some hosts' passes, not in others')."""
        self._guess = None
        self._t0 = float(t0)
        self._latched = False
        self._compute(t0, 0.0)
        self._W, self._D = None, [0.0] * self.n
        self._tell(0.0)

    def do_step(self, t: float, h: float) -> None:
        """Outputs at t + h for the inputs held (algebraic: DK warm-started, then IDP) if the step [t, t + h)
        holds an update instant (``T_mech``, module docstring); else the forces of the accelerations held
        (``inertial_forces``), the pose held."""
        T = self._T_mech
        if T > 0.0:
            eps = 1e-6 * (h if h < T else T)
            if self._t0 + math.ceil((t - self._t0 - eps) / T) * T >= t + h - eps:
                self.inertial_forces(t + h)
                self._tell(h)
                return
        self._compute(t + h, h)

    def inertial_forces(self, t: float) -> None:
        """F = M_k rho_ddot + b_k at ``t`` from the accelerations set now and the last full update's M_k, b_k
        (module docstring); no force when detached."""
        if not self.attached:
            return
        vals = self.values
        if not self._reaction(vals, self._M, self._b):
            n = self.n
            for k in range(2 * n, 3 * n):  # the accelerations
                if not math.isfinite(vals[k]):
                    raise ModelError(
                        f"{self.name}: input '{self.INPUTS[k]}' = {vals[k]!r} is not finite at t = {t!r} s"
                    )
            self._reaction(vals, self._M, self._b, True)  # finite inputs whose sum overflowed
