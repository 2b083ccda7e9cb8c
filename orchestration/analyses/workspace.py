"""`mast workspace`: the poses a mechanism design can really reach (docs/workspace.md).

The workspace of a design is the set of poses q = (z, psi, theta) that

- the mechanism can assemble (the description's checks: working assembly, leg reach, tilt range),
- put every carriage within its stroke [rho_min, rho_max] (the actuators' parameter sets),
- lie at least ``engine.MARGIN`` from a singularity of either kind (``Engine.margins``: the
  parallel margin, smallest singular value of drho/dq~, and the inverse margin, smallest
  singular value of dq~/drho, with q~ = (z, r psi, r theta)),
- lie on the assembly branch of the home pose (det(drho/dq) of the same sign), and
- are connected to the home pose (all carriages at rho_0) by a path that keeps all of this.

It is computed on a grid around home: every node and the midpoint of every edge between
neighbouring nodes is judged (the generated kinematics of the engine on arrays); an edge is
kept when both its nodes and its midpoint pass, and the workspace is the connected component
of home in the graph of kept edges (a flood fill from home). The box grows while the workspace
touches it. Per node: the margins, the dexterity (2-norm condition number of drho/dq~), the
distance [m of platform motion, tilts counted as r times the angle] to the nearest sampled
pose that is within the margin of a singularity or on the other branch, and the static
actuator forces with an optional payload (the engine's inverse dynamics at rest) with the
carriage speed a unit platform speed needs.

Outputs (``write``): DIR/workspace.json (summary), DIR/workspace.csv (the workspace and its
boundary layer, one row per sampled pose), DIR/workspace.png (sections and the boundary).
``classify`` answers for one pose.
"""
from __future__ import annotations

import csv
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence, Union

import numpy as np

from fmus.mechanism.designs import MASS_PARAMETERS, engine as design_engine
from fmus.mechanism.engine import MARGIN, Engine, margins_of
from fmus.mechanism.kinematics import KinematicsError

REPO = Path(__file__).resolve().parents[2]
BASE_SSD = REPO / "ssp" / "MAST.ssd"
DEG = math.pi / 180.0
#: the bodies' mass parameters (fmus.mechanism.designs.MASS_PARAMETERS): without them the workspace is kinematic
BODY_MASSES = ("m_leg", "I_leg", "m_platform", "I_px", "I_py", "I_pz")

#: node status codes (``Workspace.status``)
INSIDE, UNASSEMBLABLE, STROKE, SINGULAR, BRANCH, DISCONNECTED = range(6)
STATUS = ("inside", "not assemblable", "outside the stroke", "within the margin of a singularity",
          "on the other assembly branch", "not connected to home")
#: default grid steps: 5 mm in z, 1 deg in psi and theta (about 10 s per design on one core)
STEP_Z = 0.005
STEP_TILT_DEG = 1.0
#: tolerance on the stroke limits [m] (a carriage exactly at its end is within the stroke)
STROKE_TOL = 1e-12


