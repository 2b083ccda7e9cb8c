"""`mast workspace`: the poses a mechanism design can really reach (docs/workspace.md).

The workspace of a design is the set of poses q (the mechanism's coordinates, its topology's
``names``: for the 3PRS q = (z, psi, theta)) that

- the mechanism can assemble (the description's checks: working assembly, leg reach, tilt range),
- put every drive's joint within its stroke [rho_min, rho_max] (the actuators' parameter sets),
- lie at least ``engine.MARGIN`` from a singularity of either kind (``Engine.margins``: the
  parallel margin, smallest singular value of drho/dq~, and the inverse margin, smallest
  singular value of dq~/drho, with q~ the coordinates made lengths, for the 3PRS (z, r psi, r theta)),
- lie on the assembly branch of the home pose (det(drho/dq) of the same sign), and
- are connected to the home pose (all joints at rho_0) by a path that keeps all of this.

It is computed on a grid around home over a set of swept coordinates (``sweep``: one to three of
the mechanism's coordinates, by default all of them), the others held at their home values: for
the 3PRS the grid over (z, psi, theta); for a six-coordinate mechanism the constant-orientation
workspace (x, y, z at the home orientation) or the orientation workspace at the home position.
Every node and the midpoint of every edge between neighbouring nodes is judged (the generated
kinematics of the engine on arrays); an edge is kept when both its nodes and its midpoint pass,
and the workspace is the connected component of home in the graph of kept edges (a flood fill
from home). The box grows while the workspace touches it. Per node: the margins, the dexterity
(2-norm condition number of drho/dq~), the distance [m of platform motion, angles counted as
their coordinate length times the angle] to the nearest sampled pose that is within the margin
of a singularity or on the other branch, and the static drive forces (N; N m for a rotary drive)
with an optional payload (the engine's inverse dynamics at rest) with the joint speed a unit
platform speed needs.

Outputs (``write``): DIR/workspace.json (summary), DIR/workspace.csv (the workspace and its
boundary layer, one row per sampled pose: the swept coordinates in m and deg, rho_k and F_k per
drive), DIR/workspace.png (sections and the boundary). ``classify`` answers for one pose.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence, Union

import numpy as np

from fmus.mechanism.designs import KINEMATICS, MASS_PARAMETERS, describe, description
from fmus.mechanism.designs import engine as design_engine
from fmus.mechanism.engine import MARGIN, Engine, margins_of
from fmus.mechanism.kinematics import KinematicsError
from fmus.mechanism.topology import Coordinate, Topology

REPO = Path(__file__).resolve().parents[2]
BASE_SSD = REPO / "ssp" / "MAST.ssd"
DEG = math.pi / 180.0
#: the bodies' mass parameters (fmus.mechanism.designs.MASS_PARAMETERS): without them the workspace is kinematic
BODY_MASSES = ("m_leg", "I_leg", "m_platform", "I_px", "I_py", "I_pz")

#: node status codes (``Workspace.status``)
INSIDE, UNASSEMBLABLE, STROKE, SINGULAR, BRANCH, DISCONNECTED = range(6)
STATUS = (
    "inside",
    "not assemblable",
    "outside the stroke",
    "within the margin of a singularity",
    "on the other assembly branch",
    "not connected to home",
)
#: default grid steps: 5 mm in the length coordinates (z), 1 deg in the angles (psi, theta); about 10 s per
#: 3PRS design on one core
STEP_Z = 0.005
STEP_TILT_DEG = 1.0
#: tolerance on the stroke limits [m or rad] (a carriage exactly at its end is within the stroke)
STROKE_TOL = 1e-12
#: the most coordinates one grid sweeps (the others held at home): the grid's nodes grow as a power of it
MAX_SWEPT = 3


# ----------------------------------------------------------------------------- the machine
@dataclass(frozen=True)
class Machine:
    """What the workspace needs of a design: the mechanism's parameters, the strokes, home, the drives.

    rho_min, rho_max, rho_home: per drive joint, in its unit (m; rad for a rotary drive); drive: per-joint-identical
    actuator data for the
    static motor torque (M_load [kg], g_guide [m/s^2], p [m], i_r [-], k_T [N m/A], i_max [A]),
    empty when the system does not give them.
    """

    label: str
    params: Mapping
    rho_min: tuple
    rho_max: tuple
    rho_home: tuple
    drive: Mapping = field(default_factory=dict)
    payload_kg: float = 0.0
    #: the parameters of the mechanism's bodies and gravity (None: the 3PRS's, ``BODY_MASSES``)
    masses: Optional[tuple] = None

    @property
    def missing_masses(self) -> tuple[str, ...]:
        """The mass parameters the mechanism's parameters do not give (a user's own mechanism FMU, e.g. the
        lumped one of docs/interfaces.md): its workspace is then kinematic only, with no static forces."""
        if self.masses is not None:
            return tuple(name for name in self.masses if name not in self.params)
        return tuple(p.name for p in MASS_PARAMETERS if p.name in BODY_MASSES and p.name not in self.params)

    @property
    def topology(self) -> Topology:
        """The mechanism's topology (its coordinates with units, its drives): what the grid sweeps."""
        return describe(self.params, self.label, masses=False).topology

    def engine(self) -> Engine:
        params = dict(self.params)
        if self.payload_kg:
            params["m_payload"] = float(params.get("m_payload", 0.0)) + self.payload_kg
        return design_engine(params, self.label, masses=not self.missing_masses)


def _from_system(label: str, system, mechanism: Optional[Mapping] = None, payload: float = 0.0) -> Machine:
    from ..core.ssp import mechanism_parameters

    comps = system.components
    mech = dict(mechanism if mechanism is not None else mechanism_parameters(comps["mechanism"]))
    acts = [comps[n].parameters for n in sorted((n for n in comps if n.startswith("actuator")), key=_drive_order)]
    if not acts:
        raise ValueError(f"{label}: the system has no actuator components (needed for the strokes)")
    for key in ("rho_min", "rho_max", "rho_0"):
        if any(key not in a for a in acts):
            raise ValueError(f"{label}: an actuator has no parameter '{key}' (the stroke and home of its carriage)")
    drive = {}
    names = ("M_load", "g_guide", "p", "i_r", "k_T")
    if all(k in acts[0] for k in names) and "controller" in comps and "i_max" in comps["controller"].parameters:
        drive = {k: float(acts[0][k]) for k in names}
        drive["i_max"] = float(comps["controller"].parameters["i_max"])
        if mechanism is not None and "beta" in mech and "g" in mech:  # an FMU swapped in: g cos(beta)
            drive["g_guide"] = float(mech["g"]) * math.cos(float(mech["beta"]))
    if not (math.isfinite(payload) and payload >= 0.0):
        raise ValueError(f"--payload {payload!r}: expected a finite mass >= 0 kg")
    kind = mech.get("kinematics", "3PRS")
    return Machine(
        label,
        mech,
        tuple(float(a["rho_min"]) for a in acts),
        tuple(float(a["rho_max"]) for a in acts),
        tuple(float(a["rho_0"]) for a in acts),
        drive,
        float(payload),
        body_masses(kind) if kind != "3PRS" and described(kind) else None,
    )


