"""`mast check-mechanism`: does a mechanism FMU honour the MAST interface? (docs/interfaces.md)

Black-box checks, run on the FMU alone (or on a Block with the same variables), that any
correct inverse dynamics of a rigid mechanism driven by three joints passes:

1. interface: inputs rho_i, rho_dot_i, rho_ddot_i, outputs F_i and the pose, with their units;
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

INPUTS = tuple(f"rho_{i}" for i in (1, 2, 3)) + tuple(f"rho_dot_{i}" for i in (1, 2, 3)) + \
    tuple(f"rho_ddot_{i}" for i in (1, 2, 3))
OUTPUTS = ("F_1", "F_2", "F_3", "x", "y", "z", "psi", "theta", "phi")
UNITS = {**{f"rho_{i}": "m" for i in (1, 2, 3)}, **{f"rho_dot_{i}": "m/s" for i in (1, 2, 3)},
         **{f"rho_ddot_{i}": "m/s2" for i in (1, 2, 3)}, **{f"F_{i}": "N" for i in (1, 2, 3)},
         "x": "m", "y": "m", "z": "m", "psi": "rad", "theta": "rad", "phi": "rad"}
STEP = 1e-3


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
    """What the checks drive: set the nine inputs, step, read the nine outputs."""

    variables: dict            # name -> (causality, unit or None)
    parameters: dict           # name -> default value
    init_outputs: Optional[list] = None   # outputs read in initialization mode (FMUs only)

    def start(self, inputs: Sequence[float]) -> list[float]: ...
    def step(self, t: float, inputs: Sequence[float]) -> list[float]: ...
    def close(self) -> None: ...


class BlockSubject(_Subject):
    """A Block (this project's model, or a test double) called directly."""

    def __init__(self, block_class, parameters: Mapping) -> None:
        self.block_class, self.parameters = block_class, dict(parameters)
        units = getattr(block_class, "UNITS", {})
        self.variables = {**{n: ("input", units.get(n)) for n in block_class.INPUTS},
                          **{n: ("output", units.get(n)) for n in block_class.OUTPUTS}}
        self.block = None

    def _io(self):
        return [self.block.index(n) for n in INPUTS], [self.block.index(n) for n in OUTPUTS]

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
        self.variables = {v.name: (v.causality, v.unit or (v.declaredType.unit if v.declaredType else None))
                          for v in self.md.modelVariables}
        convert = {"Real": float, "Integer": int, "Enumeration": int, "String": str,
                   "Boolean": lambda s: str(s).lower() in ("true", "1")}
        self.parameters = {v.name: convert.get(v.type, str)(v.start) for v in self.md.modelVariables
                           if v.causality == "parameter" and v.start is not None}
        self.messages: list[str] = []
        self._n = 0

    def _vr(self, names):
        return [self.vars[n].valueReference for n in names]

    def start(self, inputs):
        from fmpy.fmi2 import FMU2Slave

        self.close()
        self._n += 1
        self.slave = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzip,
                               modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=f"check{self._n}")
        self.slave.instantiate(loggingOn=False)
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        self.slave.setReal(self._vr(INPUTS), list(inputs))
        try:      # hosts read outputs in initialization mode (the master reads the home pose there)
            self.init_outputs = list(self.slave.getReal(self._vr(OUTPUTS)))
        except Exception:
            self.init_outputs = None
        try:
            self.slave.exitInitializationMode()
        except Exception as err:
            raise Refused(str(err)) from None
        return list(self.slave.getReal(self._vr(OUTPUTS)))

    def step(self, t, inputs):
        try:
            self.slave.setReal(self._vr(INPUTS), list(inputs))
            self.slave.doStep(currentCommunicationPoint=t, communicationStepSize=STEP)
            return list(self.slave.getReal(self._vr(OUTPUTS)))
        except Exception as err:      # fmpy raises on a status above fmi2Warning
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
    """The controller's inverse kinematics for this mechanism: its geometry parameters when it
    declares them, else the default system's geometry (what the controller would use)."""
    from fmus.mechanism.designs import KINEMATIC_PARAMETERS_NAMES, kinematic_engine

    from ..core.ssp import read_ssd

    base = read_ssd(Path(__file__).resolve().parents[2] / "ssp" / "MAST.ssd").components["controller"].parameters
    own = {k: parameters[k] for k in KINEMATIC_PARAMETERS_NAMES if k in parameters}
    geometry = {**{k: base[k] for k in KINEMATIC_PARAMETERS_NAMES}, **own}
    where = "the mechanism's own geometry parameters" if len(own) == len(KINEMATIC_PARAMETERS_NAMES) else \
        "the default system's controller geometry" + (f" with {', '.join(own)} from the mechanism" if own else "")
    return kinematic_engine(geometry, "controller").ik, where


