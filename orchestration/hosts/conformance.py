"""`mast check-mechanism`: does a mechanism FMU honour the MAST interface? (docs/interfaces.md)

Black-box checks, run on the FMU alone (or on a Block with the same variables), that any
correct inverse dynamics of a rigid mechanism driven by n joints passes (n, the units and the
coordinates from the topology its parameters describe, ``fmus.mechanism.topology``; an FMU whose
parameters describe none is checked against the 3PRS's interface):

1. interface: inputs rho_i, rho_dot_i, rho_ddot_i (i = 1..n), outputs F_i and the pose, with their units;
2. home: at rest at the actuators' start position, finite forces and pose, already in
   initialization mode (hosts read the home pose there);
3. linear in rho_ddot, with a symmetric positive semi-definite mass matrix M = dF/drho_ddot;
4. quadratic in rho_dot: F(2 v) - F(0) = 4 (F(v) - F(0));
5. no work around a closed joint-space cycle from rest to rest (energy is conserved: the
   kinetic energy returns to zero and the potential energy to its start value);
6. the pose it reports is the one the controller's kinematic model expects: the controller's
   inverse kinematics (its ``kinematics`` and geometry, taken from the FMU's parameters when it
   declares them) maps the reported pose back to the joint positions;
7. refusal, not NaN: an unreachable joint position or a non-finite input makes doStep fail.
"""

from __future__ import annotations

import functools
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence, Union

import numpy as np

from fmus.mechanism.topology import POSE

STEP = 1e-3
#: the joint position of the home test when the topology gives no stroke (the 3PRS's mid-stroke) [m]
RHO0 = 0.15


class Refused(RuntimeError):
    """The mechanism refused a step (doStep failed, or the model raised)."""


@dataclass
class Check:
    name: str
    passed: bool
    detail: str

    def __post_init__(self) -> None:
        self.passed = bool(self.passed)

    def __str__(self) -> str:
        return f"{'PASS' if self.passed else 'FAIL'}  {self.name}: {self.detail}"


class _Subject:
    """What the checks drive: set the 3 n inputs, step, read the n + 6 outputs."""

    variables: dict  # name -> (causality, unit or None)
    parameters: dict  # name -> default value
    init_outputs: Optional[list] = None  # outputs read in initialization mode (FMUs only)

    @functools.cached_property
    def topology(self):
        """The topology the subject's parameters describe, or None (``fmus.mechanism.topology``)."""
        from fmus.mechanism.designs import describe

        try:
            return describe(self.parameters, masses=False).topology
        except Exception:  # noqa: BLE001 - parameters of a mechanism this project does not describe
            return None

    @functools.cached_property
    def expected(self):
        """The variables the subject must have (``model.Variables.required``): its topology's, else the 3PRS's."""
        from fmus.mechanism.model import MechanismBlock, Variables

        topology = self.topology
        if topology is None:
            return Variables(
                MechanismBlock.INPUTS, MechanismBlock.OUTPUTS, MechanismBlock.UNITS, MechanismBlock.DESCRIPTIONS
            ).required()
        return Variables.of_topology(topology).required()

    def start(self, inputs: Sequence[float]) -> list[float]: ...
    def step(self, t: float, inputs: Sequence[float]) -> list[float]: ...
    def close(self) -> None: ...