# ----------------------------------------------------------------------------- the machine
@dataclass(frozen=True)
class Machine:
    """What the workspace needs of a design: the mechanism's parameters, the strokes, home, the drives.

    rho_min, rho_max, rho_home: per joint [m]; drive: per-joint-identical actuator data for the
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

    @property
    def missing_masses(self) -> tuple[str, ...]:
        """The mass parameters the mechanism's parameters do not give (a user's own mechanism FMU, e.g. the
        lumped one of docs/interfaces.md): its workspace is then kinematic only, with no static forces."""
        return tuple(p.name for p in MASS_PARAMETERS if p.name in BODY_MASSES and p.name not in self.params)

    def engine(self) -> Engine:
        params = dict(self.params)
        if self.payload_kg:
            params["m_payload"] = float(params.get("m_payload", 0.0)) + self.payload_kg
        return design_engine(params, self.label, masses=not self.missing_masses)


def _from_system(label: str, system, mechanism: Optional[Mapping] = None, payload: float = 0.0) -> Machine:
    comps = system.components
    mech = dict(mechanism if mechanism is not None else comps["mechanism"].parameters)
    acts = [comps[n].parameters for n in sorted(comps) if n.startswith("actuator")]
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
        if mechanism is not None and "beta" in mech and "g" in mech:     # an FMU swapped in: g cos(beta)
            drive["g_guide"] = float(mech["g"]) * math.cos(float(mech["beta"]))
    if not (math.isfinite(payload) and payload >= 0.0):
        raise ValueError(f"--payload {payload!r}: expected a finite mass >= 0 kg")
    return Machine(label, mech, tuple(float(a["rho_min"]) for a in acts), tuple(float(a["rho_max"]) for a in acts),
                   tuple(float(a["rho_0"]) for a in acts), drive, float(payload))


def machine(design: Union[str, Path], payload: float = 0.0, mechanism: Optional[Mapping] = None) -> Machine:
    """The machine of a design name (``mast.core.designs``), a system (.ssd/.ssp) or a mechanism FMU (swapped into
    ssp/MAST.ssd with its own defaults, as ``mast compare`` does). ``mechanism``: parameters that replace
    the system's mechanism parameters (an FMU's defaults)."""
    from ..core.designs import DESIGNS
    from ..core.ssp import SSPArchive, read_ssd

    named = {d.name: d for d in DESIGNS} | {d.model_identifier: d for d in DESIGNS}
    text = str(design)
    if text in named:
        d = named[text]
        return _from_system(d.name, read_ssd(d.ssd), mechanism, payload)
    path = Path(text)
    if not path.exists():
        raise ValueError(f"design {text!r}: neither a design ({', '.join(d.name for d in DESIGNS)}) nor a file")
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
    status: np.ndarray          # int8 status codes (INSIDE: passes every local test)
    rho: np.ndarray             # (n, ...)
    Jinv: np.ndarray            # (..., n, n)
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
    """A sampled workspace (module docstring); arrays are indexed [z, psi, theta] like ``axes``."""

    machine: Machine
    home: tuple                 # (z [m], psi [rad], theta [rad])
    sign: float                 # sign of det(drho/dq) at home: the working branch
    margin: float               # MARGIN used [m/m]
    lengths: tuple              # the engine's coordinate lengths (1, r, r)
    axes: tuple                 # (z [m], psi [rad], theta [rad]) 1-D
    home_index: tuple
    status: np.ndarray
    det: np.ndarray
    parallel: np.ndarray
    inverse: np.ndarray
    dexterity: np.ndarray
    distance: np.ndarray        # [m] to the nearest sampled singular (margin or branch) pose; inf: none in the box
    rho: np.ndarray             # (3, ...)
    forces: Optional[np.ndarray] = None    # (3, ...) static actuator forces [N], inside only (NaN elsewhere)
    kept: tuple = ()            # per axis, the edges of the workspace's graph (both nodes and the midpoint pass)
    wall_time_s: float = 0.0

    @property
    def inside(self) -> np.ndarray:
        return self.status == INSIDE

    @property
    def steps(self) -> tuple:
        return tuple(float(a[1] - a[0]) for a in self.axes)

    def summary(self) -> dict:
        return summarize(self)


def _axis(centre: float, step: float, below: int, above: int) -> np.ndarray:
    return centre + step * np.arange(-below, above + 1, dtype=float)


def _kept(inside_nodes: np.ndarray, mids_ok: Sequence[np.ndarray]) -> tuple[np.ndarray, ...]:
    """Per axis, the edges kept: both nodes and the midpoint pass (shape: one less along that axis)."""
    out = []
    for axis, mid in enumerate(mids_ok):
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        out.append(inside_nodes[tuple(lo)] & inside_nodes[tuple(hi)] & mid)
    return tuple(out)


def _pairs(kept: Sequence[np.ndarray], shape: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Flat node indices (a, b) of the kept edges."""
    idx = np.arange(int(np.prod(shape))).reshape(shape)
    a_all, b_all = [], []
    for axis, keep in enumerate(kept):
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        a_all.append(idx[tuple(lo)][keep])
        b_all.append(idx[tuple(hi)][keep])
    return np.concatenate(a_all), np.concatenate(b_all)


