"""The system SSDs, generated from a system description: n actuator FMUs from the mechanism's topology.

A ``SystemDescription`` names the FMUs of the controller, of the actuator (one copy per drive),
of the mechanism and, for a system that commands itself, of a pose command (``trajectory``); the
parameter sets bound to each, in order; the step sizes (OSP annotations) and the actuators'
ratings (the ``mast.sizing`` annotation). ``system_ssd`` writes from it and a ``Topology``
(``fmus.mechanism.topology``: n drives, the coordinates and their units) the system with
components ``controller``, ``actuator_1`` .. ``actuator_n``, ``mechanism`` (and ``trajectory``)
and the connections of the connector convention (docs/interfaces.md):

- the pose command ``<c>_cmd`` for every coordinate c: a system input (or the trajectory's output)
  into the controller;
- for drive k: ``controller.i_cmd_k`` -> ``actuator_k.i_cmd``; ``actuator_k.rho`` -> ``controller.rho_k``;
  ``actuator_k.omega_m`` -> ``controller.omega_m_k``; ``actuator_k.rho, rho_dot, rho_ddot`` ->
  ``mechanism.rho_k, rho_dot_k, rho_ddot_k``; ``mechanism.F_k`` -> ``actuator_k.F``;
- the mechanism's outputs: ``F_k`` and the six pose components (x, y, z, psi, theta, phi).

A joint quantity is in m, m/s, m/s2 and N for a linear drive, rad, rad/s, rad/s2 and N.m for a rotary
one. ``topology`` gives a description's topology: ``fmus.mechanism.designs.describe`` of the values of
the sets bound to its mechanism. ``MAST`` is the default system (ssp/MAST.ssd), ``STANDALONE`` the
same with its own pose command (ssp/MAST_standalone.ssd); the design and controller variants
(``mast.core.designs``, ``mast.core.controllers``) are descriptions derived from ``MAST``.
``python -m mast.core.variants`` writes them all (tests check the committed files are what it writes).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from fmus.mechanism.designs import describe, parameter_units
from fmus.mechanism.topology import POSE, POSE_UNITS, Topology

from . import ssd
from .ssp import declared_values
from .ssv import parse_ssv

REPO = Path(__file__).resolve().parents[2]
SSP_SRC = REPO / "ssp"

#: per joint unit: (velocity, acceleration, force) units of a drive's joint quantities
JOINT_RATES = {
    "m": ("m/s", "m/s2", "N", "N/s", "N/s2", "kg"),
    "rad": ("rad/s", "rad/s2", "N.m", "N.m/s", "N.m/s2", "kg.m2"),
}
#: what a drive tells the mechanism beyond its motion, and what the mechanism answers (docs/coupling.md)
DRIVE_FORCES = ("F_drive", "F_drive_dot", "F_drive_ddot", "m_drive")
#: the actuator FMU's own connectors beside its joint quantities (unit, kind)
ACTUATOR_SIGNALS = (("theta_m", "rad"), ("omega_m", "rad/s"), ("i_m", "A"), ("tau_m", "N.m"), ("u", "V"))
_COUNTS = ("no", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten", "eleven", "twelve")


@dataclass(frozen=True)
class Part:
    """A component's FMU (``resources/<fmu>``), the parameter sets bound to it (in order, later ones
    override), its step size [s] (osp:StepSizeHint; None: the base step) and the comment before it.
    A comment may name ``{n}`` (the number of drives, in words), ``{mechanism}`` (the topology's
    name), and for an actuator ``{k}`` (its drive) and ``{kind}`` (Linear, Rotary)."""

    fmu: str
    bindings: tuple[str, ...] = ()
    step: Optional[float] = None
    comment: str = ""

    @property
    def source(self) -> str:
        return f"resources/{self.fmu}"


@dataclass(frozen=True)
class SystemDescription:
    """What a system SSD is made of besides the mechanism's topology (module docstring).

    ``name``: the document's name (and its file ssp/<name>.ssd); ``system``: the ssd:System's name;
    ``ratings``: the parameter set of each actuator's ratings (``mast sizing``); ``trajectory``: a
    pose command component in place of the system inputs; times in s."""

    name: str
    system: str
    description: str
    comment: str
    controller: Part
    actuator: Part
    mechanism: Part
    ratings: Optional[str] = None
    trajectory: Optional[Part] = None
    start_time: float = 0.0
    stop_time: float = 2.0
    base_step: float = 1e-4

    @property
    def path(self) -> Path:
        return SSP_SRC / f"{self.name}.ssd"


def topology(description: SystemDescription, root: Path = SSP_SRC) -> Topology:
    """The topology of the mechanism the sets bound to ``description``'s mechanism describe
    (``describe``; their sources relative to ``root``; their values in the units the description declares)."""
    values: dict = {}
    given: dict = {}
    for source in description.mechanism.bindings:
        for name, p in parse_ssv(root / source).items():
            values[name] = p.value
            given.pop(name, None)
            if p.si is not None:
                given[name] = (p.unit, p.si, source)
    values = declared_values(values, given, parameter_units(values), description.name)  # as the block reads them
    return describe(values, owner=description.name, masses=False).topology


def _count(n: int) -> str:
    return _COUNTS[n] if n < len(_COUNTS) else str(n)


def _joint(unit: str) -> dict[str, str]:
    speed, acceleration, force, force_rate, force_acceleration, mass = JOINT_RATES[unit]
    return {
        "rho": unit,
        "rho_dot": speed,
        "rho_ddot": acceleration,
        "F": force,
        "F_drive": force,
        "F_drive_dot": force_rate,
        "F_drive_ddot": force_acceleration,
        "m_drive": mass,
        "M_carried": mass,
    }


def system_ssd(description: SystemDescription, shape: Topology) -> ssd.SystemStructureDescription:
    """The system of ``description`` for a mechanism of topology ``shape`` (module docstring)."""
    names = {"n": _count(shape.n), "mechanism": shape.name}
    commands = [ssd.Connector(f"{c.name}_cmd", "input", unit=c.unit) for c in shape.coordinates]
    joints = [_joint(d.unit) for d in shape.drives]
    ks = range(1, shape.n + 1)

    def component(
        name: str, part: Part, connectors: list[ssd.Connector], ratings: Optional[str] = None, **words: str
    ) -> ssd.Component:
        return ssd.Component(
            name,
            part.source,
            connectors,
            [ssd.ParameterBinding(s) for s in part.bindings],
            part.step,
            ratings,
            part.comment.format(**names, **words),
        )

    controller = component(
        "controller",
        description.controller,
        commands
        + [
            *(ssd.Connector(f"rho_{k}", "input", unit=j["rho"]) for k, j in zip(ks, joints)),
            *(ssd.Connector(f"omega_m_{k}", "input", unit="rad/s") for k in ks),
            *(ssd.Connector(f"rho_cmd_{k}", "output", unit=j["rho"]) for k, j in zip(ks, joints)),
            *(ssd.Connector(f"omega_cmd_{k}", "output", unit="rad/s") for k in ks),
            *(ssd.Connector(f"i_cmd_{k}", "output", unit="A") for k in ks),
        ],
    )
    actuators = [
        component(
            f"actuator_{k}",
            description.actuator,
            [
                ssd.Connector("i_cmd", "input", unit="A"),
                ssd.Connector("F", "input", unit=j["F"]),
                ssd.Connector("M_carried", "input", unit=j["M_carried"]),
                *(ssd.Connector(q, "output", unit=j[q]) for q in ("rho", "rho_dot", "rho_ddot")),
                *(ssd.Connector(q, "output", unit=u) for q, u in ACTUATOR_SIGNALS),
                *(ssd.Connector(q, "output", unit=j[q]) for q in DRIVE_FORCES),
            ],
            description.ratings,
            k=str(k),
            kind=d.kind.capitalize(),
        )
        for k, d, j in zip(ks, shape.drives, joints)
    ]
    mechanism = component(
        "mechanism",
        description.mechanism,
        [
            *(
                ssd.Connector(f"{q}_{k}", "input", unit=j[q])
                for q in ("rho", "rho_dot", "rho_ddot", *DRIVE_FORCES)
                for k, j in zip(ks, joints)
            ),
            *(ssd.Connector(f"F_{k}", "output", unit=j["F"]) for k, j in zip(ks, joints)),
            *(ssd.Connector(p, "output", unit=POSE_UNITS[p]) for p in POSE),
            *(ssd.Connector(f"Fc_{k}", "output", unit=j["F"]) for k, j in zip(ks, joints)),
            *(ssd.Connector(f"Mc_{k}", "output", unit=j["M_carried"]) for k, j in zip(ks, joints)),
        ],
    )
    source = ""
    elements = [controller, *actuators, mechanism]
    if description.trajectory is not None:
        source = "trajectory"
        elements.insert(
            0,
            component("trajectory", description.trajectory, [dataclasses.replace(c, kind="output") for c in commands]),
        )
    connections = [ssd.Connection(source, c.name, "controller", c.name) for c in commands]
    for k in ks:
        connections += [
            ssd.Connection("controller", f"i_cmd_{k}", f"actuator_{k}", "i_cmd"),
            ssd.Connection(f"actuator_{k}", "rho", "controller", f"rho_{k}"),
            ssd.Connection(f"actuator_{k}", "omega_m", "controller", f"omega_m_{k}"),
            *(
                ssd.Connection(f"actuator_{k}", q, "mechanism", f"{q}_{k}")
                for q in ("rho", "rho_dot", "rho_ddot", *DRIVE_FORCES)
            ),
            ssd.Connection("mechanism", f"Fc_{k}", f"actuator_{k}", "F"),
            ssd.Connection("mechanism", f"Mc_{k}", f"actuator_{k}", "M_carried"),
        ]
    system = ssd.System(description.system, description.description, [] if source else commands, elements, connections)
    return ssd.SystemStructureDescription(
        description.name,
        system,
        ssd.DefaultExperiment(description.start_time, description.stop_time, description.base_step),
        comments=[description.comment],
    )


def generate(description: SystemDescription) -> bytes:
    """The .ssd file of ``description``, for the topology of its mechanism (``topology``)."""
    return system_ssd(description, topology(description)).to_bytes()


#: the default system: the MAST with joint-space position control (ssp/MAST.ssd)
MAST = SystemDescription(
    name="MAST",
    system="MAST",
    description="3PRS Multi-Axial Simulation Table, joint-space cascade control",
    comment="The MAST with joint-space position control (paper Fig. 1 and 2).\n"
    "     Sources: `mast build` packs this file with the FMUs and the parameter sets into build/ssp/MAST.ssp.\n"
    "     Components may be swapped by editing their `source`; parameter sets are bound in order, later ones "
    "override.\n"
    "     Step sizes: OSP annotations (honoured by libcosim/ecos and by the project's master): every component at\n"
    "     the drive's T_cur = 100 us, so every host that follows FMI 2.0's calling sequence computes the same\n"
    "     trajectories (docs/interfaces.md, Timing).",
    controller=Part(
        "MastController.fmu",
        (
            "resources/transmission.ssv",
            "resources/geometry_3prs.ssv",
            "resources/drive.ssv",
            "resources/controller_joint.ssv",
            "resources/controller_paper_fit.ssv",
        ),
        1e-4,
        "Joint-space cascade for the {n} axes (position and velocity loops, 1 ms), stepped at T_cur with the "
        "actuators: a tick's current command reaches them at the next tick",
    ),
    actuator=Part(
        "MastActuator.fmu",
        (
            "resources/transmission.ssv",
            "resources/actuator_manufacturer.ssv",
            "resources/stroke_3prs.ssv",
            "resources/drive.ssv",
        ),
        1e-4,
        "{kind} axis {k} with its drive's current loop (T_cur = 100 us, one tick per step): current command in",
    ),
    mechanism=Part(
        "MastMechanism.fmu",
        ("resources/geometry_3prs.ssv", "resources/mass_3prs.ssv", "resources/attached.ssv"),
        1e-4,
        "{mechanism} inverse dynamics: a disturbance to the actuators, stepped at T_cur, fully updated every "
        "T_mech = 1 ms (attached.ssv)",
    ),
    ratings="resources/drive_ratings.ssv",
)

#: the default system driven by its own pose command (ssp/MAST_standalone.ssd): hosts without system inputs run it
STANDALONE = dataclasses.replace(
    MAST,
    name="MAST_standalone",
    system="MAST_standalone",
    description=MAST.description + ", with its pose command",
    comment="The MAST with joint-space position control (paper Fig. 1 and 2), driven by its own pose command:\n"
    "     the system MAST.ssd with a MastTrajectory component in place of the system inputs, so that any\n"
    "     co-simulation host runs it as it is (libcosim and ecos accept no system-level connectors).\n"
    "     Everything else is MAST.ssd (tests/test_hosts.py checks they agree).\n" + MAST.comment.split("\n", 1)[1],
    trajectory=Part(
        "MastTrajectory.fmu",
        ("resources/home_3prs.ssv", "resources/trajectory_z.ssv"),
        1e-4,
        "Pose command: home pose (home_3prs.ssv) + sine (trajectory_z.ssv: 10 mm at 1 Hz on z); stepped "
        "with the controller",
    ),
)