class BlockSubject(_Subject):
    """A Block (this project's model, or a test double) called directly."""

    def __init__(self, block_class, parameters: Mapping) -> None:
        self.block_class, self.parameters = block_class, dict(parameters)
        units = getattr(block_class, "UNITS", {})
        self.variables = {
            **{n: ("input", units.get(n)) for n in block_class.INPUTS},
            **{n: ("output", units.get(n)) for n in block_class.OUTPUTS},
        }
        self.block = None

    def _io(self):
        io = self.expected
        return [self.block.index(n) for n in io.inputs], [self.block.index(n) for n in io.outputs]

    def start(self, inputs):
        self.block = self.block_class(self.parameters)
        ins, outs = self._io()
        for i, v in zip(ins, inputs):
            self.block.values[i] = v
        try:
            self.block.initialize(0.0)
        except Exception as err:
            raise Refused(f"{type(err).__name__}: {err}") from None
        return [self.block.values[k] for k in outs]

    def step(self, t, inputs):
        ins, outs = self._io()
        for i, v in zip(ins, inputs):
            self.block.values[i] = v
        try:
            self.block.do_step(t, STEP)
        except Exception as err:
            raise Refused(f"{type(err).__name__}: {err}") from None
        return [self.block.values[k] for k in outs]

    def close(self):
        self.block = None


class FMUSubject(_Subject):
    """An FMI 2.0 co-simulation FMU through fmpy."""

    def __init__(self, fmu: Union[str, Path]) -> None:
        from fmpy import read_model_description

        from ..core.ssp import safe_extract

        self.fmu = str(fmu)
        self._tmp = tempfile.mkdtemp(prefix="mast_check_")
        self.slave = None
        try:  # extracted with the archive limits, then read from the folder
            self.unzip = str(safe_extract(self.fmu, self._tmp))
            self.md = read_model_description(self.unzip)
            if self.md.coSimulation is None:
                raise ValueError(f"{fmu}: not a co-simulation FMU")
        except BaseException:
            self.dispose()
            raise
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.variables = {
            v.name: (v.causality, v.unit or (v.declaredType.unit if v.declaredType else None))
            for v in self.md.modelVariables
        }
        convert = {
            "Real": float,
            "Integer": int,
            "Enumeration": int,
            "String": str,
            "Boolean": lambda s: str(s).lower() in ("true", "1"),
        }
        self.parameters = {
            v.name: convert.get(v.type, str)(v.start)
            for v in self.md.modelVariables
            if v.causality == "parameter" and v.start is not None
        }
        self.messages: list[str] = []
        self._n = 0

    def _vr(self, names):
        return [self.vars[n].valueReference for n in names]

    def start(self, inputs):
        from fmpy.fmi2 import FMU2Slave

        self.close()
        self._n += 1
        self.slave = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=self.unzip,
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=f"check{self._n}",
        )
        self.slave.instantiate(loggingOn=False)
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        io = self.expected
        self.slave.setReal(self._vr(io.inputs), list(inputs))
        try:  # hosts read outputs in initialization mode (the master reads the home pose there)
            self.init_outputs = list(self.slave.getReal(self._vr(io.outputs)))
        except Exception:
            self.init_outputs = None
        try:
            self.slave.exitInitializationMode()
        except Exception as err:
            raise Refused(str(err)) from None
        return list(self.slave.getReal(self._vr(io.outputs)))

    def step(self, t, inputs):
        io = self.expected
        try:
            self.slave.setReal(self._vr(io.inputs), list(inputs))
            self.slave.doStep(currentCommunicationPoint=t, communicationStepSize=STEP)
            return list(self.slave.getReal(self._vr(io.outputs)))
        except Exception as err:  # fmpy raises on a status above fmi2Warning
            raise Refused(str(err)) from None

    def close(self):
        if self.slave is not None:
            try:
                self.slave.terminate()
            except Exception:
                pass
            self.slave.freeInstance()
            self.slave = None

    def dispose(self) -> None:
        """Close, and remove the extracted FMU."""
        self.close()
        shutil.rmtree(self._tmp, ignore_errors=True)