def _fill(eng: Engine, m: Machine, home_index: tuple, sign: float, margin: float, axes: tuple,
          progress: Optional[Callable[[float], None]]) -> tuple:
    """Judge the nodes and edge midpoints of the grid ``axes``: (nodes, status with the nodes not connected to
    home marked, the kept edges of the workspace per axis)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    z, ps, th = axes
    shape = (len(z), len(ps), len(th))
    mids = []
    # work in slabs of z (memory, progress): nodes, then the midpoints along z, psi, theta
    total = 4 * len(z)
    done = 0

    def tick(k: int = 1) -> None:
        nonlocal done
        done += k
        if progress:
            progress(min(done / total, 1.0))

    parts = []
    for i in range(len(z)):
        parts.append(_judge(eng, m, np.meshgrid(z[i:i + 1], ps, th, indexing="ij"), sign, margin))
        tick()
    nodes = _Judged(*(np.concatenate([getattr(p, f) for p in parts], axis=1 if f == "rho" else 0)
                      for f in _Judged.__dataclass_fields__))
    del parts
    zm = 0.5 * (z[:-1] + z[1:])
    mid_z = [np.zeros((0,) + shape[1:], dtype=bool)]
    for i in range(len(zm)):
        mid_z.append(_judge(eng, m, np.meshgrid(zm[i:i + 1], ps, th, indexing="ij"), sign, margin).status == INSIDE)
        tick()
    tick()
    mids.append(np.concatenate(mid_z, axis=0))
    pm, tm = 0.5 * (ps[:-1] + ps[1:]), 0.5 * (th[:-1] + th[1:])
    mid_p, mid_t = [], []
    for i in range(len(z)):
        mid_p.append(_judge(eng, m, np.meshgrid(z[i:i + 1], pm, th, indexing="ij"), sign, margin).status == INSIDE)
        mid_t.append(_judge(eng, m, np.meshgrid(z[i:i + 1], ps, tm, indexing="ij"), sign, margin).status == INSIDE)
        tick(2)
    mids += [np.concatenate(mid_p, axis=0), np.concatenate(mid_t, axis=0)]
    ok = nodes.status == INSIDE
    kept = _kept(ok, mids)
    a, b = _pairs(kept, shape)
    n = ok.size
    graph = coo_matrix((np.ones(len(a), dtype=np.int8), (a, b)), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    home_flat = np.ravel_multi_index(home_index, shape)
    if not ok.ravel()[home_flat]:
        raise ValueError(f"{m.label}: the home pose is not inside the workspace: {STATUS[nodes.status.ravel()[home_flat]]}")
    connected = (labels == labels[home_flat]).reshape(shape)
    status = nodes.status.copy()
    status[ok & ~connected] = DISCONNECTED
    return nodes, status, _kept(status == INSIDE, kept)


def compute(m: Machine, step_z: float = STEP_Z, step_tilt: float = STEP_TILT_DEG * DEG, margin: float = MARGIN,
            progress: Optional[Callable[[float], None]] = None, max_tilt: float = 90 * DEG) -> Workspace:
    """The workspace of machine ``m`` on a grid of steps ``step_z`` [m], ``step_tilt`` [rad] (module docstring)."""
    from scipy.ndimage import distance_transform_edt

    for name, v in (("step_z", step_z), ("step_tilt", step_tilt)):
        if not (math.isfinite(v) and v > 0.0):
            raise ValueError(f"workspace: {name} = {v!r}: expected a finite step > 0")
    t0 = time.perf_counter()
    eng = m.engine()
    try:
        home = eng.dk(m.rho_home)[0]
    except KinematicsError as exc:
        raise ValueError(f"{m.label}: no home pose for the carriages at rho_0 = {m.rho_home} m: {exc}") from None
    sign = math.copysign(1.0, eng.margins(home).det)
    # the box: the heave all carriages' strokes allow (from the home Jacobian) and +-35 deg of tilt, or
    # on a fine grid the extent of a pass 4 times coarser (1/64 of the work) with two of its steps around
    J = np.array(eng.jacobian(home)[1]).reshape(3, 3)
    span = max(hi - lo for lo, hi in zip(m.rho_min, m.rho_max))
    limits = [int(4 * span * abs(J[0].sum()) / step_z)] * 2 + [int(max_tilt / step_tilt)] * 4   # z-, z+, psi-, ...
    if step_z < 0.02 or step_tilt < 4 * DEG:
        rough = compute(m, 4 * step_z, 4 * step_tilt, margin, None, max_tilt)
        ins = rough.inside
        first_last = [np.flatnonzero(ins.any(axis=tuple(a for a in range(3) if a != d))) for d in range(3)]
        extent = []
        for d, idx in enumerate(first_last):
            k = rough.home_index[d]
            extent += [4 * (k - idx.min() + 2), 4 * (idx.max() - k + 2)]
        extent = [min(e, lim) for e, lim in zip(extent, limits)]
    else:
        extent = [int(math.ceil(0.6 * span * abs(J[0].sum()) / step_z))] * 2 + \
            [int(math.ceil(35 * DEG / step_tilt))] * 4
    while True:
        axes = (_axis(home[0], step_z, extent[0], extent[1]), _axis(home[1], step_tilt, extent[2], extent[3]),
                _axis(home[2], step_tilt, extent[4], extent[5]))
        index = (extent[0], extent[2], extent[4])
        nodes, status, kept = _fill(eng, m, index, sign, margin, axes, progress)
        inside = status == INSIDE
        faces = (inside[0].any(), inside[-1].any(), inside[:, 0].any(), inside[:, -1].any(),
                 inside[:, :, 0].any(), inside[:, :, -1].any())
        grow = [f and e < lim for f, e, lim in zip(faces, extent, limits)]
        if not any(grow):
            break
        extent = [min(lim, int(math.ceil(e * 1.5))) if g else e for e, g, lim in zip(extent, grow, limits)]
    singular = (status == SINGULAR) | (status == BRANCH)
    steps = (step_z * eng.lengths[0], step_tilt * eng.lengths[1], step_tilt * eng.lengths[2])
    distance = (distance_transform_edt(~singular, sampling=steps) if singular.any()
                else np.full(status.shape, np.inf))
    forces = None
    if inside.any() and not m.missing_masses:
        forces = np.full((3,) + status.shape, np.nan)
        Jq = np.linalg.inv(nodes.Jinv[inside])
        grids = np.meshgrid(*axes, indexing="ij")
        zero = [0.0] * 3
        forces[:, inside] = eng.forces_many([g[inside] for g in grids], Jq, zero, zero)
    return Workspace(m, tuple(home), sign, margin, eng.lengths, axes, index, status, nodes.det, nodes.parallel,
                     nodes.inverse, nodes.dexterity, distance, nodes.rho, forces, kept, time.perf_counter() - t0)


# ----------------------------------------------------------------------------- one pose
def segment_clear(eng: Engine, m: Machine, q0: Sequence[float], q1: Sequence[float], sign: float,
                  margin: float = MARGIN, samples: int = 16) -> tuple[bool, str]:
    """Whether the straight path q0 -> q1 (``samples`` + 1 poses) stays inside the local tests; why not."""
    a, b = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
    s = np.linspace(0.0, 1.0, samples + 1)
    path = a[:, None] + (b - a)[:, None] * s
    j = _judge(eng, m, list(path), sign, margin)
    bad = np.flatnonzero(j.status != INSIDE)
    if not len(bad):
        return True, ""
    k = bad[0]
    return False, f"{STATUS[j.status[k]]} at {_fmt_pose(path[:, k])}"


def _fmt_pose(q) -> str:
    return f"z = {q[0]:.6g} m, psi = {math.degrees(q[1]):.4g} deg, theta = {math.degrees(q[2]):.4g} deg"


def classify(ws: Workspace, q: Sequence[float]) -> dict:
    """Is pose q = (z [m], psi [rad], theta [rad]) inside the workspace ``ws``? Its margins and, if not, why.

    Inside: it passes the local tests and a straight path to a neighbouring node of the grid that is
    inside (one of its cell's corners, nearest first) passes them too (``segment_clear``).
    """
    m = ws.machine
    eng = m.engine()
    q = tuple(float(v) for v in q)
    j = _judge(eng, m, [np.array([v]) for v in q], ws.sign, ws.margin)
    code = int(j.status[0])
    out = {"pose": {"z_m": q[0], "psi_deg": math.degrees(q[1]), "theta_deg": math.degrees(q[2])},
           "inside": False, "reason": ""}
    if code != UNASSEMBLABLE:
        out["rho_m"] = [float(v) for v in j.rho[:, 0]]
        out.update({"det": float(j.det[0]), "margin_parallel": float(j.parallel[0]),
                    "margin_inverse": float(j.inverse[0]), "dexterity": float(j.dexterity[0])})
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
    for axis, v in zip(ws.axes, q):
        k = int(np.clip(np.searchsorted(axis, v) - 1, 0, len(axis) - 2))
        corners.append((k, k + 1))
    cand = [(a, b, c) for a in corners[0] for b in corners[1] for c in corners[2] if ws.status[a, b, c] == INSIDE]
    scale = np.asarray(ws.lengths)
    node = lambda idx: np.array([ws.axes[d][idx[d]] for d in range(3)])   # noqa: E731
    cand.sort(key=lambda idx: float(np.linalg.norm((node(idx) - q) * scale)))
    why = "no corner of its grid cell is inside the workspace"
    for idx in cand:
        ok, why = segment_clear(eng, m, q, node(idx), ws.sign, ws.margin)
        if ok:
            out["inside"] = True
            out["distance_to_singularity_m"] = float(ws.distance[idx])
            return out
    out["reason"] = f"not connected to home: {why}"
    return out


# ----------------------------------------------------------------------------- summary and files
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
    return {"z_m": float(ws.axes[0][i[0]]), "psi_deg": math.degrees(ws.axes[1][i[1]]),
            "theta_deg": math.degrees(ws.axes[2][i[2]])}


def _boundary(ws: Workspace) -> dict:
    """What limits the workspace: the status of the outside neighbours of inside nodes, counted."""
    ins = ws.inside
    counts = np.zeros(len(STATUS), dtype=int)
    for axis in range(3):
        for shift in (1, -1):
            nb = np.roll(ws.status, shift, axis=axis)
            edge = [slice(None)] * 3
            edge[axis] = slice(0, 1) if shift == 1 else slice(-1, None)
            valid = np.ones_like(ins)
            valid[tuple(edge)] = False
            hit = ins & valid & (nb != INSIDE)
            counts += np.bincount(nb[hit], minlength=len(STATUS))
    total = counts.sum()
    return {STATUS[k]: round(float(counts[k] / total), 4) for k in range(1, len(STATUS)) if total and counts[k]}


def summarize(ws: Workspace) -> dict:
    m = ws.machine
    ins = ws.inside
    dz, dp, dt = ws.steps
    n = int(ins.sum())
    flat = np.flatnonzero(ins.ravel())
    smallest = np.minimum(ws.parallel, ws.inverse).ravel()[flat]
    dex = ws.dexterity.ravel()[flat]
    dist = ws.distance.ravel()[flat]
    hi_ = ws.home_index
    ranges = {"z_m": _run(ws, 0), "psi_deg": tuple(math.degrees(v) for v in _run(ws, 1)),
              "theta_deg": tuple(math.degrees(v) for v in _run(ws, 2))}
    out = {
        "design": m.label,
        "payload_kg": m.payload_kg,
        "home": {"rho_m": list(m.rho_home), "z_m": ws.home[0], "psi_deg": math.degrees(ws.home[1]),
                 "theta_deg": math.degrees(ws.home[2]), "det": float(ws.det[hi_]),
                 "margin_parallel": float(ws.parallel[hi_]), "margin_inverse": float(ws.inverse[hi_]),
                 "dexterity": float(ws.dexterity[hi_])},
        "strokes_m": {"rho_min": list(m.rho_min), "rho_max": list(m.rho_max)},
        "margin_limit": ws.margin,
        "coordinate_lengths_m": list(ws.lengths),
        "grid": {"step_z_m": dz, "step_tilt_deg": math.degrees(dp),
                 "box": {"z_m": [float(ws.axes[0][0]), float(ws.axes[0][-1])],
                         "psi_deg": [math.degrees(ws.axes[1][0]), math.degrees(ws.axes[1][-1])],
                         "theta_deg": [math.degrees(ws.axes[2][0]), math.degrees(ws.axes[2][-1])]},
                 "nodes": int(ws.status.size), "kept_edges": int(sum(k.sum() for k in ws.kept))},
        "poses_inside": n,
        "volume_m_rad2": n * dz * dp * dt,
        "volume_m_deg2": n * dz * math.degrees(dp) * math.degrees(dt),
        "ranges_through_home": {k: list(v) for k, v in ranges.items()},
        "extent": {"z_m": [float(ws.axes[0][np.flatnonzero(ins.any(axis=(1, 2)))].min()),
                           float(ws.axes[0][np.flatnonzero(ins.any(axis=(1, 2)))].max())],
                   "psi_deg": [math.degrees(ws.axes[1][np.flatnonzero(ins.any(axis=(0, 2)))].min()),
                               math.degrees(ws.axes[1][np.flatnonzero(ins.any(axis=(0, 2)))].max())],
                   "theta_deg": [math.degrees(ws.axes[2][np.flatnonzero(ins.any(axis=(0, 1)))].min()),
                                 math.degrees(ws.axes[2][np.flatnonzero(ins.any(axis=(0, 1)))].max())]},
        "worst_dexterity": {"value": float(dex.max()), "at": _at(ws, int(flat[np.argmax(dex)]))},
        "smallest_margin": {"value": float(smallest.min()), "at": _at(ws, int(flat[np.argmin(smallest)])),
                            "kind": "parallel" if ws.parallel.ravel()[flat[np.argmin(smallest)]]
                            <= ws.inverse.ravel()[flat[np.argmin(smallest)]] else "inverse"},
        "smallest_distance_to_singularity_m": (None if not np.isfinite(dist.min()) else
                                               {"value": float(dist.min()), "at": _at(ws, int(flat[np.argmin(dist)]))}),
        "distance_to_singularity_at_home_m": (None if not np.isfinite(ws.distance[hi_])
                                              else float(ws.distance[hi_])),
        "largest_carriage_speed_per_platform_speed": float((1.0 / ws.inverse.ravel()[flat]).max()),
        "limited_by": _boundary(ws),
        "wall_time_s": round(ws.wall_time_s, 2),
    }
    if ws.machine.missing_masses:
        out["static_forces"] = {"not_computed": f"the mechanism's parameters give no {', '.join(ws.machine.missing_masses)}: "
                                                "the workspace and its margins are kinematic, the static forces unknown"}
    if ws.forces is not None:
        F = ws.forces.reshape(3, -1)[:, flat]
        peak = np.abs(F).max(axis=0)
        out["static_forces"] = {"home_N": [float(v) for v in ws.forces[(slice(None),) + hi_]],
                                "largest_N": float(peak.max()), "at": _at(ws, int(flat[np.argmax(peak)]))}
        d = m.drive
        if d:
            # motor torque holding the carriage and its share of the mechanism at rest (friction left out)
            tau = (np.abs(F + d["M_load"] * d["g_guide"])).max(axis=0) * d["p"] / (2 * math.pi * d["i_r"])
            peak_torque = d["k_T"] * d["i_max"]
            out["static_forces"].update({"largest_motor_torque_Nm": float(tau.max()),
                                         "at_largest_torque": _at(ws, int(flat[np.argmax(tau)])),
                                         "motor_peak_torque_Nm": peak_torque,
                                         "largest_torque_fraction_of_peak": float(tau.max() / peak_torque),
                                         "fraction_of_poses_beyond_peak_torque": float(np.mean(tau > peak_torque))})
    return out


CSV_COLUMNS = ("z_m", "psi_deg", "theta_deg", "status", "inside", "rho_1_m", "rho_2_m", "rho_3_m", "det",
               "margin_parallel", "margin_inverse", "dexterity", "distance_to_singularity_m", "F_1_N", "F_2_N", "F_3_N")


def _layer(ws: Workspace) -> np.ndarray:
    """The workspace and the nodes next to it (its boundary layer)."""
    ins = ws.inside
    near = ins.copy()
    for axis in range(3):
        for shift in (1, -1):
            rolled = np.roll(ins, shift, axis=axis)
            edge = [slice(None)] * 3
            edge[axis] = slice(0, 1) if shift == 1 else slice(-1, None)
            rolled[tuple(edge)] = False
            near |= rolled
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
    F = ws.forces.reshape(3, -1)[:, sel] if ws.forces is not None else np.full((3, len(sel)), np.nan)
    cols = [ws.axes[0][idx[0]], np.degrees(ws.axes[1][idx[1]]), np.degrees(ws.axes[2][idx[2]])]
    status = ws.status.ravel()[sel]
    rho = ws.rho.reshape(3, -1)[:, sel]
    vals = [ws.det, ws.parallel, ws.inverse, ws.dexterity, ws.distance]
    with open(out / "workspace.csv", "w", newline="") as handle:
        w = csv.writer(handle)
        w.writerow(CSV_COLUMNS)
        data = np.column_stack(cols + [rho[0], rho[1], rho[2]] + [v.ravel()[sel] for v in vals] + [F[0], F[1], F[2]])
        for row, st in zip(data, status):
            text = [f"{v:.6g}" if np.isfinite(v) else ("inf" if v > 0 else "") for v in row]
            w.writerow(text[:3] + [STATUS[st], int(st == INSIDE)] + text[3:])
    files.append(out / "workspace.csv")
    if plots:
        files.append(plot(ws, out / "workspace.png"))
    return files


_COLOURS = {UNASSEMBLABLE: "#4d4d4d", STROKE: "#bdbdbd", SINGULAR: "#d62728", BRANCH: "#ff7f0e", DISCONNECTED: "#e377c2"}


def plot(ws: Workspace, path: Path) -> Path:
    """Sections through home (z-psi, z-theta, psi-theta at four heights) and the boundary in 3-D."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    z, ps, th = ws.axes[0], np.degrees(ws.axes[1]), np.degrees(ws.axes[2])
    smallest = np.minimum(ws.parallel, ws.inverse)
    vmax = float(np.nanmax(np.where(ws.inside, smallest, np.nan))) if ws.inside.any() else 1.0
    cmap_out = ListedColormap([_COLOURS.get(k, "white") for k in range(len(STATUS))])

    def section(ax, st, val, x, y, xlabel, ylabel, title):
        ax.pcolormesh(x, y, st.T, cmap=cmap_out, vmin=-0.5, vmax=len(STATUS) - 0.5, shading="nearest")
        im = ax.pcolormesh(x, y, np.where(st == INSIDE, val, np.nan).T, cmap="viridis", vmin=ws.margin, vmax=vmax,
                           shading="nearest")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=9)
        return im

    h = ws.home_index
    fig = plt.figure(figsize=(16, 9))
    ax1 = fig.add_subplot(2, 4, 1)
    im = section(ax1, ws.status[:, :, h[2]], smallest[:, :, h[2]], z, ps, "z [m]", "psi [deg]",
                 f"theta = {th[h[2]]:.3g} deg")
    ax2 = fig.add_subplot(2, 4, 2)
    section(ax2, ws.status[:, h[1], :], smallest[:, h[1], :], z, th, "z [m]", "theta [deg]", f"psi = {ps[h[1]]:.3g} deg")
    for a in (ax1, ax2):
        a.plot([z[h[0]]], [0.0], "w+", ms=10, mew=2)
    ins_z = np.flatnonzero(ws.inside.any(axis=(1, 2)))
    spread = np.linspace(ins_z.min(), ins_z.max(), 5).round().astype(int)[1:-1] if len(ins_z) else []
    heights = sorted({int(v) for v in spread} | {h[0]})
    for k, iz in enumerate(heights[:4]):
        ax = fig.add_subplot(2, 4, 5 + k)
        section(ax, ws.status[iz], smallest[iz], ps, th, "psi [deg]", "theta [deg]",
                f"z = {z[iz]:.4g} m" + (" (home)" if iz == h[0] else ""))
        ax.set_aspect("equal")
    ax3 = fig.add_subplot(2, 4, (3, 4), projection="3d")
    layer = _layer(ws) & ~ws.inside
    for code, colour in _COLOURS.items():
        sel = layer & (ws.status == code)
        if sel.any():
            i = np.nonzero(sel)
            step = max(1, len(i[0]) // 4000)
            ax3.scatter(ps[i[1]][::step], th[i[2]][::step], z[i[0]][::step], s=2, c=colour, alpha=0.5, depthshade=False)
    ax3.set_xlabel("psi [deg]")
    ax3.set_ylabel("theta [deg]")
    ax3.set_zlabel("z [m]")
    ax3.set_title("boundary: what stops the workspace", fontsize=9)
    fig.colorbar(im, ax=ax2, label="smallest singularity margin [m/m] (inside)")
    fig.legend(handles=[Patch(color=c, label=STATUS[k]) for k, c in _COLOURS.items()], loc="lower center", ncol=5,
               fontsize=8)
    s = summarize(ws)
    fig.suptitle(f"{ws.machine.label}: workspace {s['volume_m_deg2']:.4g} m deg^2 ({s['poses_inside']} poses), "
                 f"home z = {ws.home[0]:.4g} m; smallest margin {s['smallest_margin']['value']:.3g} m/m, "
                 f"worst dexterity {s['worst_dexterity']['value']:.3g}; margin limit {ws.margin:g} m/m")
    fig.subplots_adjust(left=0.05, right=0.97, top=0.92, bottom=0.1, hspace=0.3, wspace=0.35)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
