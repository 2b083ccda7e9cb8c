"""Systematic inverse dynamics of a mechanism from its description (paper sections 2.4, 3.3).

A mechanism is *described* by (``Description``):

- its independent coordinates q (for the MAST: z, psi, theta) and its n joint coordinates rho
  (the actuated slider positions), as many as coordinates;
- ``evaluate(q)``: the joint coordinates rho(q) (inverse kinematics), the platform pose
  (x, y, z, psi, theta, phi), and the frame (origin, rotation matrix) of every moving body;
- the bodies' inertial data (``Body``: mass, centre of mass in the body frame, inertia tensor
  about the centre of mass in the body frame).

``evaluate`` is written with ordinary arithmetic and the functions of the expression tracer
(fmus.common.tracer: ``sin``, ``cos``, ``sqrt``, ``atan2``, ``hypot``, ``sign``, ``require``). With
floats it simply evaluates. The engine runs it once on *traced* numbers: that records an
expression graph, which the engine differentiates symbolically (forward mode, first order in
each coordinate and second order along the motion) and turns into straight-line Python code. So the
Jacobians and their time derivatives are exact (no finite differences) and cost about as
much as hand-written closed forms.

From the description the engine produces, with gravity g along -z:

- per body b, with J_vb, J_wb the Jacobians (in rho_dot) of its centre-of-mass velocity
  (world frame) and of its angular velocity (body frame) and a_b0, wdot_b0 the accelerations
  when rho_ddot = 0 ("Jdot rho_dot"):

      M   = sum_b m_b J_vb^T J_vb + J_wb^T I_b J_wb                         (inertial term I = M rho_ddot)
      c   = sum_b m_b J_vb^T a_b0 + J_wb^T (I_b wdot_b0 + w_b x I_b w_b)    (Coriolis/centrifugal)
      g   = sum_b m_b g J_vb^T e_z                                          (gravity)
      t_rho = M rho_ddot + c + g                                            (Eq. 32)

  Translation by the principle of energy equivalence (Eqs. 5-9, 24-27), rotation by
  Boltzmann-Hamel with the body angular velocity as quasi-velocities (Eqs. 13, 18-19);
  each body's contribution (translation and rotation separately) is reported.
- the direct kinematics (Newton on the inverse kinematics, warm-started) that stays on the
  assembly branch of its starting pose: a solution where det(drho/dq) has the other sign, or
  within ``MARGIN`` of a singularity (``margins``), is a ``SingularityError`` naming the pose;
- the same inverse kinematics and Jacobian over arrays of poses (``evaluate_many``) and the
  forces over arrays (``forces_many``): the workspace analysis (mast.analyses.workspace).

Singularity margins (docs/mechanism.md, "Singularities and the assembly branch"): with the
coordinates made lengths by the description's ``lengths`` (q~_k = l_k q_k: a tilt counted as
the travel of the points at the platform radius), the *parallel margin* is the smallest
singular value of drho/dq~ (carriage travel per metre of platform motion in the weakest
direction; 0 where the platform can move with the carriages locked) and the *inverse margin*
the smallest singular value of dq~/drho (platform motion per metre of carriage travel; 0 where
a carriage can move without moving the platform).

Joint coordinates and forces: t_rho_i is the generalized force conjugate to rho_i, i.e. the
force the actuator applies along its joint (power t_rho . rho_dot).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping, Optional, Sequence

import numpy as np

from ..common.tracer import Expr, Forward, Graph, Second, add, compile_function, lift, mul, needed, neg, sub
from .kinematics import COND_LIMIT, KinematicsError, inv3
from .topology import Topology

__all__ = [
    "Body",
    "Description",
    "Evaluation",
    "Engine",
    "Part",
    "TracedBody",
    "EngineIDP",
    "EngineJacobians",
    "KinematicsError",
    "MARGIN",
    "Margins",
    "SingularityError",
]

#: smallest singularity margin [m/m] the direct kinematics accepts (both kinds, module docstring):
#: 1/MARGIN = 20 is the largest amplification of a carriage error into a platform error (or of a load
#: at the platform into an actuator force, by virtual work) and of a platform speed into a carriage
#: speed. At home the three designs have 0.54-0.63, ten times more (docs/mechanism.md)
MARGIN = 0.05


# ===================================================================================== descriptions
@dataclass(frozen=True)
class Body:
    """Inertial data of a rigid body: ``mass`` [kg], ``com`` (3,) [m] centre of mass in the body
    frame, ``inertia`` (3, 3) [kg m^2] inertia tensor about the centre of mass, body-frame axes."""

    name: str
    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

    def __post_init__(self) -> None:
        I = np.array(self.inertia, dtype=float)
        if I.shape != (3, 3) or not np.all(np.isfinite(I)) or not np.allclose(I, I.T, atol=0.0, rtol=0.0):
            raise ValueError(f"body {self.name}: inertia must be a finite symmetric 3x3 tensor")
        if not (math.isfinite(self.mass) and self.mass >= 0.0):
            raise ValueError(f"body {self.name}: mass {self.mass!r} must be finite and >= 0")
        if np.linalg.eigvalsh(I).min() < -1e-12 * max(1.0, abs(I).max()):
            raise ValueError(f"body {self.name}: inertia tensor is not positive semi-definite")
        object.__setattr__(self, "com", tuple(float(c) for c in self.com))
        object.__setattr__(self, "inertia", tuple(tuple(float(v) for v in row) for row in I))

    @property
    def massless(self) -> bool:
        return self.mass == 0.0 and not any(any(row) for row in self.inertia)


@dataclass
class Evaluation:
    """What ``Description.evaluate(q)`` returns: joint coordinates, pose, body frames.

    rho: n joint coordinates; pose: (x, y, z, psi, theta, phi) of the platform;
    frames: one (origin (3,), rotation (3, 3) as nested sequences, world <- body) per body,
    in the order of ``Description.bodies`` (of ``bodies`` when given).

    A description traced with its parameters as named inputs of the generated functions (the
    native FMUs compute with the values a host sets, mast.core.native) also gives ``parameters``
    ({input name: the value this description has}, in argument order, after the engine's own
    arguments), ``bodies`` (``TracedBody``: inertial data as expressions of those inputs) and
    ``gravity`` (g as one of them, [m/s^2]).
    """

    rho: Sequence
    pose: Sequence
    frames: Sequence
    bodies: Optional[Sequence] = None
    parameters: Mapping[str, float] = field(default_factory=dict)
    gravity: object = None


@dataclass(frozen=True)
class TracedBody:
    """A body whose inertial data are traced expressions (``Evaluation.bodies``): as ``Body``, unchecked
    (the parameters they come from are checked where they are set)."""

    name: str
    mass: object
    com: tuple
    inertia: tuple


@dataclass(frozen=True)
class Part:
    """A piece of a mechanism's drawing (``Description.sketch``), placed at a pose by the frame of its body.

    kind: ``"link"`` (a bar through ``points``, in order), ``"plate"`` (a closed outline through ``points``,
    filled), ``"joint"`` (a joint at each point), ``"carriage"`` (an actuated carriage or piston at each point)
    or ``"guide"`` (the fixed axis of joint coordinate ``joint`` (0-based): ``points`` are where its carriage
    is at rho = 0 and at rho = 1 m, the axis being linear in rho).
    body: the name of the body (``Description.bodies``) whose frame ``points`` [m] are given in, moving with
    it; None: the fixed base (world frame).
    """

    kind: str
    body: Optional[str]
    points: tuple
    joint: Optional[int] = None

    KINDS = ("link", "plate", "joint", "carriage", "guide")

    def __post_init__(self) -> None:
        if self.kind not in self.KINDS:
            raise ValueError(f"part kind {self.kind!r}: expected one of {', '.join(self.KINDS)}")
        if (self.kind == "guide") != (self.joint is not None) or (self.kind == "guide" and self.body is not None):
            raise ValueError("a guide is a part of the base (body None) with its joint; other parts have no joint")
        points = tuple(tuple(float(c) for c in p) for p in self.points)
        if not points or any(len(p) != 3 or not all(math.isfinite(c) for c in p) for p in points):
            raise ValueError(f"{self.kind} of {self.body or 'the base'}: points must be finite (x, y, z) [m]")
        object.__setattr__(self, "points", points)


class Description:
    """A mechanism for the engine. Subclasses set ``name``, ``coordinates``, ``joints``, ``bodies``
    and implement ``evaluate`` (with this module's functions) and ``guess``; ``sketch`` for a drawing."""

    name: str = "mechanism"
    coordinates: tuple[str, ...] = ("z", "psi", "theta")
    joints: tuple[str, ...] = ("rho_1", "rho_2", "rho_3")
    bodies: tuple[Body, ...] = ()
    #: per coordinate, the length [m] that turns its increment into a displacement (1 for a length; for
    #: an angle, the radius of the points it moves): the singularity margins compare motions in metres
    lengths: Optional[tuple[float, ...]] = None

    def evaluate(self, q: Sequence) -> Evaluation:
        raise NotImplementedError

    def guess(self, rho: Sequence[float]) -> tuple[float, ...]:
        """A starting pose for the direct kinematics (for example the level pose for rho)."""
        raise NotImplementedError

    def key(self) -> tuple:
        """Everything that defines the description (used to share compiled code)."""
        raise NotImplementedError

    @property
    def topology(self) -> "Topology":
        """Its interface shape (``topology.Topology``: coordinates with units, drives with kind and stroke, home
        pose): what the mechanism FMU's variables, the controllers, the SSD and the CLI are derived from."""
        raise NotImplementedError

    def sketch(self) -> tuple[Part, ...]:
        """The parts a drawing of the mechanism shows (``Part``: its base, bodies, joints and carriages),
        in body frames: placed at a pose by the frames ``evaluate`` gives (mast animate). Empty: no drawing."""
        return ()

    def __deepcopy__(self, memo):
        return self


# ===================================================================================== results
@dataclass(frozen=True)
class EngineJacobians:
    """Kinematics to first and second order at one (q, rho_dot), in joint space.

    q (n,), rho (n,); J (n, n) = dq/drho, J_inv = drho/dq, cond = condition number of J_inv;
    qdot = J rho_dot, Jdot (n,) = "Jdot rho_dot" (q acceleration when rho_ddot = 0);
    per body (dicts by name): J_v (3, n) centre-of-mass velocity Jacobian (world frame),
    J_w (3, n) angular velocity Jacobian (body frame), a0 (3,) / wdot0 (3,) the centre-of-mass
    and angular accelerations when rho_ddot = 0, v (3,), w (3,) the velocities.
    """

    q: np.ndarray
    rho: np.ndarray
    J: np.ndarray
    J_inv: np.ndarray
    cond: float
    qdot: np.ndarray
    Jdot: np.ndarray
    J_v: dict
    J_w: dict
    a0: dict
    wdot0: dict
    v: dict
    w: dict


@dataclass(frozen=True)
class EngineIDP:
    """Inverse dynamics at one instant (Eq. 32).

    t_rho (n,) [N]: generalized forces along the joints, t_rho = I_term + c_term + g_term;
    I_term = M rho_ddot (inertial), c_term (Coriolis/centrifugal, quadratic in rho_dot),
    g_term (gravity); M (n, n) mass matrix in rho; q (n,) independent coordinates;
    pose (6,) (x, y, z, psi, theta, phi); cond: condition number of drho/dq (a singularity flag);
    terms: {(body, "translation" | "rotation"): (I, c, g) arrays (n,)}: each body's share.
    """

    t_rho: np.ndarray
    I_term: np.ndarray
    c_term: np.ndarray
    g_term: np.ndarray
    M: np.ndarray
    q: np.ndarray
    pose: np.ndarray
    cond: float
    terms: dict = field(default_factory=dict)

    def by_body(self) -> dict:
        """{body: I + c + g} summed over translation and rotation."""
        out: dict = {}
        for (body, _), (i, c, g) in self.terms.items():
            out[body] = out.get(body, 0.0) + i + c + g
        return out


class SingularityError(KinematicsError):
    """The direct kinematics would leave the assembly branch of its start, or come within MARGIN of a
    singularity (docs/mechanism.md): the pose is named, nothing jumps."""


@dataclass(frozen=True)
class Margins:
    """How far a pose is from a singularity (module docstring), coordinates scaled by ``lengths``.

    det: det(drho/dq) (unscaled; its sign tells the assembly branches apart);
    parallel [m/m]: smallest singular value of drho/dq~ (0 at a parallel singularity);
    inverse [m/m]: smallest singular value of dq~/drho (0 at an inverse singularity);
    dexterity: condition number (2-norm) of drho/dq~, >= 1 (1: isotropic).
    """

    det: float
    parallel: float
    inverse: float
    dexterity: float

    @property
    def smallest(self) -> float:
        return min(self.parallel, self.inverse)


def margins_of(Jinv: np.ndarray, lengths: Sequence[float]) -> tuple[np.ndarray, ...]:
    """(det, parallel, inverse, dexterity) of drho/dq matrices ``Jinv`` (..., n, n), as arrays (Margins)."""
    Jinv = np.asarray(Jinv, dtype=float)
    with np.errstate(all="ignore"):
        sv = np.linalg.svd(Jinv / np.asarray(lengths, dtype=float), compute_uv=False)
        return np.linalg.det(Jinv), sv[..., -1], 1.0 / sv[..., 0], sv[..., 0] / sv[..., -1]


# ===================================================================================== the engine
def _inv(m: list[float], n: int) -> tuple[list[float], float]:
    """Inverse (row-major) and determinant of an n x n matrix; ZeroDivisionError if singular."""
    if n == 3:
        inv, det = inv3(m)
        return list(inv), det
    a = [list(m[r * n : (r + 1) * n]) + [1.0 if c == r else 0.0 for c in range(n)] for r in range(n)]
    det = 1.0
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(a[r][c]))
        if a[p][c] == 0.0:
            raise ZeroDivisionError("singular matrix")
        if p != c:
            a[c], a[p] = a[p], a[c]
            det = -det
        piv = a[c][c]
        det *= piv
        a[c] = [v / piv for v in a[c]]
        for r in range(n):
            if r != c and a[r][c] != 0.0:
                f = a[r][c]
                a[r] = [v - f * w for v, w in zip(a[r], a[c])]
    return [a[r][n + c] for r in range(n) for c in range(n)], det


