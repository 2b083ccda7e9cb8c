"""Up-front check of a run's pose commands against the plant's workspace.

Before the first step the master hands the extreme poses the stimulus will command
(``Stimulus.extremes``, e.g. the home pose plus and minus a sine's amplitude) to
``check_commands``. Each goes through the inverse kinematics of the plant's mechanism
(the component whose inputs ``rho_1..n`` the actuators feed, with its own bound
parameters; n and the coordinates from its description's topology) and the joint positions
are compared with the strokes ``[rho_min, rho_max]`` of the actuators feeding it. A pose that is unreachable or drives
a carriage off its
stroke refuses the run, naming the command, its value and the limit along that axis
(found by bisection from the home pose), instead of a run that fails part-way or, with a
stroke that does not stop the model, runs to the end on nonsense.

This is the simple, exact check of the commanded extremes; what a design can reach
altogether is a workspace analysis of its own.
"""

from __future__ import annotations

import math
from typing import Mapping, Optional, Sequence

from .motion import sine_extremes, system_axes, unit


class CommandError(ValueError):
    """A commanded pose outside the workspace of the system's mechanism; its message gives angles in radians (the
    Python API's unit), ``in_degrees`` the same message in degrees (the command line's)."""

    def __init__(self, message: str, in_degrees: Optional[str] = None) -> None:
        super().__init__(message)
        self.in_degrees = in_degrees or message


class StrokeError(ValueError):
    """An actuator's stroke that excludes its drive's position at the mechanism's home pose."""


def _show(axis: str, value: float, degrees: bool = False) -> str:
    if unit(axis) == "m":
        return f"{axis}_cmd = {value:.6g} m"
    if degrees:
        return f"{axis}_cmd = {math.degrees(value):.6g} deg ({value:.4g} rad)"
    return f"{axis}_cmd = {value:.6g} rad ({math.degrees(value):.4g} deg)"


def _amount(axis: str, value: float, degrees: bool = False) -> str:
    """``value`` of coordinate ``axis`` with its unit: m, rad, or deg when ``degrees`` (an angle)."""
    if degrees and unit(axis) != "m":
        return f"{math.degrees(value):.6g} deg"
    return f"{value:.6g} {unit(axis)}"


def _plant(
    system, params: Mapping[str, Mapping], mechanism: str
) -> Optional[tuple[str, object, list[tuple[str, float, float, str]]]]:
    """(mechanism name, its kinematic engine, [(actuator, rho_min, rho_max, unit)] per drive) or None."""
    from fmus.mechanism.designs import kinematic_engine

    spec = system.components.get(mechanism)
    if spec is None:
        return None
    try:
        eng = kinematic_engine(params.get(mechanism, {}), mechanism)
        drives = eng.description.topology.drives
    except Exception:  # a mechanism this project does not describe (a third-party FMU): nothing to check
        return None
    strokes = []
    for k, drive in enumerate(drives, 1):
        joint = f"rho_{k}"
        if joint not in spec.inputs:
            return None
        feed = [c for c in system.connections if c.end_element == mechanism and c.end_connector == joint]
        source = params.get(feed[0].start_element, {}) if feed and feed[0].start_element else {}
        if "rho_min" not in source or "rho_max" not in source:
            return None
        strokes.append((feed[0].start_element, float(source["rho_min"]), float(source["rho_max"]), drive.unit))
    return mechanism, eng, strokes


def trajectory_parameters(axes: Sequence[str]) -> tuple[str, ...]:
    """The parameters of a pose-command component of a system with motion axes ``axes`` (fmus/trajectory: home
    pose plus one sine on every axis): ``<c>_home``, ``amplitude_<c>`` per axis c, then ``frequency``."""
    return (*(f"{a}_home" for a in axes), *(f"amplitude_{a}" for a in axes), "frequency")