def _controller_ik(parameters: Mapping) -> tuple[Callable, str]:
    """The controller's inverse kinematics for this mechanism (the description its ``kinematics`` names, the 3PRS
    without one): its geometry parameters when it declares them all, else the default system's controller geometry
    (the 3PRS) or the description file's values (another mechanism), with those it declares."""
    from fmus.mechanism.designs import KINEMATIC_PARAMETERS, description, kinematic_engine, parameters_for

    from ..core.ssp import read_ssd

    kind = parameters.get("kinematics", "3PRS")
    names = [p.name for p in parameters_for(KINEMATIC_PARAMETERS, kind) if p.name != "kinematics"]
    if kind == "3PRS":
        base = read_ssd(Path(__file__).resolve().parents[2] / "ssp" / "MAST.ssd").components["controller"].parameters
        fallback = "the default system's controller geometry"
    else:
        base, fallback = description(kind).values(), f"the {kind} description file's geometry"
    own = {k: parameters[k] for k in names if k in parameters}
    geometry = {"kinematics": kind, **{k: base[k] for k in names}, **own}
    where = (
        "the mechanism's own geometry parameters"
        if len(own) == len(names)
        else fallback + (f" with {', '.join(own)} from the mechanism" if own else "")
    )
    return kinematic_engine(geometry, "controller").ik, where