def described(name: str) -> bool:
    """Whether ``name`` is a mechanism of a shipped description file (``designs.KINEMATICS``: 3PRS, 3RPS, ...)."""
    return name in KINEMATICS and not callable(KINEMATICS[name])


def body_masses(name: str) -> tuple[str, ...]:
    """The parameters of the bodies and gravity of the described mechanism ``name`` (its description's traced
    parameters that are not its geometry's): what its static forces need."""
    file = description(name)
    return tuple(n for n in file.traced if n not in file.kinematic)


def _from_description(name: str, payload: float = 0.0) -> Machine:
    """The machine of a mechanism description alone (no system): its file's parameter values, its drives' strokes,
    home at its home pose; no actuator data (the static forces in N, no motor torque)."""
    if not (math.isfinite(payload) and payload >= 0.0):
        raise ValueError(f"--payload {payload!r}: expected a finite mass >= 0 kg")
    file = description(name)
    params = {"kinematics": name, **file.values()}
    top = describe(params, name, masses=False).topology
    rho_home = design_engine(params, name, masses=False).ik(top.home)
    return Machine(
        name,
        params,
        tuple(d.stroke[0] for d in top.drives),
        tuple(d.stroke[1] for d in top.drives),
        tuple(float(v) for v in rho_home),
        {},
        float(payload),
        body_masses(name),
    )


def _drive_order(name: str) -> tuple:
    """actuator_k in the order of k (actuator_10 after actuator_9), the connector convention's drive k."""
    head, _, k = name.rpartition("_")
    return (0, int(k), head) if k.isdigit() else (1, 0, name)


def machine(design: Union[str, Path], payload: float = 0.0, mechanism: Optional[Mapping] = None) -> Machine:
    """The machine of a design name (``mast.core.designs``), a system (.ssd/.ssp), a mechanism FMU (swapped into
    ssp/MAST.ssd with its own defaults, as ``mast compare`` does) or the name of a mechanism description alone
    (``described``: its own strokes and home, no system). ``mechanism``: parameters that replace the system's
    mechanism parameters (an FMU's defaults)."""
    from ..core.designs import DESIGNS
    from ..core.ssp import SSPArchive, read_ssd

    named = {d.name: d for d in DESIGNS} | {d.model_identifier: d for d in DESIGNS}
    text = str(design)
    if text in named:
        d = named[text]
        return _from_system(d.name, read_ssd(d.ssd), mechanism, payload)
    path = Path(text)
    if not path.exists() and described(text) and mechanism is None:
        return _from_description(text, payload)
    if not path.exists():
        raise ValueError(
            f"design {text!r}: neither a design ({', '.join(d.name for d in DESIGNS)}), a mechanism "
            f"description ({', '.join(k for k in KINEMATICS if described(k))}) nor a file"
        )
    if path.suffix == ".ssd":
        return _from_system(path.stem, read_ssd(path), mechanism, payload)
    if path.suffix == ".ssp":
        with SSPArchive(path) as archive:
            return _from_system(path.stem, archive.system, mechanism, payload)
    if path.suffix == ".fmu":
        from ..core.components import fmu_parameters

        return _from_system(path.stem, read_ssd(BASE_SSD), {**fmu_parameters(path), **(mechanism or {})}, payload)
    raise ValueError(f"design {text!r}: expected a design name, an .ssd/.ssp system or a mechanism .fmu")


# ----------------------------------------------------------------------------- judging poses
@dataclass
class _Judged:
    status: np.ndarray  # int8 status codes (INSIDE: passes every local test)
    rho: np.ndarray  # (n, ...)
    Jinv: np.ndarray  # (..., n, n)
    det: np.ndarray
    parallel: np.ndarray
    inverse: np.ndarray
    dexterity: np.ndarray


def _judge(eng: Engine, m: Machine, q: Sequence[np.ndarray], sign: float, margin: float) -> _Judged:
    """Status and margins of every pose in the arrays q (local tests: assembly, stroke, branch, margin)."""
    rho, Jinv, ok = eng.evaluate_many(q)
    shape = ok.shape
    status = np.where(ok, INSIDE, UNASSEMBLABLE).astype(np.int8)
    lo = np.asarray(m.rho_min).reshape((-1,) + (1,) * len(shape)) - STROKE_TOL
    hi = np.asarray(m.rho_max).reshape((-1,) + (1,) * len(shape)) + STROKE_TOL
    out = np.any((rho < lo) | (rho > hi), axis=0)
    status[ok & out] = STROKE
    det, par, inv, dex = (np.full(shape, np.nan) for _ in range(4))
    if ok.any():
        det[ok], par[ok], inv[ok], dex[ok] = margins_of(Jinv[ok], eng.lengths)
    cand = status == INSIDE
    status[cand & (np.sign(det) != sign)] = BRANCH
    status[(status == INSIDE) & ~(np.minimum(par, inv) >= margin)] = SINGULAR
    return _Judged(status, rho, Jinv, det, par, inv, dex)