def trajectory_extremes(
    system, params: Mapping[str, Mapping], t0: float, t1: float
) -> Optional[tuple[list[float], list[list[float]]]]:
    """The extreme poses a trajectory component of ``system`` commands between t0 and t1 (None: none), on the
    system's motion axes (``motion.system_axes``)."""
    axes = system_axes(system, params)
    names = trajectory_parameters(axes)
    n = len(axes)
    for name, spec in system.components.items():
        p = params.get(name, {})
        if all(f"{a}_cmd" in spec.outputs for a in axes) and all(k in p for k in names):
            home = [float(p[k]) for k in names[:n]]
            amplitude = [float(p[k]) for k in names[n : 2 * n]]
            return sine_extremes(home, amplitude, 2.0 * math.pi * float(p["frequency"]) * max(t1 - t0, 0.0))
    return None


def _violation(eng, strokes, pose: Sequence[float]) -> Optional[str]:
    """Why ``pose`` is outside the workspace, or None."""
    from fmus.mechanism.kinematics import KinematicsError

    try:
        rho = eng.ik(pose)
    except KinematicsError as err:
        return str(err)
    for i, (actuator, lo, hi, u) in enumerate(strokes):
        if not lo <= rho[i] <= hi:
            return (
                f"carriage {i + 1} would be at rho_{i + 1} = {rho[i]:.6g} {u}, beyond the stroke "
                f"[{lo:g}, {hi:g}] {u} of {actuator}"
            )
    return None


def check_strokes(name: str, eng, strokes: Sequence[tuple[str, float, float, str]]) -> None:
    """Raise StrokeError if an actuator's stroke [rho_min, rho_max] (``strokes``, per drive) excludes the position
    of its drive at the home pose of the mechanism ``name`` (its description's, ``eng``): the message names the
    actuator, the joint, its position at home and the limit it passes."""
    topology = eng.description.topology
    rho = eng.ik(list(topology.home))
    for k, (actuator, lo, hi, u) in enumerate(strokes):
        if not lo <= rho[k] <= hi:
            limit = f"rho_min = {lo:g} {u}" if rho[k] < lo else f"rho_max = {hi:g} {u}"
            pose = ", ".join(f"{c} = {v:.6g} {unit(c)}" for c, v in zip(topology.names, topology.home))
            raise StrokeError(
                f"{actuator}: stroke [{lo:g}, {hi:g}] {u} excludes the home pose of '{name}' ({pose}), where its "
                f"joint rho_{k + 1} = {rho[k]:.6g} {u}: {limit} leaves home out of reach"
            )


def check_commands(
    system,
    params: Mapping[str, Mapping],
    home: Sequence[float],
    extremes: Sequence[Sequence[float]],
    mechanism: str = "mechanism",
) -> None:
    """Raise CommandError if a pose of ``extremes`` (the mechanism's coordinates, in its order and units: for
    the 3PRS z [m], psi, theta [rad]) is outside the workspace of ``mechanism`` (the component whose pose
    outputs the stimulus reads as the home pose); StrokeError first if an actuator's stroke excludes the
    description's home pose (``check_strokes``)."""
    plant = _plant(system, params, mechanism)
    if plant is None:
        return
    name, eng, strokes = plant
    check_strokes(name, eng, strokes)
    axes = eng.description.topology.names
    if _violation(eng, strokes, home) is not None:
        return  # the home pose itself is the initial state's business (the mechanism reports it)
    for pose in extremes:
        if not all(math.isfinite(v) for v in pose):
            raise CommandError(f"pose command {tuple(pose)}: not finite")
        why = _violation(eng, strokes, pose)
        if why is None:
            continue
        moved = [k for k in range(len(axes)) if pose[k] != home[k]] or [0]
        k = moved[0]
        axis = axes[k]
        # the limit along the direction home -> pose: bisection on the fraction s of the way
        inside, outside = 0.0, 1.0
        for _ in range(60):
            mid = 0.5 * (inside + outside)
            trial = [h + mid * (p - h) for h, p in zip(home, pose)]
            if _violation(eng, strokes, trial) is None:
                inside = mid
            else:
                outside = mid
        limit = home[k] + inside * (pose[k] - home[k])
        side = "largest" if pose[k] > home[k] else "smallest"
        said = [
            f"{_show(axis, pose[k], deg)} is outside the workspace of '{name}': {why}. The {side} reachable "
            f"{axis}_cmd on the way from the home pose ({_show(axis, home[k], deg)}) is {_amount(axis, limit, deg)}"
            for deg in (False, True)
        ]
        raise CommandError(*said)