def check(subject: _Subject, rho0: Optional[float] = None, amplitude: float = 0.02, seed: int = 1) -> list[Check]:
    """Run the checks of the module docstring; each returns PASS/FAIL with what it measured. ``rho0``: every
    joint's position at home (None: the middle of each drive's stroke, ``RHO0`` without a topology)."""
    out: list[Check] = []
    rng = np.random.default_rng(seed)
    topology, io = subject.topology, subject.expected
    n = len(io.outputs) - 6
    zero = [0.0] * n
    words = {3: "nine"}
    count_in, count_out = (
        words.get(len(io.inputs), str(len(io.inputs))),
        words.get(len(io.outputs), str(len(io.outputs))),
    )
    units = {io.units[f"rho_{k}"] for k in range(1, n + 1)}
    u = units.pop() if len(units) == 1 else "(m or rad)"

    # 1. interface
    missing = [v for v in io.inputs if subject.variables.get(v, (None,))[0] != "input"] + [
        v for v in io.outputs if subject.variables.get(v, (None,))[0] != "output"
    ]
    wrong_units = [
        f"{v} [{subject.variables[v][1]}] (expected {io.units[v]})"
        for v in io.inputs + io.outputs
        if v in subject.variables and subject.variables[v][1] not in (None, "", io.units[v])
    ]
    out.append(
        Check(
            "interface",
            not missing and not wrong_units,
            f"all {count_in} inputs and {count_out} outputs, units as specified"
            if not missing and not wrong_units
            else f"missing or wrong causality: {', '.join(missing) or 'none'}; units: {', '.join(wrong_units) or 'ok'}",
        )
    )
    if missing:
        return out

    # 2. home
    if rho0 is not None or topology is None:
        home = [RHO0 if rho0 is None else rho0] * n
    else:
        home = [0.5 * (d.stroke[0] + d.stroke[1]) for d in topology.drives]
    shown = f"{home[0]}" if len(set(home)) == 1 else f"({', '.join(f'{v:g}' for v in home)})"
    z = io.outputs.index("z")
    try:
        y0 = subject.start(home + zero + zero)
        ok = all(math.isfinite(v) for v in y0)
        detail = (
            f"at rest at rho = {shown} {u}: F = ({', '.join(f'{v:.4g}' for v in y0[:n])}) "
            f"{io.units['F_1']}, z = {y0[z]:.6g} m"
            if ok
            else f"non-finite outputs {y0}"
        )
        early = subject.init_outputs
        if early is not None and not np.allclose(early, y0, rtol=1e-9, atol=1e-12):
            ok = False
            detail += (
                f"; but in initialization mode, with the same inputs, the outputs were {early}: they must "
                f"follow the inputs there (hosts read the home pose before leaving initialization)"
            )
        out.append(Check("home", ok, detail))
    except Refused as err:
        out.append(Check("home", False, f"refused at rest at rho = {shown} {u}: {err}"))
        return out
    t = [0.0]

    def F(rho, rd, rdd) -> np.ndarray:
        y = subject.step(t[0], list(rho) + list(rd) + list(rdd))
        t[0] += STEP
        return np.array(y)

    try:
        # 3. linear in rho_ddot, M symmetric positive semi-definite
        worst_lin, worst_sym, min_eig, scale = 0.0, 0.0, math.inf, 1e-12
        for _ in range(3):
            rho = np.array(home) + rng.uniform(-amplitude, amplitude, n)
            rd = rng.uniform(-0.2, 0.2, n)
            f0 = F(rho, rd, zero)[:n]
            M = np.column_stack([F(rho, rd, np.eye(n)[j])[:n] - f0 for j in range(n)])
            a = rng.uniform(-5, 5, n)
            worst_lin = max(worst_lin, np.abs(F(rho, rd, a)[:n] - f0 - M @ a).max())
            scale = max(scale, np.abs(M).max())
            worst_sym = max(worst_sym, np.abs(M - M.T).max())
            min_eig = min(min_eig, np.linalg.eigvalsh(0.5 * (M + M.T)).min())
        ok = worst_lin <= 1e-6 * scale * 5 + 1e-9 and worst_sym <= 1e-6 * scale + 1e-12 and min_eig >= -1e-9 * scale
        out.append(
            Check(
                "mass matrix",
                ok,
                f"affine in rho_ddot to {worst_lin:.2g} N, M = dF/drho_ddot symmetric to "
                f"{worst_sym:.2g} kg, smallest eigenvalue {min_eig:.4g} kg",
            )
        )

        # 4. quadratic in rho_dot
        worst, ref = 0.0, 1e-12
        for _ in range(3):
            rho = np.array(home) + rng.uniform(-amplitude, amplitude, n)
            v = rng.uniform(-0.5, 0.5, n)
            f0, f1, f2 = (F(rho, k * v, zero)[:n] for k in (0, 1, 2))
            worst = max(worst, np.abs((f2 - f0) - 4 * (f1 - f0)).max())
            ref = max(ref, np.abs(f1 - f0).max())
        out.append(
            Check(
                "velocity terms",
                worst <= 1e-6 * ref + 1e-9,
                f"F(2v) - F(0) = 4 (F(v) - F(0)) to {worst:.2g} N (velocity terms up to {ref:.3g} N)",
            )
        )

        # 5. closed cycle, rest to rest: no net work
        T = 0.4
        du, dw = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
        du *= amplitude / np.abs(du).max()
        dw *= amplitude / np.abs(dw).max()
        samples = 400
        work, gross = 0.0, 0.0
        ts = np.linspace(0.0, T, samples + 1)
        powers = []
        for s in ts:
            x = s / T
            tau, taud, taudd = (
                10 * x**3 - 15 * x**4 + 6 * x**5,
                (30 * x**2 - 60 * x**3 + 30 * x**4) / T,
                (60 * x - 180 * x**2 + 120 * x**3) / T**2,
            )
            ph = 2 * math.pi * tau
            pos = np.array(home) + du * math.sin(ph) + dw * (1 - math.cos(ph))
            dpos = du * math.cos(ph) + dw * math.sin(ph)
            ddpos = -du * math.sin(ph) + dw * math.cos(ph)
            vel = dpos * 2 * math.pi * taud
            acc = ddpos * (2 * math.pi * taud) ** 2 + dpos * 2 * math.pi * taudd
            powers.append(F(pos, vel, acc)[:n] @ vel)
        powers = np.array(powers)
        h = T / samples
        work = h / 3 * (powers[0] + powers[-1] + 4 * powers[1:-1:2].sum() + 2 * powers[2:-1:2].sum())
        gross = np.abs(powers).sum() * h
        out.append(
            Check(
                "closed cycle",
                abs(work) <= 1e-5 * gross + 1e-9,
                f"net work {work:.3g} J around a joint-space loop from rest to rest (gross {gross:.3g} J)",
            )
        )

        # 6. the pose fits the controller's kinematic model
        ik, where = _controller_ik(subject.parameters)
        coordinates = [POSE.index(c) for c in (topology.names if topology is not None else ("z", "psi", "theta"))]
        worst = 0.0
        for _ in range(5):
            rho = np.array(home) + rng.uniform(-amplitude, amplitude, n)
            pose = F(rho, zero, zero)[n:]
            worst = max(worst, np.abs(np.array(ik([pose[k] for k in coordinates])) - rho).max())
        out.append(
            Check(
                "controller kinematics",
                worst < 1e-9,
                f"the controller's inverse kinematics ({where}) maps the reported pose back to rho to {worst:.2g} {u}",
            )
        )
    except Refused as err:
        out.append(Check("inside the workspace", False, f"a step near home was refused: {err}"))
        subject.close()
        return out

    # 7. refusal, not NaN
    refusals = []
    far = list(home)
    far[1 % n] += 10.0
    for label, inputs in (
        ("unreachable rho", far + zero + zero),
        ("non-finite input", home + [math.nan] + zero[1:] + zero),
    ):
        try:
            subject.start(home + zero + zero)
            y = subject.step(0.0, inputs)
            refusals.append(f"{label}: accepted, outputs {'finite' if all(map(math.isfinite, y)) else 'not finite'}")
        except Refused:
            refusals.append(f"{label}: refused")
    out.append(
        Check("refuses what it cannot compute", all(r.endswith("refused") for r in refusals), "; ".join(refusals))
    )
    subject.close()
    return out