# ----------------------------------------------------------------------------- the workspace
@dataclass
class Workspace:
    """A sampled workspace (module docstring); arrays are indexed like ``axes``, one dimension per swept
    coordinate (for the 3PRS [z, psi, theta])."""

    machine: Machine
    home: tuple  # every coordinate's home value, in the topology's order and units (m, rad)
    sign: float  # sign of det(drho/dq) at home: the working branch
    margin: float  # MARGIN used [m/m]
    lengths: tuple  # the engine's coordinate lengths, every coordinate (3PRS: 1, r, r)
    axes: tuple  # per swept coordinate, its 1-D grid [m or rad]
    home_index: tuple
    status: np.ndarray
    det: np.ndarray
    parallel: np.ndarray
    inverse: np.ndarray
    dexterity: np.ndarray
    distance: np.ndarray  # [m] to the nearest sampled singular (margin or branch) pose; inf: none in the box
    rho: np.ndarray  # (n, ...) the drives' joints
    forces: Optional[np.ndarray] = None  # (n, ...) static drive forces [N; N m rotary], inside only (NaN elsewhere)
    kept: tuple = ()  # per axis, the edges of the workspace's graph (both nodes and the midpoint pass)
    wall_time_s: float = 0.0
    topology: Optional[Topology] = None  # the mechanism's (coordinates, drives); None: the 3PRS's
    swept: tuple = (0, 1, 2)  # the indices (into the topology's coordinates) of the swept ones, in order

    @property
    def inside(self) -> np.ndarray:
        return self.status == INSIDE

    @property
    def steps(self) -> tuple:
        return tuple(float(a[1] - a[0]) for a in self.axes)

    @property
    def mechanism(self) -> Topology:
        """The mechanism's topology: its coordinates with units, its drives."""
        return self.topology if self.topology is not None else self.machine.topology

    @property
    def coordinates(self) -> tuple[Coordinate, ...]:
        """Every coordinate of the mechanism (``Topology.coordinates``)."""
        return self.mechanism.coordinates

    @property
    def swept_coordinates(self) -> tuple[Coordinate, ...]:
        return tuple(self.coordinates[k] for k in self.swept)

    @property
    def held(self) -> dict[str, float]:
        """The coordinates not swept and their (home) values [m or rad]."""
        return {c.name: self.home[k] for k, c in enumerate(self.coordinates) if k not in self.swept}

    def pose(self, index: Sequence[int]) -> np.ndarray:
        """Every coordinate at the grid node ``index`` (the held ones at home) [m or rad]."""
        q = np.array(self.home, dtype=float)
        for d, k in enumerate(self.swept):
            q[k] = self.axes[d][index[d]]
        return q

    def summary(self) -> dict:
        return summarize(self)


def sweep_of(topology: Topology, sweep: Optional[Sequence[str]] = None, where: str = "workspace") -> tuple[int, ...]:
    """The indices of the coordinates ``sweep`` names (default: every coordinate, if at most ``MAX_SWEPT``), in the
    topology's order. ValueError naming what is wrong: a name the mechanism lacks, one named twice, none or more
    than ``MAX_SWEPT``."""
    names = topology.names
    if sweep is None:
        if len(names) > MAX_SWEPT:
            raise ValueError(
                f"{where}: {topology.name} has {len(names)} coordinates ({', '.join(names)}): give the "
                f"(at most {MAX_SWEPT}) swept ones, the others are held at home (for example x,y,z: the "
                "constant-orientation workspace; psi,theta,phi: the orientation workspace)"
            )
        return tuple(range(len(names)))
    sweep = list(sweep)
    unknown = [c for c in sweep if c not in names]
    if unknown:
        raise ValueError(
            f"{where}: swept coordinate {', '.join(repr(c) for c in unknown)}: {topology.name} has no "
            f"such coordinate; its coordinates are {', '.join(names)}"
        )
    if len(set(sweep)) != len(sweep) or not 1 <= len(sweep) <= MAX_SWEPT:
        raise ValueError(
            f"{where}: swept coordinates {', '.join(sweep) or '(none)'}: expected 1 to {MAX_SWEPT} "
            f"different ones of {', '.join(names)}"
        )
    return tuple(sorted(names.index(c) for c in sweep))


def sweep_for_pose(topology: Topology, q: Sequence[float]) -> Optional[tuple[str, ...]]:
    """The coordinates to sweep to answer for pose ``q`` (``--pose`` without ``--sweep``): None (every one) for a
    mechanism of at most ``MAX_SWEPT`` coordinates; else the group of the coordinates q moves from home (the lengths
    x, y, z: the constant-orientation workspace; the angles: the orientation one) when they are of one kind, the
    moved coordinates themselves otherwise (the lengths when q is home). ValueError naming them when q moves more
    than ``MAX_SWEPT``."""
    coords = topology.coordinates
    if len(coords) <= MAX_SWEPT:
        return None
    moved = [c for c, v, h in zip(coords, q, topology.home) if v != h]
    if len(moved) > MAX_SWEPT:
        raise ValueError(
            f"pose {_fmt_pose(q, coords)}: it leaves home in {len(moved)} coordinates "
            f"({', '.join(c.name for c in moved)}); a workspace sweeps at most {MAX_SWEPT}, the "
            f"others held at home: move at most {MAX_SWEPT} of {', '.join(topology.names)} from home"
        )
    kinds = {c.angular for c in moved} or {False}
    group = [c for c in coords if c.angular in kinds]
    return tuple(c.name for c in (group if len(kinds) == 1 and len(group) <= MAX_SWEPT else moved))


def _axis(centre: float, step: float, below: int, above: int) -> np.ndarray:
    return centre + step * np.arange(-below, above + 1, dtype=float)


def _shifted(ndim: int, axis: int) -> tuple[tuple, tuple]:
    """Index tuples of the lower and the upper node of every edge along ``axis``."""
    lo, hi = [slice(None)] * ndim, [slice(None)] * ndim
    lo[axis], hi[axis] = slice(None, -1), slice(1, None)
    return tuple(lo), tuple(hi)


def _kept(inside_nodes: np.ndarray, mids_ok: Sequence[np.ndarray]) -> tuple[np.ndarray, ...]:
    """Per axis, the edges kept: both nodes and the midpoint pass (shape: one less along that axis)."""
    out = []
    for axis, mid in enumerate(mids_ok):
        lo, hi = _shifted(inside_nodes.ndim, axis)
        out.append(inside_nodes[lo] & inside_nodes[hi] & mid)
    return tuple(out)


