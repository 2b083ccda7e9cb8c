"""A mechanism FMU written from scratch with pythonfmu: the worked example of docs/interfaces.md.

The simplest mechanism that plugs into the MAST: each carriage carries a lumped mass m that
moves with it along its guide (no coupling between the axes), and the pose it reports is the
paper's 3PRS kinematics (T layout), so the controller's inverse kinematics fits it.

    F_i = m (rho_ddot_i + g)        force actuator i applies, along its guide, positive up

Build it (from the repository root):

    python -c "from pythonfmu import FmuBuilder; FmuBuilder.build_FMU('docs/examples/lumped_mechanism.py', dest='build/fmus')"
    mast check-mechanism build/fmus/LumpedMechanism.fmu
    mast compare --mechanism build/fmus/MastMechanism.fmu build/fmus/LumpedMechanism.fmu --out results/lumped --quick

It needs nothing of this project: numpy and pythonfmu only.
"""  # noqa: E501 (a shell command, whole to be copied)

from __future__ import annotations

import builtins
import math

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.enums import Fmi2Status

JOINTS = [f"rho_{i}" for i in (1, 2, 3)] + [f"rho_dot_{i}" for i in (1, 2, 3)] + [f"rho_ddot_{i}" for i in (1, 2, 3)]
POSE = ["x", "y", "z", "psi", "theta", "phi"]


class LumpedMechanism(Fmi2Slave):
    """Lumped masses on the carriages, poses of the paper's 3PRS (T layout): a minimal mechanism FMU."""

    author = "MAST co-simulation project (example)"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.m, self.g = 0.75, 9.81  # kg per carriage, m/s^2
        # the geometry the controller's kinematic model must use (same names as its parameter set)
        self.kinematics, self.H, self.r, self.L = "3PRS", 0.4, 0.35, 0.26
        self.alpha_1, self.alpha_2, self.alpha_3, self.beta = 0.0, math.pi / 2, math.pi, 0.0
        for name in JOINTS:
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.input, variability=Fmi2Variability.continuous))
        for name in ["F_1", "F_2", "F_3"] + POSE:
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.output, variability=Fmi2Variability.continuous))
        self.register_variable(
            String("kinematics", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        )
        for name in ("m", "g", "H", "r", "L", "alpha_1", "alpha_2", "alpha_3", "beta"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed))
        self._guess = None

    # -- the paper's T layout: inverse kinematics in closed form, direct kinematics by Newton
    def _ik(self, q: np.ndarray) -> np.ndarray:
        z, psi, theta = q
        r, H, L = self.r, self.H, self.L
        x = -r * math.sin(theta) * math.sin(psi)  # parasitic motion of the T layout (y = phi = 0)
        d = (x + r * math.cos(theta), r * math.cos(psi), r * math.cos(theta) - x)  # radial distance of S_i
        h = (z - r * math.sin(theta), z + r * math.cos(theta) * math.sin(psi), z + r * math.sin(theta))
        reach = [L * L - (H - di) ** 2 for di in d]
        if min(reach) <= 0.0 or min(H - di for di in d) <= 0.0:
            raise ValueError(f"pose (z, psi, theta) = {tuple(q)} is not reachable")
        return np.array([hi - math.sqrt(wi) for hi, wi in zip(h, reach)])

    def _dk(self, rho: np.ndarray) -> np.ndarray:
        q = (
            self._guess
            if self._guess is not None
            else np.array([rho.mean() + math.sqrt(self.L**2 - (self.H - self.r) ** 2), 0.0, 0.0])
        )
        for _ in range(30):
            e = self._ik(q) - rho
            if np.abs(e).max() < 1e-12:
                return q
            J = np.column_stack([(self._ik(q + 1e-7 * u) - self._ik(q - 1e-7 * u)) / 2e-7 for u in np.eye(3)])
            q = q - np.linalg.solve(J, e)
        raise ValueError(f"direct kinematics did not converge for rho = {tuple(rho)}")

    def _compute(self) -> None:
        values = [getattr(self, n) for n in JOINTS]
        if not all(math.isfinite(v) for v in values):
            raise ValueError("non-finite input")
        q = self._dk(np.array(values[:3]))
        self._guess = q
        for i in (1, 2, 3):
            setattr(self, f"F_{i}", self.m * (getattr(self, f"rho_ddot_{i}") + self.g))
        z, psi, theta = q
        self.x, self.y, self.z = -self.r * math.sin(theta) * math.sin(psi), 0.0, z
        self.psi, self.theta, self.phi = psi, theta, 0.0

    # in initialization mode the outputs follow the inputs: hosts read the home pose there
    _in_init = False

    def enter_initialization_mode(self) -> None:
        self._in_init = True

    def get_real(self, vrs):
        if self._in_init:
            try:
                self._compute()
            except ValueError:  # inputs not set yet: keep the last outputs
                pass
        return super().get_real(vrs)

    def exit_initialization_mode(self) -> None:
        self._in_init = False
        try:
            self._compute()
        except ValueError as err:
            self.log(f"initial pose: {err}", status=Fmi2Status.error)  # doStep will refuse too

    def do_step(self, current_time: float, step_size: float) -> bool:
        # refuse (False: fmi2Discard) rather than raise: pythonfmu 0.7.0 mishandles the references of
        # an instance whose method raised, and a process running many of them may crash later
        try:
            self._compute()
        except ValueError as err:
            self.log(f"doStep at t = {current_time:g} s: {err}", status=Fmi2Status.error)
            return False
        return True


# pythonfmu 0.7.0 runs this file at every instantiation, then releases one reference to its globals
# that it never took: hold one per run, so that instances can come and go (mast build does the same)
builtins.__dict__.setdefault("_lumped_mechanism_globals", []).append(globals())