def check(subject: _Subject, rho0: float = 0.15, amplitude: float = 0.02, seed: int = 1) -> list[Check]:
    """Run the checks of the module docstring; each returns PASS/FAIL with what it measured."""
    out: list[Check] = []
    rng = np.random.default_rng(seed)
    zero = [0.0, 0.0, 0.0]

    # 1. interface
    missing = [n for n in INPUTS if subject.variables.get(n, (None,))[0] != "input"] + \
        [n for n in OUTPUTS if subject.variables.get(n, (None,))[0] != "output"]
    wrong_units = [f"{n} [{subject.variables[n][1]}] (expected {UNITS[n]})" for n in INPUTS + OUTPUTS
                   if n in subject.variables and subject.variables[n][1] not in (None, "", UNITS[n])]
    out.append(Check("interface", not missing and not wrong_units,
                     "all nine inputs and nine outputs, units as specified" if not missing and not wrong_units else
                     f"missing or wrong causality: {', '.join(missing) or 'none'}; units: {', '.join(wrong_units) or 'ok'}"))
    if missing:
        return out

    # 2. home
    home = [rho0] * 3
    try:
        y0 = subject.start(home + zero + zero)
        ok = all(math.isfinite(v) for v in y0)
        detail = (f"at rest at rho = {rho0} m: F = ({', '.join(f'{v:.4g}' for v in y0[:3])}) N, z = {y0[5]:.6g} m"
                  if ok else f"non-finite outputs {y0}")
        early = subject.init_outputs
        if early is not None and not np.allclose(early, y0, rtol=1e-9, atol=1e-12):
            ok = False
            detail += (f"; but in initialization mode, with the same inputs, the outputs were {early}: they must "
                       f"follow the inputs there (hosts read the home pose before leaving initialization)")
        out.append(Check("home", ok, detail))
    except Refused as err:
        out.append(Check("home", False, f"refused at rest at rho = {rho0} m: {err}"))
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
            rho = np.array(home) + rng.uniform(-amplitude, amplitude, 3)
            rd = rng.uniform(-0.2, 0.2, 3)
            f0 = F(rho, rd, zero)[:3]
            M = np.column_stack([F(rho, rd, np.eye(3)[j])[:3] - f0 for j in range(3)])
            a = rng.uniform(-5, 5, 3)
            worst_lin = max(worst_lin, np.abs(F(rho, rd, a)[:3] - f0 - M @ a).max())
            scale = max(scale, np.abs(M).max())
            worst_sym = max(worst_sym, np.abs(M - M.T).max())
            min_eig = min(min_eig, np.linalg.eigvalsh(0.5 * (M + M.T)).min())
        ok = worst_lin <= 1e-6 * scale * 5 + 1e-9 and worst_sym <= 1e-6 * scale + 1e-12 and min_eig >= -1e-9 * scale
        out.append(Check("mass matrix", ok, f"affine in rho_ddot to {worst_lin:.2g} N, M = dF/drho_ddot symmetric to "
                                            f"{worst_sym:.2g} kg, smallest eigenvalue {min_eig:.4g} kg"))

        # 4. quadratic in rho_dot
        worst, ref = 0.0, 1e-12
        for _ in range(3):
            rho = np.array(home) + rng.uniform(-amplitude, amplitude, 3)
            v = rng.uniform(-0.5, 0.5, 3)
            f0, f1, f2 = (F(rho, k * v, zero)[:3] for k in (0, 1, 2))
            worst = max(worst, np.abs((f2 - f0) - 4 * (f1 - f0)).max())
            ref = max(ref, np.abs(f1 - f0).max())
        out.append(Check("velocity terms", worst <= 1e-6 * ref + 1e-9,
                         f"F(2v) - F(0) = 4 (F(v) - F(0)) to {worst:.2g} N (velocity terms up to {ref:.3g} N)"))

        # 5. closed cycle, rest to rest: no net work
        T = 0.4
        u, w = rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3)
        u *= amplitude / np.abs(u).max()
        w *= amplitude / np.abs(w).max()
        n = 400
        work, gross = 0.0, 0.0
        ts = np.linspace(0.0, T, n + 1)
        powers = []
        for s in ts:
            x = s / T
            tau, taud, taudd = 10 * x ** 3 - 15 * x ** 4 + 6 * x ** 5, (30 * x ** 2 - 60 * x ** 3 + 30 * x ** 4) / T, \
                (60 * x - 180 * x ** 2 + 120 * x ** 3) / T ** 2
            ph = 2 * math.pi * tau
            pos = np.array(home) + u * math.sin(ph) + w * (1 - math.cos(ph))
            dpos = u * math.cos(ph) + w * math.sin(ph)
            ddpos = -u * math.sin(ph) + w * math.cos(ph)
            vel = dpos * 2 * math.pi * taud
            acc = ddpos * (2 * math.pi * taud) ** 2 + dpos * 2 * math.pi * taudd
            powers.append(F(pos, vel, acc)[:3] @ vel)
        powers = np.array(powers)
        h = T / n
        work = h / 3 * (powers[0] + powers[-1] + 4 * powers[1:-1:2].sum() + 2 * powers[2:-1:2].sum())
        gross = np.abs(powers).sum() * h
        out.append(Check("closed cycle", abs(work) <= 1e-5 * gross + 1e-9,
                         f"net work {work:.3g} J around a joint-space loop from rest to rest "
                         f"(gross {gross:.3g} J)"))

        # 6. the pose fits the controller's kinematic model
        ik, where = _controller_ik(subject.parameters)
        worst = 0.0
        for _ in range(5):
            rho = np.array(home) + rng.uniform(-amplitude, amplitude, 3)
            pose = F(rho, zero, zero)[3:]
            worst = max(worst, np.abs(np.array(ik((pose[2], pose[3], pose[4]))) - rho).max())
        out.append(Check("controller kinematics", worst < 1e-9,
                         f"the controller's inverse kinematics ({where}) maps the reported pose back to rho "
                         f"to {worst:.2g} m"))
    except Refused as err:
        out.append(Check("inside the workspace", False, f"a step near home was refused: {err}"))
        subject.close()
        return out

    # 7. refusal, not NaN
    refusals = []
    for label, inputs in (("unreachable rho", [rho0, rho0 + 10.0, rho0] + zero + zero),
                          ("non-finite input", [rho0, rho0, rho0, math.nan, 0.0, 0.0] + zero)):
        try:
            subject.start(home + zero + zero)
            y = subject.step(0.0, inputs)
            refusals.append(f"{label}: accepted, outputs {'finite' if all(map(math.isfinite, y)) else 'not finite'}")
        except Refused:
            refusals.append(f"{label}: refused")
    out.append(Check("refuses what it cannot compute", all(r.endswith("refused") for r in refusals), "; ".join(refusals)))
    subject.close()
    return out


def check_mechanism(target: Union[str, Path], parameters: Optional[Mapping] = None, isolate: bool = True,
                    **kwargs) -> list[Check]:
    """Checks of an FMU file, or of this project's mechanism model with ``parameters``.

    An FMU runs in a child process (``isolate``): an FMU that crashes its host fails the check
    instead of taking the caller down (pythonfmu FMUs also share one interpreter per process).
    """
    if parameters is not None:
        from fmus.mechanism.model import MechanismBlock

        return check(BlockSubject(MechanismBlock, parameters), **kwargs)
    if isolate:  # the child's temporary files go to a folder removed here, even if the child crashes
        with tempfile.TemporaryDirectory(prefix="mast_check_") as tmp:
            proc = subprocess.run([sys.executable, "-m", "mast.hosts.conformance", "--json", str(target)],
                                  capture_output=True, text=True, timeout=600, env={**os.environ, "TMPDIR": tmp})
        try:
            return [Check(**c) for c in json.loads(proc.stdout.strip().splitlines()[-1])]
        except (IndexError, ValueError, TypeError):
            return [Check("runs in a host", False, f"the checking process ended with code {proc.returncode}: "
                                                   f"{proc.stderr.strip()[-1000:]}")]
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