def _cond(m: Sequence[float], minv: Sequence[float]) -> float:
    return math.sqrt(sum([v * v for v in m])) * math.sqrt(sum([v * v for v in minv]))


def _shown(rho: Sequence[float]) -> str:
    """Joint coordinates as error messages print them."""
    return ", ".join(f"{v:.9g}" for v in rho)


def _vee_RtX(R, X):
    """vee of the antisymmetric part of R^T X (R, X: 3x3 nested): ((R^T X)_21 - (R^T X)_12)/2, ..."""

    def rtx(i, j):
        return add(add(mul(R[0][i], X[0][j]), mul(R[1][i], X[1][j])), mul(R[2][i], X[2][j]))

    return [
        mul(0.5, sub(rtx(2, 1), rtx(1, 2))),
        mul(0.5, sub(rtx(0, 2), rtx(2, 0))),
        mul(0.5, sub(rtx(1, 0), rtx(0, 1))),
    ]


class Engine:
    """Kinematics and inverse dynamics of a ``Description`` (see the module docstring).

    ``g`` [m/s^2]: gravitational acceleration along -z. ``cond_limit``: condition number of
    drho/dq above which a configuration is reported singular (KinematicsError); ``margin``
    (``MARGIN``): the smallest singularity margin the direct kinematics accepts.
    """

    def __init__(self, description: Description, g: float = 9.81, cond_limit: float = COND_LIMIT) -> None:
        self.description = description
        self.g = float(g)
        self.cond_limit = cond_limit
        self.n = n = len(description.coordinates)
        if len(description.joints) != n:
            raise ValueError(
                f"{description.name}: {len(description.joints)} joints for {n} coordinates; "
                "the engine needs as many joint coordinates as independent coordinates"
            )
        self.bodies = tuple(description.bodies)
        self.lengths = tuple(float(v) for v in (description.lengths or (1.0,) * n))
        if len(self.lengths) != n or not all(math.isfinite(v) and v > 0.0 for v in self.lengths):
            raise ValueError(f"{description.name}: lengths {description.lengths!r}: expected {n} lengths > 0 m")
        # squared scales of the entries of drho/dq~ = Jinv / l_k and dq~/drho = l_j J (row-major)
        self._wa = [1.0 / (self.lengths[m % n] ** 2) for m in range(n * n)]
        self._wb = [self.lengths[m // n] ** 2 for m in range(n * n)]
        self.margin = MARGIN
        self._fns: dict[str, Callable] = {}
        graph = Graph()
        self._graph = graph
        q = [graph.input(f"q{j}") for j in range(n)]
        ev = description.evaluate(q)
        if len(ev.rho) != n or len(ev.pose) != 6 or len(ev.frames) != len(ev.bodies or self.bodies):
            raise ValueError(
                f"{description.name}: evaluate() must give {n} joint coordinates, a 6-value pose "
                f"and one frame per body ({len(ev.bodies or self.bodies)})"
            )
        lifted = lambda x: lift(graph, x)  # noqa: E731
        if ev.bodies is not None:
            self.bodies = tuple(ev.bodies)
        #: names and values of the description's parameters traced as inputs (Evaluation.parameters): the
        #: generated functions take them after their own arguments; this engine calls them with the values
        self.parameters = tuple(ev.parameters)
        self._pv = tuple(float(v) for v in ev.parameters.values())
        self._gravity = self.g if ev.gravity is None else ev.gravity
        self._q = q
        self._rho = [lifted(r) for r in ev.rho]
        self._pose = [lifted(p) for p in ev.pose]
        self._frames = []
        for body, (origin, R) in zip(self.bodies, ev.frames):
            R = [[lifted(R[i][j]) for j in range(3)] for i in range(3)]
            o = [lifted(v) for v in origin]
            com = [
                add(o[i], add(add(mul(R[i][0], body.com[0]), mul(R[i][1], body.com[1])), mul(R[i][2], body.com[2])))
                for i in range(3)
            ]
            self._frames.append((com, R))
        # first derivatives along each coordinate (q-space basis): shared by every function
        self._dq = [Forward(graph, {f"q{j}": (1.0 if j == k else 0.0) for j in range(n)}) for k in range(n)]

    def __deepcopy__(self, memo):  # immutable once built (Block.get_state deep-copies blocks)
        return self

    # -------------------------------------------------------------------------- generated functions
    #: what an overflow of the equations' coefficients is blamed on (``designs.engine``: the largest parameters)
    overflow_hint = ""

    def _fn(self, name: str) -> Callable:
        fn = self._fns.get(name)
        if fn is None:
            try:
                fn = self._fns[name] = getattr(self, f"_build_{name}")()
            except OverflowError as err:
                raise OverflowError(f"{err}{self.overflow_hint}") from None
        return fn

    def _qnames(self) -> list[str]:
        return [f"q{j}" for j in range(self.n)]

    def _args(self, names: list[str]) -> list[str]:
        """A generated function's arguments: ``names``, then the traced parameters (``parameters``)."""
        return names + list(self.parameters)

    def _build_ik(self) -> Callable:
        return compile_function("ik", self._args(self._qnames()), self._rho, self._graph, f"{self.description.name} ik")

    def _build_ikjac(self) -> Callable:
        return compile_function(
            "ikjac",
            self._args(self._qnames()),
            self._ikjac_outputs(),
            self._graph,
            f"{self.description.name} ik+jacobian",
        )

    def _kept(self) -> tuple[list[Expr], set[int]]:
        """What ``forces`` shares with ``ikjac`` at the same q (the pose's geometry, its checks): (the nodes of
        that part ``forces`` reads, the part's nodes). ``ikjac_kept`` returns the former after ikjac's outputs,
        ``forces_kept`` takes that tuple and computes only the rest (``compile_function``'s ``prior``)."""
        found = getattr(self, "_kept_split", None)
        if found is None:
            graph, forces = self._graph, self._forces_outputs()
            wanted = needed(forces, graph.checks)
            done = needed(self._ikjac_outputs(), graph.checks) & wanted
            read = {a.id for i in wanted - done for a in graph.nodes[i].args} | {o.id for o in forces}
            shared = [graph.nodes[i] for i in sorted(read & done) if graph.nodes[i].op not in ("input", "const")]
            found = self._kept_split = (shared, done)
        return found

    def _ikjac_outputs(self) -> list[Expr]:
        n = self.n
        return list(self._rho) + [self._dq[k](self._rho[i]) for i in range(n) for k in range(n)]

    def _forces_outputs(self) -> list[Expr]:
        """t_rho (n), the pose (6), then the inertial split of t_rho = M rho_ddot + b (``inertial``): the mass matrix
        M in joint space (n x n, row-major) and the bias b = Coriolis/centrifugal + gravity (n), the same graph."""
        t, _, c, gt, M = self._dynamics_graph(False)[:5]
        n = self.n
        return (
            list(t)
            + list(self._pose)
            + [M[a][b] for a in range(n) for b in range(n)]
            + [add(c[a], gt[a]) for a in range(n)]
        )

    def _build_ikjac_kept(self) -> Callable:
        outs = self._ikjac_outputs() + self._kept()[0]
        return compile_function(
            "ikjac_kept",
            self._args(self._qnames()),
            outs,
            self._graph,
            f"{self.description.name} ik+jacobian, kept for the forces",
        )

    def _forces_inputs(self) -> list[str]:
        """The force functions' own arguments: q, J = dq/drho (row-major), rho_dot, rho_ddot."""
        n = self.n
        return (
            self._qnames()
            + [f"J{j}{k}" for j in range(n) for k in range(n)]
            + [f"rd{k}" for k in range(n)]
            + [f"rdd{k}" for k in range(n)]
        )

    def _build_forces_kept(self) -> Callable:
        shared, done = self._kept()
        inputs = self._forces_inputs()
        return compile_function(
            "forces_kept",
            self._args(inputs),
            self._forces_outputs(),
            self._graph,
            f"{self.description.name} forces after ikjac_kept",
            prior=(self._ikjac_outputs() + shared, done),
        )

    def _build_pose(self) -> Callable:
        return compile_function(
            "pose", self._args(self._qnames()), self._pose, self._graph, f"{self.description.name} pose"
        )

    def _build_ikjac_many(self) -> Callable:
        n = self.n
        outs = list(self._rho) + [self._dq[k](self._rho[i]) for i in range(n) for k in range(n)]
        return compile_function(
            "ikjac",
            self._args(self._qnames()),
            outs,
            self._graph,
            f"{self.description.name} ik+jacobian, arrays",
            vector=True,
            rejected=KinematicsError,
        )

    def _build_forces_many(self) -> Callable:
        t = self._dynamics_graph(False)[0]
        inputs = self._forces_inputs()
        return compile_function(
            "forces",
            self._args(inputs),
            list(t),
            self._graph,
            f"{self.description.name} forces, arrays",
            vector=True,
            rejected=KinematicsError,
        )

    def _dynamics_graph(self, detailed: bool):
        """Outputs of the inverse dynamics, built on the graph (inputs q, J = dq/drho, rd, rdd)."""
        n, g = self.n, self._graph
        Jm = [[g.input(f"J{j}{k}") for k in range(n)] for j in range(n)]
        rd = [g.input(f"rd{k}") for k in range(n)]
        rdd = [g.input(f"rdd{k}") for k in range(n)]
        qd = [_sum(mul(Jm[j][k], rd[k]) for k in range(n)) for j in range(n)]
        p1 = Forward(g, {f"q{j}": qd[j] for j in range(n)})
        p2 = Second(g, p1, {})
        h = [p2(r) for r in self._rho]  # rho'' when qdd = 0
        qdd0 = [neg(_sum(mul(Jm[j][k], h[k]) for k in range(n))) for j in range(n)]  # Jdot rho_dot
        dq = self._dq

        def acc(y: Expr) -> Expr:  # y'' with rho_ddot = 0
            return add(p2(y), _sum(mul(dq[k](y), qdd0[k]) for k in range(n)))

        def to_rho(col_q: list[Expr]) -> list[Expr]:  # row vector in q -> in rho
            return [_sum(mul(col_q[k], Jm[k][c]) for k in range(n)) for c in range(n)]

        M = [[g.const(0.0)] * n for _ in range(n)]
        c = [g.const(0.0)] * n
        gt = [g.const(0.0)] * n
        terms, kin = [], []
        grav = self._gravity
        for body, (com, R) in zip(self.bodies, self._frames):
            m, I = body.mass, body.inertia
            Jv = [to_rho([dq[k](com[i]) for k in range(n)]) for i in range(3)]  # 3 x n
            a0 = [acc(com[i]) for i in range(3)]
            dR = [[[dq[k](R[i][j]) for j in range(3)] for i in range(3)] for k in range(n)]
            Jw_q = [_vee_RtX(R, dR[k]) for k in range(n)]  # n columns
            Jw = [to_rho([Jw_q[k][i] for k in range(n)]) for i in range(3)]  # 3 x n
            w = [_sum(mul(Jw[i][k], rd[k]) for k in range(n)) for i in range(3)]
            wdot0 = _vee_RtX(R, [[acc(R[i][j]) for j in range(3)] for i in range(3)])
            Iw = [_sum(mul(I[i][j], w[j]) for j in range(3)) for i in range(3)]
            mom = [
                add(
                    _sum(mul(I[i][j], wdot0[j]) for j in range(3)),
                    sub(mul(w[(i + 1) % 3], Iw[(i + 2) % 3]), mul(w[(i + 2) % 3], Iw[(i + 1) % 3])),
                )
                for i in range(3)
            ]
            Mt = [[None] * n for _ in range(n)]
            Mr = [[None] * n for _ in range(n)]
            for a in range(n):
                for b in range(a, n):
                    Mt[a][b] = Mt[b][a] = mul(m, _sum(mul(Jv[i][a], Jv[i][b]) for i in range(3)))
                    IJb = [_sum(mul(I[i][j], Jw[j][b]) for j in range(3)) for i in range(3)]
                    Mr[a][b] = Mr[b][a] = _sum(mul(Jw[i][a], IJb[i]) for i in range(3))
            ct = [mul(m, _sum(mul(Jv[i][a], a0[i]) for i in range(3))) for a in range(n)]
            cr = [_sum(mul(Jw[i][a], mom[i]) for i in range(3)) for a in range(n)]
            gtr = [mul(m * grav, Jv[2][a]) for a in range(n)]
            for a in range(n):
                c[a] = add(c[a], add(ct[a], cr[a]))
                gt[a] = add(gt[a], gtr[a])
                for b in range(n):
                    M[a][b] = add(M[a][b], add(Mt[a][b], Mr[a][b]))
            if detailed:
                It = [_sum(mul(Mt[a][b], rdd[b]) for b in range(n)) for a in range(n)]
                Ir = [_sum(mul(Mr[a][b], rdd[b]) for b in range(n)) for a in range(n)]
                terms.append((It, ct, gtr, Ir, cr))
                kin.append((Jv, Jw, a0, wdot0, [p1(x) for x in com], w))
        It = [_sum(mul(M[a][b], rdd[b]) for b in range(n)) for a in range(n)]
        t = [add(add(It[a], c[a]), gt[a]) for a in range(n)]
        return t, It, c, gt, M, terms, kin, qd, qdd0

    def _build_forces(self) -> Callable:
        inputs = self._forces_inputs()
        return compile_function(
            "forces", self._args(inputs), self._forces_outputs(), self._graph, f"{self.description.name} forces"
        )

    def _build_detailed(self) -> Callable:
        n = self.n
        t, It, c, gt, M, terms, kin, qd, qdd0 = self._dynamics_graph(True)
        outs = list(t) + list(It) + list(c) + list(gt) + [M[a][b] for a in range(n) for b in range(n)]
        outs += list(self._pose) + list(self._rho) + list(qd) + list(qdd0)
        for (Itb, ctb, gtb, Irb, crb), (Jv, Jw, a0, wd0, v, w) in zip(terms, kin):
            outs += list(Itb) + list(ctb) + list(gtb) + list(Irb) + list(crb)
            outs += [x for row in Jv for x in row] + [x for row in Jw for x in row] + list(a0) + list(wd0)
            outs += list(v) + list(w)
        inputs = self._forces_inputs()
        return compile_function("detailed", self._args(inputs), outs, self._graph, f"{self.description.name} detailed")

    # -------------------------------------------------------------------------- kinematics
    def ik(self, q: Sequence[float]) -> tuple[float, ...]:
        """Joint coordinates rho(q) (inverse kinematics); KinematicsError if unreachable."""
        return self._fn("ik")(*q, *self._pv)

    def pose(self, q: Sequence[float]) -> tuple[float, ...]:
        """(x, y, z, psi, theta, phi) of the platform at q."""
        return self._fn("pose")(*q, *self._pv)

    def jacobian(self, q: Sequence[float], check: bool = True) -> tuple[list[float], list[float], float]:
        """(J_inv = drho/dq, J = dq/drho, cond) at q, row-major flat lists; KinematicsError if singular."""
        n = self.n
        out = self._fn("ikjac")(*q, *self._pv)
        Jinv = list(out[n:])
        J, _ = self._inverse(Jinv, q)
        cond = _cond(Jinv, J)
        if check:
            self._check_cond(cond, q)
        return Jinv, J, cond

    def _inverse(self, Jinv: list[float], q) -> tuple[list[float], float]:
        try:
            return _inv(Jinv, self.n)
        except ZeroDivisionError:
            raise KinematicsError(f"singular configuration: drho/dq is singular at {self._fmt_q(q)}") from None

    def _check_cond(self, cond: float, q) -> None:
        if not cond < self.cond_limit:
            raise KinematicsError(
                f"singular configuration: drho/dq has condition number {cond:.3g} "
                f"(limit {self.cond_limit:.0e}) at {self._fmt_q(q)}"
            )

    def margins(self, q: Sequence[float]) -> Margins:
        """Singularity margins and dexterity at q (``Margins``; KinematicsError if q is not admissible)."""
        n = self.n
        Jinv = np.array(self._fn("ikjac")(*q, *self._pv)[n:], dtype=float).reshape(n, n)
        return Margins(*(float(v) for v in margins_of(Jinv, self.lengths)))

    def _fmt_q(self, q) -> str:
        units = {"z": "m", "x": "m", "y": "m"}
        return ", ".join(
            f"{name} = {float(v):.6g} {units.get(name, 'rad')}"
            + ("" if name in units else f" ({math.degrees(float(v)):.4g} deg)")
            for name, v in zip(self.description.coordinates, q)
        )

    def dk(
        self, rho: Sequence[float], guess: Optional[Sequence[float]] = None, tol: float = 1e-12, max_iter: int = 50
    ) -> tuple[tuple[float, ...], list[float], float]:
        """Direct kinematics: (q, J = dq/drho, cond) for joint coordinates rho.

        Newton's method on the inverse kinematics, from ``guess`` (or the description's level
        guess), until max |rho(q) - rho| < tol. KinematicsError if it does not converge, leaves
        the workspace, or ends in a singular configuration (cond(drho/dq) >= cond_limit);
        SingularityError if the solution's det(drho/dq) has another sign than at the start
        (another assembly branch) or its singularity margin is below ``margin``.
        """
        return self._newton(rho, guess, tol, max_iter, self._fn("ikjac"))[:3]

    def dk_kept(
        self, rho: Sequence[float], guess: Optional[Sequence[float]] = None
    ) -> tuple[tuple[float, ...], list[float], float, tuple]:
        """``dk`` for the forces that follow at its solution: (q, J, cond, kept), ``kept`` what ``forces_kept``
        reuses of the last evaluation at q (the same Newton steps: the same q, J, cond)."""
        return self._newton(rho, guess, 1e-12, 50, self._fn("ikjac_kept"))

    def _newton(
        self, rho: Sequence[float], guess: Optional[Sequence[float]], tol: float, max_iter: int, ikjac: Callable
    ) -> tuple[tuple[float, ...], list[float], float, tuple]:
        """``dk``'s Newton iteration with ``ikjac`` (``ikjac``, or ``ikjac_kept``): (q, J, cond, its output at q)."""
        n = self.n
        r = [float(v) for v in rho]
        if len(r) != n:
            raise KinematicsError(f"direct kinematics: expected {n} joint coordinates, got {len(r)}")
        if not all(math.isfinite(v) for v in r):
            raise KinematicsError(f"direct kinematics: rho = {tuple(r)!r} is not finite")
        if guess is None or not all(math.isfinite(float(v)) for v in guess):
            q = list(self.description.guess(r))
        else:
            q = [float(v) for v in guess]
        pv = self._pv
        res = math.inf
        start, det0 = None, 0.0
        for it in range(max_iter + 1):
            try:
                out = ikjac(*q, *pv)
                e = [out[i] - r[i] for i in range(n)]
                res = max([abs(v) for v in e])
                Jinv = list(out[n : n + n * n])
                J, det = self._inverse(Jinv, q)
                if res < tol:
                    cond = _cond(Jinv, J)
                    self._check_cond(cond, q)
            except KinematicsError as exc:
                raise KinematicsError(
                    f"direct kinematics did not converge for rho = ({_shown(r)}) m: iteration "
                    f"{it} reached {self._fmt_q(q)}, where: {exc}"
                ) from exc
            if not math.isfinite(res):
                raise KinematicsError(
                    f"direct kinematics did not converge for rho = ({_shown(r)}) m: non-finite "
                    f"residual at iteration {it} ({self._fmt_q(q)})"
                )
            if it == 0:
                start, det0 = tuple(q), det
            if res < tol:
                self._check_branch(q, Jinv, J, det, start, det0, r)
                return tuple(q), J, cond, out
            if it == max_iter:
                break
            for j in range(n):
                q[j] -= sum([J[j * n + k] * e[k] for k in range(n)])
        raise KinematicsError(
            f"direct kinematics did not converge for rho = ({_shown(r)}) m: {max_iter} iterations, "
            f"residual max|rho(q) - rho| = {res:.3g} m > tol = {tol:.3g} m "
            f"(last {self._fmt_q(q)})"
        )

    def _check_branch(self, q, Jinv, J, det, start, det0, rho) -> None:
        """The solution on the start's branch and at least ``margin`` from a singularity (SingularityError)."""
        if (det > 0.0) != (det0 > 0.0):
            raise SingularityError(
                f"direct kinematics for rho = ({_shown(rho)}) m: the solution {self._fmt_q(q)} lies on another "
                "assembly "
                f"branch than the start {self._fmt_q(start)} (det(drho/dq) = {det:+.3g} there, {det0:+.3g} at the "
                f"start): the joints crossed a parallel singularity; refused rather than jump to the other branch"
            )
        m = self.margin
        # cheap lower bounds first: sigma_min(A) >= 1 / |A^-1|_F (exact singular values only near the limit)
        fa = sum([v * v * w for v, w in zip(Jinv, self._wa)])
        fb = sum([v * v * w for v, w in zip(J, self._wb)])
        if fa * m * m <= 1.0 and fb * m * m <= 1.0:
            return
        mg = self.margins(q)
        if mg.smallest < m:
            kind = (
                "parallel (the platform could move with the joints locked)"
                if mg.parallel < m
                else "inverse (a joint could move without moving the platform)"
            )
            raise SingularityError(
                f"direct kinematics for rho = ({_shown(rho)}) m: the solution {self._fmt_q(q)} is within the margin "
                "of a "
                f"{kind} singularity: margins parallel {mg.parallel:.3g}, inverse {mg.inverse:.3g} < {m:g} m/m "
                f"(det(drho/dq) = {det:+.3g}; docs/mechanism.md, 'Singularities and the assembly branch')"
            )

    def evaluate_many(self, q: Sequence) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Inverse kinematics and Jacobian over arrays: q = n arrays (broadcast together) ->
        (rho (n, ...), drho/dq (..., n, n), admissible (...) bool). Values where not admissible are meaningless."""
        n = self.n
        arrays = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in q))
        out = self._fn("ikjac_many")(*arrays, *self._pv)
        shape = arrays[0].shape
        full = [np.broadcast_to(np.asarray(v, dtype=float), shape) for v in out[:-1]]
        rho = np.stack(full[:n])
        Jinv = np.stack(full[n:], axis=-1).reshape(shape + (n, n))
        ok = np.broadcast_to(np.asarray(out[-1], dtype=bool), shape) & np.all(np.isfinite(rho), axis=0)
        return rho, Jinv, ok

    def forces_many(self, q: Sequence, J: np.ndarray, rho_dot: Sequence, rho_ddot: Sequence) -> np.ndarray:
        """``forces`` over arrays: q = n arrays, J (..., n, n) = dq/drho; rho_dot, rho_ddot: n arrays or
        floats -> t_rho (n, ...)."""
        n = self.n
        J = np.asarray(J, dtype=float)
        args = list(q) + [J[..., j, k] for j in range(n) for k in range(n)] + list(rho_dot) + list(rho_ddot)
        out = self._fn("forces_many")(*args, *self._pv)
        shape = J.shape[:-2]
        return np.stack([np.broadcast_to(np.asarray(v, dtype=float), shape) for v in out[:n]])

    # -------------------------------------------------------------------------- dynamics
    def forces(
        self, q: Sequence[float], J: Sequence[float], rho_dot: Sequence[float], rho_ddot: Sequence[float]
    ) -> tuple[float, ...]:
        """Hot path: (t_rho..., x, y, z, psi, theta, phi) at q with J = dq/drho (from ``dk``)."""
        return self._fn("forces")(*q, *J, *rho_dot, *rho_ddot, *self._pv)[: self.n + 6]

    def inertial(
        self, q: Sequence[float], J: Sequence[float], rho_dot: Sequence[float], rho_ddot: Sequence[float]
    ) -> tuple[float, ...]:
        """``forces`` with the split t_rho = M rho_ddot + b of the same evaluation: (t_rho (n), the pose (6), M (n x n,
        row-major) [kg, kg m or kg m^2 by the drives' units], b (n) [N or N m]: Coriolis/centrifugal at rho_dot and
        gravity). M and b depend on q and rho_dot only: a block may hold them and take rho_ddot anew."""
        return self._fn("forces")(*q, *J, *rho_dot, *rho_ddot, *self._pv)

    def forces_kept(
        self, kept: tuple, q: Sequence[float], J: Sequence[float], rho_dot: Sequence[float], rho_ddot: Sequence[float]
    ) -> tuple[float, ...]:
        """``inertial`` after ``dk_kept``: what it computed at q is not computed again (the same floats)."""
        return self._fn("forces_kept")(kept, *q, *J, *rho_dot, *rho_ddot, *self._pv)

    def _detailed(self, q, J, rd, rdd):
        return self._fn("detailed")(*q, *J, *rd, *rdd, *self._pv)

    def _unpack(self, q, J, cond, rd, rdd) -> tuple[EngineIDP, EngineJacobians]:
        n = self.n
        out = self._detailed(q, J, rd, rdd)
        k = 0

        def take(m):
            nonlocal k
            v = np.array(out[k : k + m], dtype=float)
            k += m
            return v

        t, It, c, gt, M = take(n), take(n), take(n), take(n), take(n * n).reshape(n, n)
        pose, rho, qd, qdd0 = take(6), take(n), take(n), take(n)
        terms, Jv, Jw, a0, wd0, v, w = {}, {}, {}, {}, {}, {}, {}
        for body in self.bodies:
            Itb, ctb, gtb, Irb, crb = take(n), take(n), take(n), take(n), take(n)
            terms[(body.name, "translation")] = (Itb, ctb, gtb)
            terms[(body.name, "rotation")] = (Irb, crb, np.zeros(n))
            Jv[body.name], Jw[body.name] = take(3 * n).reshape(3, n), take(3 * n).reshape(3, n)
            a0[body.name], wd0[body.name], v[body.name], w[body.name] = take(3), take(3), take(3), take(3)
        qa = np.array(q, dtype=float)
        Jm = np.array(J, dtype=float).reshape(n, n)
        idp = EngineIDP(t, It, c, gt, M, qa, pose, cond, terms)
        jac = EngineJacobians(qa, rho, Jm, np.linalg.inv(Jm), cond, qd, qdd0, Jv, Jw, a0, wd0, v, w)
        return idp, jac

    def inverse_dynamics(
        self,
        rho: Sequence[float],
        rho_dot: Sequence[float],
        rho_ddot: Sequence[float],
        guess: Optional[Sequence[float]] = None,
    ) -> EngineIDP:
        """Forces t_rho for the joint motion (rho, rho_dot, rho_ddot), pose by the direct kinematics."""
        rd, rdd = self._vector("rho_dot", rho_dot), self._vector("rho_ddot", rho_ddot)
        q, J, cond = self.dk(self._vector("rho", rho), guess)
        return self._unpack(q, J, cond, rd, rdd)[0]

    def inverse_dynamics_at_pose(
        self, q: Sequence[float], rho_dot: Sequence[float], rho_ddot: Sequence[float]
    ) -> EngineIDP:
        """As ``inverse_dynamics`` at a known q (no direct kinematics)."""
        q = self._vector("q", q)
        _, J, cond = self.jacobian(q)
        return self._unpack(q, J, cond, self._vector("rho_dot", rho_dot), self._vector("rho_ddot", rho_ddot))[0]

    def jacobians(self, q: Sequence[float], rho_dot: Optional[Sequence[float]] = None) -> EngineJacobians:
        """Every Jacobian at q and, for rho_dot, the velocities and "Jdot rho_dot" terms."""
        q = self._vector("q", q)
        rd = self._vector("rho_dot", rho_dot) if rho_dot is not None else [0.0] * self.n
        _, J, cond = self.jacobian(q)
        return self._unpack(q, J, cond, rd, [0.0] * self.n)[1]

    def _vector(self, name: str, v) -> list[float]:
        out = [float(x) for x in v]
        if len(out) != self.n:
            raise KinematicsError(f"{self.description.name}: {name} must have {self.n} components, got {len(out)}")
        for k, x in enumerate(out):
            if not math.isfinite(x):
                raise KinematicsError(f"{self.description.name}: {name}_{k + 1} = {x!r} is not finite")
        return out


def _sum(items) -> Expr:
    total = None
    for x in items:
        total = x if total is None else add(total, x)
    return total if total is not None else 0.0