def _pairs(kept: Sequence[np.ndarray], shape: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Flat node indices (a, b) of the kept edges."""
    idx = np.arange(int(np.prod(shape))).reshape(shape)
    a_all, b_all = [], []
    for axis, keep in enumerate(kept):
        lo, hi = _shifted(len(shape), axis)
        a_all.append(idx[lo][keep])
        b_all.append(idx[hi][keep])
    return np.concatenate(a_all), np.concatenate(b_all)


def _poses(grids: Sequence[np.ndarray], home: Sequence[float], swept: Sequence[int]) -> list[np.ndarray]:
    """Every coordinate over the swept ones' ``grids`` (the held ones at home, as arrays of the grids' shape)."""
    out = [np.full(grids[0].shape, float(v)) for v in home]
    for g, k in zip(grids, swept):
        out[k] = g
    return out


def _fill(
    eng: Engine,
    m: Machine,
    home_index: tuple,
    sign: float,
    margin: float,
    axes: tuple,
    progress: Optional[Callable[[float], None]],
    home: Sequence[float],
    swept: Sequence[int],
) -> tuple:
    """Judge the nodes and edge midpoints of the grid ``axes`` (of the ``swept`` coordinates, the others at
    ``home``): (nodes, status with the nodes not connected to home marked, the kept edges of the workspace per
    axis)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    first, rest = axes[0], axes[1:]
    shape = tuple(len(a) for a in axes)
    mids = []
    # work in slabs of the first axis (memory, progress): nodes, then the midpoints along each axis
    total = (len(axes) + 1) * len(first)
    done = 0

    def tick(k: int = 1) -> None:
        nonlocal done
        done += k
        if progress:
            progress(min(done / total, 1.0))

    def judged(*grid: np.ndarray) -> _Judged:
        return _judge(eng, m, _poses(np.meshgrid(*grid, indexing="ij"), home, swept), sign, margin)

    parts = []
    for i in range(len(first)):
        parts.append(judged(first[i : i + 1], *rest))
        tick()
    nodes = _Judged(
        *(
            np.concatenate([getattr(p, f) for p in parts], axis=1 if f == "rho" else 0)
            for f in _Judged.__dataclass_fields__
        )
    )
    del parts
    fm = 0.5 * (first[:-1] + first[1:])
    mid_first = [np.zeros((0,) + shape[1:], dtype=bool)]
    for i in range(len(fm)):
        mid_first.append(judged(fm[i : i + 1], *rest).status == INSIDE)
        tick()
    tick()
    mids.append(np.concatenate(mid_first, axis=0))
    rest_mid = [0.5 * (a[:-1] + a[1:]) for a in rest]
    mid_rest = [[] for _ in rest]
    for i in range(len(first)):
        for d, am in enumerate(rest_mid):
            grid = [first[i : i + 1], *rest]
            grid[1 + d] = am
            mid_rest[d].append(judged(*grid).status == INSIDE)
        tick(len(rest))
    mids += [np.concatenate(part, axis=0) for part in mid_rest]
    ok = nodes.status == INSIDE
    kept = _kept(ok, mids)
    a, b = _pairs(kept, shape)
    n = ok.size
    graph = coo_matrix((np.ones(len(a), dtype=np.int8), (a, b)), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    home_flat = np.ravel_multi_index(home_index, shape)
    if not ok.ravel()[home_flat]:
        raise ValueError(
            f"{m.label}: the home pose is not inside the workspace: {STATUS[nodes.status.ravel()[home_flat]]}"
        )
    connected = (labels == labels[home_flat]).reshape(shape)
    status = nodes.status.copy()
    status[ok & ~connected] = DISCONNECTED
    return nodes, status, _kept(status == INSIDE, kept)


def compute(
    m: Machine,
    step_z: float = STEP_Z,
    step_tilt: float = STEP_TILT_DEG * DEG,
    margin: float = MARGIN,
    progress: Optional[Callable[[float], None]] = None,
    max_tilt: float = 90 * DEG,
    sweep: Optional[Sequence[str]] = None,
) -> Workspace:
    """The workspace of machine ``m`` (module docstring) on a grid of steps ``step_z`` [m] in the length coordinates
    (x, y, z) and ``step_tilt`` [rad] in the angles, over the coordinates ``sweep`` (``sweep_of``: default every
    coordinate of the mechanism, at most three), the others held at their home values."""
    from scipy.ndimage import distance_transform_edt

    for name, v in (("step_z", step_z), ("step_tilt", step_tilt)):
        if not (math.isfinite(v) and v > 0.0):
            raise ValueError(f"workspace: {name} = {v!r}: expected a finite step > 0")
    t0 = time.perf_counter()
    eng = m.engine()
    topology = eng.description.topology
    swept = sweep_of(topology, sweep, f"workspace of {m.label}")
    n = topology.n
    if not len(m.rho_home) == len(m.rho_min) == len(m.rho_max) == n:
        raise ValueError(
            f"{m.label}: {len(m.rho_home)} actuators for the {n} drives of {topology.name} "
            f"({', '.join(topology.joints)}): expected actuator_1..actuator_{n}"
        )
    home = home_pose(eng, m)
    sign = math.copysign(1.0, eng.margins(home).det)
    # the box: for a length coordinate the motion the drives' strokes allow (from the home Jacobian: all
    # carriages together for the 3PRS's z), for an angle +-35 deg; or on a fine grid the extent of a pass 4
    # times coarser (1/64 of the work for three coordinates) with two of its steps around
    coords = [topology.coordinates[k] for k in swept]
    steps = [step_tilt if c.angular else step_z for c in coords]
    J = np.array(eng.jacobian(home)[1]).reshape(n, n)
    span = max(hi - lo for lo, hi in zip(m.rho_min, m.rho_max))
    rate = [float(np.abs(J[k]).sum()) for k in swept]  # |dq_k/drho| summed over the drives
    limits, start = [], []
    for c, h, a in zip(coords, steps, rate):
        limits += [int(max_tilt / h) if c.angular else int(4 * span * a / h)] * 2  # below, above home
        start += [int(math.ceil(35 * DEG / h)) if c.angular else int(math.ceil(0.6 * span * a / h))] * 2
    if step_z < 0.02 or step_tilt < 4 * DEG:
        rough = compute(m, 4 * step_z, 4 * step_tilt, margin, None, max_tilt, [c.name for c in coords])
        ins = rough.inside
        first_last = [
            np.flatnonzero(ins.any(axis=tuple(a for a in range(ins.ndim) if a != d))) for d in range(ins.ndim)
        ]
        extent = []
        for d, idx in enumerate(first_last):
            k = rough.home_index[d]
            extent += [4 * (k - idx.min() + 2), 4 * (idx.max() - k + 2)]
        extent = [min(e, lim) for e, lim in zip(extent, limits)]
    else:
        extent = start
    while True:
        axes = tuple(_axis(home[k], h, extent[2 * d], extent[2 * d + 1]) for d, (k, h) in enumerate(zip(swept, steps)))
        index = tuple(extent[0::2])
        nodes, status, kept = _fill(eng, m, index, sign, margin, axes, progress, home, swept)
        inside = status == INSIDE
        faces = []
        for d in range(len(axes)):
            lo, hi = [slice(None)] * len(axes), [slice(None)] * len(axes)
            lo[d], hi[d] = 0, -1
            faces += [inside[tuple(lo)].any(), inside[tuple(hi)].any()]
        grow = [f and e < lim for f, e, lim in zip(faces, extent, limits)]
        if not any(grow):
            break
        extent = [min(lim, int(math.ceil(e * 1.5))) if g else e for e, g, lim in zip(extent, grow, limits)]
    singular = (status == SINGULAR) | (status == BRANCH)
    sampling = tuple(h * eng.lengths[k] for k, h in zip(swept, steps))
    distance = distance_transform_edt(~singular, sampling=sampling) if singular.any() else np.full(status.shape, np.inf)
    forces = None
    if inside.any() and not m.missing_masses:
        forces = np.full((n,) + status.shape, np.nan)
        grids = _poses(np.meshgrid(*axes, indexing="ij"), home, swept)
        forces[:, inside] = static_forces(eng, [g[inside] for g in grids], nodes.Jinv[inside])
    return Workspace(
        m,
        tuple(home),
        sign,
        margin,
        eng.lengths,
        axes,
        index,
        status,
        nodes.det,
        nodes.parallel,
        nodes.inverse,
        nodes.dexterity,
        distance,
        nodes.rho,
        forces,
        kept,
        time.perf_counter() - t0,
        topology,
        swept,
    )


def home_pose(eng: Engine, m: Machine) -> tuple[float, ...]:
    """The pose of machine ``m`` with every drive at its home joint value rho_0 (its direct kinematics); ValueError
    naming the machine if it does not assemble there."""
    try:
        return tuple(eng.dk(m.rho_home)[0])
    except KinematicsError as exc:
        raise ValueError(f"{m.label}: no home pose for the carriages at rho_0 = {m.rho_home} m: {exc}") from None


# ----------------------------------------------------------------------------- static forces
def static_forces(eng: Engine, q: Sequence[np.ndarray], Jinv: np.ndarray) -> np.ndarray:
    """The drive forces [N; N m rotary] that hold the mechanism (and its payload) at rest at the poses q (n arrays;
    ``Jinv`` (..., n, n) = drho/dq there, from ``Engine.evaluate_many``): its inverse dynamics at zero joint speed
    and acceleration, (n, ...)."""
    zero = [0.0] * eng.n
    return eng.forces_many(q, np.linalg.inv(Jinv), zero, zero)


def held_force(F: np.ndarray, drive: Mapping) -> np.ndarray:
    """The force a drive's guide carries at rest [N]: the mechanism's static force ``F`` plus its carriage's weight
    along the guide (``Machine.drive``'s M_load g_guide; none when the system gives no actuator data)."""
    return F + drive.get("M_load", 0.0) * drive.get("g_guide", 0.0)


def home_static_forces(m: Machine) -> tuple[tuple[float, ...], np.ndarray]:
    """(home pose, the static drive forces there [N; N m rotary], one per drive) of machine ``m`` with its payload;
    ValueError naming the machine if its carriages at rho_0 do not assemble or its masses are not given."""
    if m.missing_masses:
        raise ValueError(f"{m.label}: the mechanism's parameters give no {', '.join(m.missing_masses)}")
    eng = m.engine()
    home = home_pose(eng, m)
    q = [np.array([v]) for v in home]
    _, Jinv, ok = eng.evaluate_many(q)
    if not ok.all():
        raise ValueError(f"{m.label}: the home pose {tuple(home)} does not assemble")
    return tuple(float(v) for v in home), static_forces(eng, q, Jinv)[:, 0]


# ----------------------------------------------------------------------------- one pose
def segment_clear(
    eng: Engine,
    m: Machine,
    q0: Sequence[float],
    q1: Sequence[float],
    sign: float,
    margin: float = MARGIN,
    samples: int = 16,
) -> tuple[bool, str]:
    """Whether the straight path q0 -> q1 (``samples`` + 1 poses, every coordinate) stays inside the local tests;
    why not."""
    a, b = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
    s = np.linspace(0.0, 1.0, samples + 1)
    path = a[:, None] + (b - a)[:, None] * s
    j = _judge(eng, m, list(path), sign, margin)
    bad = np.flatnonzero(j.status != INSIDE)
    if not len(bad):
        return True, ""
    k = bad[0]
    return False, f"{STATUS[j.status[k]]} at {_fmt_pose(path[:, k], eng.description.topology.coordinates)}"


def _fmt_pose(q, coordinates: Sequence[Coordinate]) -> str:
    return ", ".join(
        f"{c.name} = {math.degrees(v):.4g} deg" if c.angular else f"{c.name} = {v:.6g} m"
        for c, v in zip(coordinates, q)
    )


def parse_pose(text: str, topology: Topology) -> tuple[float, ...]:
    """``--pose`` text, one number per coordinate of ``topology`` in m (x, y, z) or deg (the angles), comma-separated
    -> the pose in m and rad. ValueError naming how many numbers and which coordinates were expected."""
    coords = topology.coordinates
    parts = text.split(",")
    try:
        values = [float(v) for v in parts]
    except ValueError:
        values = []
    if len(values) != len(coords) or not all(math.isfinite(v) for v in values):
        form = ",".join(f"{c.name.upper()}_DEG" if c.angular else c.name.upper() for c in coords)
        units = ", ".join("deg" if c.angular else "m" for c in coords)
        example = ",".join(f"{shown(c, v):.3g}" for c, v in zip(coords, topology.home))
        raise ValueError(
            f"--pose {text!r}: expected {form}, {len(coords)} finite numbers ({units}), one per coordinate "
            f"of {topology.name} ({', '.join(topology.names)}), e.g. {example} (home)"
        )
    return tuple(math.radians(v) if c.angular else v for c, v in zip(coords, values))


def column(c: Coordinate) -> str:
    """The name of coordinate ``c`` in the summary and the CSV: ``<name>_deg`` for an angle, ``<name>_m``."""
    return f"{c.name}_deg" if c.angular else f"{c.name}_m"


def shown(c: Coordinate, value: float) -> float:
    """``value`` [m or rad] of coordinate ``c`` as the summary and the CSV give it (m or deg)."""
    return math.degrees(value) if c.angular else float(value)


def classify(ws: Workspace, q: Sequence[float]) -> dict:
    """Is pose q (every coordinate of the mechanism in its order and SI unit: for the 3PRS z [m], psi [rad],
    theta [rad]) inside the workspace ``ws``? Its margins and, if not, why.

    Inside: it passes the local tests and a straight path to a neighbouring node of the grid that is
    inside (one of its cell's corners, nearest first) passes them too (``segment_clear``). ValueError if q
    has not one value per coordinate or leaves a held coordinate's value (the grid's section).
    """
    m = ws.machine
    eng = m.engine()
    coords = ws.coordinates
    q = tuple(float(v) for v in q)
    if len(q) != len(coords):
        raise ValueError(
            f"pose {q!r}: expected {len(coords)} values, one per coordinate ({', '.join(c.name for c in coords)})"
        )
    off = [c.name for k, c in enumerate(coords) if k not in ws.swept and q[k] != ws.home[k]]
    if off:
        held = [c for c in coords if c.name in off]
        raise ValueError(
            f"pose {_fmt_pose(q, coords)}: this workspace holds {', '.join(off)} at home "
            f"({_fmt_pose([ws.home[k] for k, c in enumerate(coords) if c.name in off], held)}); "
            "sweep it to ask about other values"
        )
    j = _judge(eng, m, [np.array([v]) for v in q], ws.sign, ws.margin)
    code = int(j.status[0])
    out = {"pose": {column(c): shown(c, v) for c, v in zip(coords, q)}, "inside": False, "reason": ""}
    if code != UNASSEMBLABLE:
        out[f"rho_{_drive_suffix(ws)}"] = [float(v) for v in j.rho[:, 0]]
        out.update(
            {
                "det": float(j.det[0]),
                "margin_parallel": float(j.parallel[0]),
                "margin_inverse": float(j.inverse[0]),
                "dexterity": float(j.dexterity[0]),
            }
        )
    else:
        try:
            eng.ik(q)
            out["reason"] = "not assemblable"
        except KinematicsError as exc:
            out["reason"] = f"not assemblable: {exc}"
    if code != INSIDE:
        out["reason"] = out["reason"] or STATUS[code]
        return out
    corners = []
    for axis, k in zip(ws.axes, ws.swept):
        i = int(np.clip(np.searchsorted(axis, q[k]) - 1, 0, len(axis) - 2))
        corners.append((i, i + 1))
    cand = [idx for idx in itertools.product(*corners) if ws.status[idx] == INSIDE]
    scale = np.asarray(ws.lengths)
    cand.sort(key=lambda idx: float(np.linalg.norm((ws.pose(idx) - q) * scale)))
    why = "no corner of its grid cell is inside the workspace"
    for idx in cand:
        ok, why = segment_clear(eng, m, q, ws.pose(idx), ws.sign, ws.margin)
        if ok:
            out["inside"] = True
            out["distance_to_singularity_m"] = float(ws.distance[idx])
            return out
    out["reason"] = f"not connected to home: {why}"
    return out


# ----------------------------------------------------------------------------- summary and files
def _drive_suffix(ws: Workspace, force: bool = False) -> str:
    """The unit in the summary's joint (force) keys: m (N) when every drive is linear, rad (Nm) when every one is
    rotary, si for a mix (each drive's own unit)."""
    kinds = {d.kind for d in ws.mechanism.drives}
    if kinds == {"linear"}:
        return "N" if force else "m"
    if kinds == {"rotary"}:
        return "Nm" if force else "rad"
    return "si"


def _run(ws: Workspace, axis: int) -> tuple[float, float]:
    """Range of coordinate ``axis`` inside the workspace along the line through home."""
    line = [slice(i, i + 1) for i in ws.home_index]
    line[axis] = slice(None)
    ins = ws.inside[tuple(line)].ravel()
    k = ws.home_index[axis]
    lo = k
    while lo > 0 and ins[lo - 1]:
        lo -= 1
    hi = k
    while hi < len(ins) - 1 and ins[hi + 1]:
        hi += 1
    return float(ws.axes[axis][lo]), float(ws.axes[axis][hi])


def _at(ws: Workspace, flat: int) -> dict:
    i = np.unravel_index(flat, ws.status.shape)
    return {column(c): shown(c, ws.axes[d][i[d]]) for d, c in enumerate(ws.swept_coordinates)}


def _neighbours(ws: Workspace):
    """(axis, shift, valid): the nodes' neighbours along every axis, valid False where the roll wrapped around."""
    for axis in range(ws.status.ndim):
        for shift in (1, -1):
            edge = [slice(None)] * ws.status.ndim
            edge[axis] = slice(0, 1) if shift == 1 else slice(-1, None)
            valid = np.ones(ws.status.shape, dtype=bool)
            valid[tuple(edge)] = False
            yield axis, shift, valid


def _boundary(ws: Workspace) -> dict:
    """What limits the workspace: the status of the outside neighbours of inside nodes, counted."""
    ins = ws.inside
    counts = np.zeros(len(STATUS), dtype=int)
    for axis, shift, valid in _neighbours(ws):
        nb = np.roll(ws.status, shift, axis=axis)
        hit = ins & valid & (nb != INSIDE)
        counts += np.bincount(nb[hit], minlength=len(STATUS))
    total = counts.sum()
    return {STATUS[k]: round(float(counts[k] / total), 4) for k in range(1, len(STATUS)) if total and counts[k]}


def volume_unit(ws: Workspace, angle: str = "rad") -> str:
    """The unit of the workspace's volume, as in its summary's keys: for the 3PRS m_rad2 (``angle`` "deg": m_deg2)."""
    lengths = sum(not c.angular for c in ws.swept_coordinates)
    angles = len(ws.swept) - lengths
    return "_".join(u + (str(k) if k > 1 else "") for u, k in (("m", lengths), (angle, angles)) if k)


def unit_text(unit: str) -> str:
    """A unit as the summary's keys write it, for reading: m_deg2 -> "m deg^2"."""
    return " ".join(p[:-1] + "^" + p[-1] if p[-1].isdigit() else p for p in unit.split("_"))


def summarize(ws: Workspace) -> dict:
    m = ws.machine
    ins = ws.inside
    coords = ws.swept_coordinates
    n = int(ins.sum())
    flat = np.flatnonzero(ins.ravel())
    smallest = np.minimum(ws.parallel, ws.inverse).ravel()[flat]
    dex = ws.dexterity.ravel()[flat]
    dist = ws.distance.ravel()[flat]
    hi_ = ws.home_index
    joints, force = _drive_suffix(ws), _drive_suffix(ws, force=True)
    volume, volume_deg = float(n), float(n)
    for c, step in zip(coords, ws.steps):
        volume *= step
        volume_deg *= shown(c, step)
    grid = {}  # the steps of the length coordinates (--step-z) and of the angles (--step-tilt)
    lengths = [step for c, step in zip(coords, ws.steps) if not c.angular]
    angles = [step for c, step in zip(coords, ws.steps) if c.angular]
    if lengths:
        grid["step_z_m"] = lengths[0]
    if angles:
        grid["step_tilt_deg"] = math.degrees(angles[0])
    if ws.held:
        grid["held_at_home"] = {
            column(c): shown(c, ws.home[k]) for k, c in enumerate(ws.coordinates) if k not in ws.swept
        }
    grid.update(
        {
            "box": {column(c): [shown(c, ws.axes[d][0]), shown(c, ws.axes[d][-1])] for d, c in enumerate(coords)},
            "nodes": int(ws.status.size),
            "kept_edges": int(sum(k.sum() for k in ws.kept)),
        }
    )
    others = lambda d: tuple(a for a in range(ins.ndim) if a != d)  # noqa: E731
    extent = {}
    for d, c in enumerate(coords):
        reached = ws.axes[d][np.flatnonzero(ins.any(axis=others(d)))]
        extent[column(c)] = [shown(c, reached.min()), shown(c, reached.max())]
    out = {
        "design": m.label,
        "payload_kg": m.payload_kg,
        "home": {
            f"rho_{joints}": list(m.rho_home),
            **{column(c): shown(c, v) for c, v in zip(ws.coordinates, ws.home)},
            "det": float(ws.det[hi_]),
            "margin_parallel": float(ws.parallel[hi_]),
            "margin_inverse": float(ws.inverse[hi_]),
            "dexterity": float(ws.dexterity[hi_]),
        },
        f"strokes_{joints}": {"rho_min": list(m.rho_min), "rho_max": list(m.rho_max)},
        "margin_limit": ws.margin,
        "coordinate_lengths_m": list(ws.lengths),
        "grid": grid,
        "poses_inside": n,
        f"volume_{volume_unit(ws)}": volume,
        f"volume_{volume_unit(ws, 'deg')}": volume_deg,
        "ranges_through_home": {column(c): [shown(c, v) for v in _run(ws, d)] for d, c in enumerate(coords)},
        "extent": extent,
        "worst_dexterity": {"value": float(dex.max()), "at": _at(ws, int(flat[np.argmax(dex)]))},
        "smallest_margin": {
            "value": float(smallest.min()),
            "at": _at(ws, int(flat[np.argmin(smallest)])),
            "kind": "parallel"
            if ws.parallel.ravel()[flat[np.argmin(smallest)]] <= ws.inverse.ravel()[flat[np.argmin(smallest)]]
            else "inverse",
        },
        "smallest_distance_to_singularity_m": (
            None
            if not np.isfinite(dist.min())
            else {"value": float(dist.min()), "at": _at(ws, int(flat[np.argmin(dist)]))}
        ),
        "distance_to_singularity_at_home_m": (None if not np.isfinite(ws.distance[hi_]) else float(ws.distance[hi_])),
        "largest_carriage_speed_per_platform_speed": float((1.0 / ws.inverse.ravel()[flat]).max()),
        "limited_by": _boundary(ws),
        "wall_time_s": round(ws.wall_time_s, 2),
    }
    if ws.machine.missing_masses:
        out["static_forces"] = {
            "not_computed": f"the mechanism's parameters give no {', '.join(ws.machine.missing_masses)}: "
            "the workspace and its margins are kinematic, the static forces unknown"
        }
    if ws.forces is not None:
        F = ws.forces.reshape(len(ws.forces), -1)[:, flat]
        peak = np.abs(F).max(axis=0)
        out["static_forces"] = {
            f"home_{force}": [float(v) for v in ws.forces[(slice(None),) + hi_]],
            f"largest_{force}": float(peak.max()),
            "at": _at(ws, int(flat[np.argmax(peak)])),
        }
        d = m.drive
        if d:
            # motor torque holding the carriage and its share of the mechanism at rest (friction left out)
            tau = np.abs(held_force(F, d)).max(axis=0) * d["p"] / (2 * math.pi * d["i_r"])
            peak_torque = d["k_T"] * d["i_max"]
            out["static_forces"].update(
                {
                    "largest_motor_torque_Nm": float(tau.max()),
                    "at_largest_torque": _at(ws, int(flat[np.argmax(tau)])),
                    "motor_peak_torque_Nm": peak_torque,
                    "largest_torque_fraction_of_peak": float(tau.max() / peak_torque),
                    "fraction_of_poses_beyond_peak_torque": float(np.mean(tau > peak_torque)),
                }
            )
    return out


def csv_columns(ws: Workspace) -> tuple[str, ...]:
    """The columns of workspace.csv: the swept coordinates (m, deg), the status, each drive's joint (rho_k in m, or
    rad for a rotary drive), the margins, each drive's static force (F_k in N, or Nm). For the 3PRS: z_m,
    psi_deg, theta_deg, status, inside, rho_1_m .. rho_3_m, det, ..., F_1_N .. F_3_N."""
    drives = ws.mechanism.drives
    return (
        *(column(c) for c in ws.swept_coordinates),
        "status",
        "inside",
        *(f"{d.name}_{d.unit}" for d in drives),
        "det",
        "margin_parallel",
        "margin_inverse",
        "dexterity",
        "distance_to_singularity_m",
        *(f"F_{k}_{'N' if d.kind == 'linear' else 'Nm'}" for k, d in enumerate(drives, 1)),
    )


def _layer(ws: Workspace) -> np.ndarray:
    """The workspace and the nodes next to it (its boundary layer)."""
    ins = ws.inside
    near = ins.copy()
    for axis, shift, valid in _neighbours(ws):
        near |= np.roll(ins, shift, axis=axis) & valid
    return near


def write(ws: Workspace, out: Union[str, Path], plots: bool = True) -> list[Path]:
    """DIR/workspace.json, DIR/workspace.csv (the workspace and its boundary layer), DIR/workspace.png."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    summary = summarize(ws)
    (out / "workspace.json").write_text(json.dumps(summary, indent=2))
    files = [out / "workspace.json"]
    sel = np.flatnonzero(_layer(ws).ravel())
    idx = np.unravel_index(sel, ws.status.shape)
    n = len(ws.rho)
    F = ws.forces.reshape(n, -1)[:, sel] if ws.forces is not None else np.full((n, len(sel)), np.nan)
    coords = ws.swept_coordinates
    cols = [np.degrees(ws.axes[d][idx[d]]) if c.angular else ws.axes[d][idx[d]] for d, c in enumerate(coords)]
    status = ws.status.ravel()[sel]
    rho = ws.rho.reshape(n, -1)[:, sel]
    vals = [ws.det, ws.parallel, ws.inverse, ws.dexterity, ws.distance]
    with open(out / "workspace.csv", "w", newline="") as handle:
        w = csv.writer(handle)
        w.writerow(csv_columns(ws))
        data = np.column_stack(cols + list(rho) + [v.ravel()[sel] for v in vals] + list(F))
        k = len(cols)
        for row, st in zip(data, status):
            text = [f"{v:.6g}" if np.isfinite(v) else ("inf" if v > 0 else "") for v in row]
            w.writerow(text[:k] + [STATUS[st], int(st == INSIDE)] + text[k:])
    files.append(out / "workspace.csv")
    if plots:
        files.append(plot(ws, out / "workspace.png"))
    return files


_COLOURS = {
    UNASSEMBLABLE: "#4d4d4d",
    STROKE: "#bdbdbd",
    SINGULAR: "#d62728",
    BRANCH: "#ff7f0e",
    DISCONNECTED: "#e377c2",
}


def plot(ws: Workspace, path: Path) -> Path:
    """Sections through home and the boundary in 3-D (three swept coordinates: for the 3PRS z-psi, z-theta, and
    psi-theta at four heights), the one section (two), the margin along the line (one)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    coords = ws.swept_coordinates
    g = [np.degrees(a) if c.angular else a for c, a in zip(coords, ws.axes)]  # the grids as shown (m, deg)
    label = [f"{c.name} [{'deg' if c.angular else 'm'}]" for c in coords]

    def at(d: int, i: int) -> str:
        c = coords[d]
        return f"{c.name} = {g[d][i]:.3g} deg" if c.angular else f"{c.name} = {g[d][i]:.4g} m"

    smallest = np.minimum(ws.parallel, ws.inverse)
    vmax = float(np.nanmax(np.where(ws.inside, smallest, np.nan))) if ws.inside.any() else 1.0
    cmap_out = ListedColormap([_COLOURS.get(k, "white") for k in range(len(STATUS))])

    def section(ax, st, val, x, y, xlabel, ylabel, title):
        ax.pcolormesh(x, y, st.T, cmap=cmap_out, vmin=-0.5, vmax=len(STATUS) - 0.5, shading="nearest")
        im = ax.pcolormesh(
            x, y, np.where(st == INSIDE, val, np.nan).T, cmap="viridis", vmin=ws.margin, vmax=vmax, shading="nearest"
        )
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=9)
        return im

    h = ws.home_index
    if len(coords) == 3:
        fig = plt.figure(figsize=(16, 9))
        ax1 = fig.add_subplot(2, 4, 1)
        im = section(ax1, ws.status[:, :, h[2]], smallest[:, :, h[2]], g[0], g[1], label[0], label[1], at(2, h[2]))
        ax2 = fig.add_subplot(2, 4, 2)
        section(ax2, ws.status[:, h[1], :], smallest[:, h[1], :], g[0], g[2], label[0], label[2], at(1, h[1]))
        for a, y in ((ax1, g[1][h[1]]), (ax2, g[2][h[2]])):
            a.plot([g[0][h[0]]], [y], "w+", ms=10, mew=2)
        ins_0 = np.flatnonzero(ws.inside.any(axis=(1, 2)))
        spread = np.linspace(ins_0.min(), ins_0.max(), 5).round().astype(int)[1:-1] if len(ins_0) else []
        levels = sorted({int(v) for v in spread} | {h[0]})
        for k, i0 in enumerate(levels[:4]):
            ax = fig.add_subplot(2, 4, 5 + k)
            section(
                ax,
                ws.status[i0],
                smallest[i0],
                g[1],
                g[2],
                label[1],
                label[2],
                at(0, i0) + (" (home)" if i0 == h[0] else ""),
            )
            ax.set_aspect("equal")
        ax3 = fig.add_subplot(2, 4, (3, 4), projection="3d")
        layer = _layer(ws) & ~ws.inside
        for code, colour in _COLOURS.items():
            sel = layer & (ws.status == code)
            if sel.any():
                i = np.nonzero(sel)
                step = max(1, len(i[0]) // 4000)
                ax3.scatter(
                    g[1][i[1]][::step],
                    g[2][i[2]][::step],
                    g[0][i[0]][::step],
                    s=2,
                    c=colour,
                    alpha=0.5,
                    depthshade=False,
                )
        ax3.set_xlabel(label[1])
        ax3.set_ylabel(label[2])
        ax3.set_zlabel(label[0])
        ax3.set_title("boundary: what stops the workspace", fontsize=9)
        fig.colorbar(im, ax=ax2, label="smallest singularity margin [m/m] (inside)")
    else:
        fig = plt.figure(figsize=(10, 7))
        ax = fig.add_subplot(1, 1, 1)
        if len(coords) == 2:
            im = section(ax, ws.status, smallest, g[0], g[1], label[0], label[1], "through home")
            ax.plot([g[0][h[0]]], [g[1][h[1]]], "w+", ms=10, mew=2)
            fig.colorbar(im, ax=ax, label="smallest singularity margin [m/m] (inside)")
        else:
            ax.plot(g[0], np.where(ws.inside, smallest, np.nan), "-", color="tab:green", label="inside")
            for code, colour in _COLOURS.items():
                sel = ws.status == code
                ax.plot(g[0][sel], np.zeros(int(sel.sum())), "s", color=colour, ms=4)
            ax.axvline(g[0][h[0]], color="k", lw=0.8)
            ax.set_xlabel(label[0])
            ax.set_ylabel("smallest singularity margin [m/m]")
            ax.set_title("along the line through home", fontsize=9)
    fig.legend(
        handles=[Patch(color=c, label=STATUS[k]) for k, c in _COLOURS.items()], loc="lower center", ncol=5, fontsize=8
    )
    s = summarize(ws)
    unit = volume_unit(ws, "deg")
    held = ", ".join(
        f"{c.name} = {shown(c, v):.4g} {'deg' if c.angular else 'm'}"
        for c, v in ((ws.coordinates[k], ws.home[k]) for k in range(len(ws.home)) if k not in ws.swept)
    )
    first = coords[0]
    fig.suptitle(
        f"{ws.machine.label}: workspace {s[f'volume_{unit}']:.4g} {unit_text(unit)} ({s['poses_inside']} poses), "
        f"home {first.name} = {shown(first, ws.home[ws.swept[0]]):.4g} {'deg' if first.angular else 'm'}"
        + (f" ({held} held)" if held else "")
        + f"; smallest margin {s['smallest_margin']['value']:.3g} m/m, "
        f"worst dexterity {s['worst_dexterity']['value']:.3g}; margin limit {ws.margin:g} m/m",
        **({} if len(coords) == 3 else {"fontsize": 8}),
    )
    if len(coords) == 3:
        fig.subplots_adjust(left=0.05, right=0.97, top=0.92, bottom=0.1, hspace=0.3, wspace=0.35)
    else:
        fig.subplots_adjust(left=0.1, right=0.97, top=0.9, bottom=0.14)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
