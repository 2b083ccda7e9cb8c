"""Python API: run an SSP with the project's master, through FMI or directly."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence, Union

from fmus.common.parameters import Value

from .components import BlockComponent, FMUComponent
from .master import Master, Result, SimulationError, Stimulus
from .motion import AXES, NoStimulus, SineMotion, bind, system_axes, unit
from .specimen import Specimen, with_specimen
from .ssp import SSPArchive, safe_extract


def default_signals(system) -> list[str]:
    """Every system input and every output a component declares in the SSD."""
    signals = list(system.system_inputs)
    for name, comp in system.components.items():
        signals += [f"{name}.{o}" for o in comp.outputs]
    return signals


def drive_tick_steps(system) -> Optional[tuple[float, dict[str, float]]]:
    """(base step, step sizes) that exchange the controller and the actuators at every tick of the drive's
    current loop (the actuators' ``T_cur``), the mechanism at its own step: the MAST systems' own step sizes
    (docs/interfaces.md, Timing), stated for an analysis that restates the drive's torque measurement on the
    record (synthesize, diagnose) and must run so whatever a system's SSD says. None for a system without
    actuators that have a current loop."""
    actuators = [n for n, c in system.components.items() if n.startswith("actuator_") and "T_cur" in c.parameters]
    if not actuators:
        return None
    T = float(system.components[actuators[0]].parameters["T_cur"])
    return T, {name: T for name in ("controller", *actuators) if name in system.components}


def parse_overrides(items: Sequence[str]) -> dict[str, dict[str, Value]]:
    """``ELEMENT.PARAMETER=VALUE`` strings to {element: {parameter: value}}."""
    overrides: dict[str, dict[str, Value]] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        element, dot, parameter = key.strip().partition(".")
        if not sep or not dot or not element or not parameter:
            raise ValueError(f"--set {item!r}: expected ELEMENT.PARAMETER=VALUE, e.g. actuator_1.tau_c=0.07")
        raw = raw.strip()
        try:
            value: Value = int(raw) if raw.lstrip("+-").isdigit() else float(raw)
        except ValueError:
            value = raw
        overrides.setdefault(element, {})[parameter] = value
    return overrides


def simulate(
    ssp: Union[str, Path],
    stimulus: Optional[Stimulus],
    stop_time: float,
    parameters: Optional[Mapping[str, Mapping[str, Value]]] = None,
    record: Optional[Sequence[str]] = None,
    record_step: Optional[float] = 1e-3,
    direct: bool = False,
    base_step: Optional[float] = None,
    step_sizes: Optional[Mapping[str, float]] = None,
    progress: Optional[Callable[[float], None]] = None,
    feedthrough: bool = False,
    component: Optional[Callable[[str, type], BlockComponent]] = None,
    specimen: Optional[Specimen] = None,
) -> Result:
    """Run ``ssp`` (a built .ssp, or a .ssd whose FMUs exist) and return the recorded signals.

    ``direct=True`` runs the same schedule on the model objects the FMUs wrap
    (no FMI): the reference the co-simulation must reproduce to rounding.
    A failing run raises SimulationError carrying the partial Result.
    ``stimulus=None`` runs a system without inputs (its command comes from a component).
    ``feedthrough=True``: declared direct feedthrough passed on within a tick, outside FMI 2.0's calling
    sequence (master.py). ``component`` (with ``direct``): makes each component from its name and block class in
    place of ``BlockComponent`` (the monolithic reference's, mast.analyses.monolithic).
    ``specimen``: a specimen on the platform (``core.specimen.Specimen``), the mechanism's payload parameters added
    to ``parameters`` (one of them set there too is refused); whether the drives hold it is
    ``mast.analyses.specimen.check_held``, which the commands run first.
    """
    parameters = with_specimen(parameters, specimen)
    with SSPArchive(ssp) as archive, tempfile.TemporaryDirectory(prefix="mast_fmus_") as unzip_root:
        system = archive.system
        if stimulus is None:
            if system.system_inputs:
                raise ValueError(f"{ssp}: the system has inputs ({', '.join(system.system_inputs)}): give a stimulus")
            stimulus = NoStimulus()
        else:  # the stimulus commands the coordinates of the system's mechanism
            bind(stimulus, system_axes(system, parameters), str(ssp))
        components = {}
        unzipped: dict[Path, Path] = {}
        try:
            for name, spec in system.components.items():
                fmu = system.fmu_path(name)
                if direct:
                    make = component or BlockComponent
                    components[name] = make(name, BlockComponent.class_for(fmu.stem, spec.parameters))
                else:
                    # a native actuator with an n_dof above the chains it carries: the model generated with it
                    from .native.build import for_parameters

                    fmu = for_parameters(fmu, {**spec.parameters, **(parameters or {}).get(name, {})})
                    if fmu not in unzipped:
                        unzipped[fmu] = safe_extract(
                            fmu, Path(unzip_root) / f"{len(unzipped)}_{fmu.stem}", system.fmu_label(name)
                        )
                    components[name] = FMUComponent(name, fmu, unzipped[fmu])
            master = Master(system, components, base_step=base_step, step_sizes=step_sizes, feedthrough=feedthrough)
        except Exception:
            for comp in components.values():
                comp.close()
            raise
        return master.run(
            stop_time,
            stimulus,
            record=default_signals(system) if record is None else record,
            record_step=record_step,
            parameters=parameters,
            progress=progress,
        )


def motion_from_cli(
    axis: str, amplitude: float, frequency: float, axes: Optional[Sequence[str]] = None, where: str = "the system"
) -> SineMotion:
    """CLI units: metres for x, y, z, degrees for the angles. ``axes``: the coordinates of the system ``where``
    (``motion.system_axes``; None: the 3PRS's); a coordinate it lacks is refused (ValueError naming it and the
    system's)."""
    motion = SineMotion(axis, amplitude if unit(axis) == "m" else math.radians(amplitude), frequency, axes=(axis,))
    bind(motion, AXES if axes is None else axes, where)
    return motion


def summarize(result: Result, stop_time: float, motion: SineMotion, ssp: Optional[Union[str, Path]] = None) -> dict:
    """The figures of a run, and what ran: ``system``, the SSP (absolute path) and per component the parameter
    values the master set (``Result.stats``; what ``mast animate`` draws the mechanism from)."""
    summary = {
        "wall_time_s": round(result.wall_time_s, 4),
        "simulated_time_s": stop_time,
        "real_time_factor": round(stop_time / result.wall_time_s, 3) if result.wall_time_s > 0 else None,
        "motion": {
            "axis": motion.axis,
            "amplitude": motion.amplitude,
            "frequency_Hz": motion.frequency,
            "home": dict(zip(motion.axes, motion.home)),
        },
        "base_step_s": result.stats.get("base_step"),
        "step_multiples": result.stats.get("multiples"),
        "error": result.error,
        "system": {
            "ssp": None if ssp is None else str(Path(ssp).resolve()),
            "parameters": result.stats.get("parameters"),
        },
    }
    cmd, got = f"{motion.axis}_cmd", f"mechanism.{motion.axis}"
    if cmd in result.signals and got in result.signals and len(result.time):
        err = result[cmd] - result[got]
        summary["tracking_error_peak"] = float(abs(err).max())
        summary["tracking_error_rms"] = float((err**2).mean() ** 0.5)
    if len(result.time):  # every coordinate commanded (the moved one and the held ones), in m or rad
        summary["coordinates"] = {
            c: {
                "unit": unit(c),
                "error_peak": float(abs(result[f"{c}_cmd"] - result[f"mechanism.{c}"]).max()),
                "error_rms": float(((result[f"{c}_cmd"] - result[f"mechanism.{c}"]) ** 2).mean() ** 0.5),
            }
            for c in result.coordinates()
            if f"mechanism.{c}" in result.signals
        }
    for j in result.drives():  # every drive's motor (actuator_k, the connector convention)
        for signal, key in (("tau_m", f"tau_m_{j}_{{}}_Nm"), ("i_m", f"i_m_{j}_{{}}_A")):
            name = f"actuator_{j}.{signal}"
            if name in result.signals and len(result.time):
                summary[key.format("peak")] = float(abs(result[name]).max())
                summary[key.format("rms")] = float((result[name] ** 2).mean() ** 0.5)
    return summary


def write_outputs(
    result: Result, out: Path, stop_time: float, motion: SineMotion, ssp: Optional[Union[str, Path]] = None
) -> dict:
    """results.csv, summary.json and plot.png into ``out`` (``ssp``: the system run, recorded in the summary)."""
    from .plots import plot_run

    out.mkdir(parents=True, exist_ok=True)
    result.write_csv(out / "results.csv")
    summary = summarize(result, stop_time, motion, ssp)
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    if len(result.time) > 1:
        plot_run(result, motion.axis, out / "motion.png")
    return summary


__all__ = [
    "simulate",
    "SimulationError",
    "SineMotion",
    "Specimen",
    "parse_overrides",
    "write_outputs",
    "motion_from_cli",
]