def check_mechanism(
    target: Union[str, Path], parameters: Optional[Mapping] = None, isolate: bool = True, **kwargs
) -> list[Check]:
    """Checks of an FMU file, or of this project's mechanism model with ``parameters``.

    An FMU runs in a child process (``isolate``): an FMU that crashes its host fails the check
    instead of taking the caller down (pythonfmu FMUs also share one interpreter per process).
    """
    if parameters is not None:
        from fmus.mechanism.model import MechanismBlock

        return check(BlockSubject(MechanismBlock.for_parameters(parameters), parameters), **kwargs)
    if isolate:  # the child's temporary files go to a folder removed here, even if the child crashes
        from ..core.ssp import check_archive
        from ..core.ssv import SSPFormatError

        try:  # an archive no reader of ours opens is named in one line, not in the child's traceback
            check_archive(target)
        except SSPFormatError as err:
            return [Check("runs in a host", False, str(err))]
        with tempfile.TemporaryDirectory(prefix="mast_check_") as tmp:
            proc = subprocess.run(
                [sys.executable, "-m", "mast.hosts.conformance", "--json", str(target)],
                capture_output=True,
                text=True,
                timeout=600,
                env={**os.environ, "TMPDIR": tmp},
            )
        try:
            return [Check(**c) for c in json.loads(proc.stdout.strip().splitlines()[-1])]
        except (IndexError, ValueError, TypeError):
            return [
                Check(
                    "runs in a host",
                    False,
                    f"the checking process ended with code {proc.returncode}: {proc.stderr.strip()[-1000:]}",
                )
            ]
    subject = FMUSubject(target)
    try:
        return check(subject, **kwargs)
    finally:
        subject.dispose()


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``python -m mast.hosts.conformance [--json] FMU``: the checks of one FMU, in this process."""
    args = list(sys.argv[1:] if argv is None else argv)
    as_json = "--json" in args
    args = [a for a in args if a != "--json"]
    results = check_mechanism(args[0], isolate=False)
    if as_json:
        print(json.dumps([{"name": c.name, "passed": c.passed, "detail": c.detail} for c in results]))
    else:
        print("\n".join(map(str, results)))
    return 0 if all(c.passed for c in results) else 1


if __name__ == "__main__":
    sys.exit(main())
