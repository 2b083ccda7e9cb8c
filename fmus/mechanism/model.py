"""Mechanism block: direct kinematics + inverse dynamics (paper sections 2.1, 3.3).

An algebraic block: from the slider motion (rho, rho_dot, rho_ddot) held over the step
it computes the platform pose (direct kinematics, Newton warm-started from the previous
pose, on its assembly branch and at least ``engine.MARGIN`` from a singularity: a step that
would cross or approach one stops with an error naming the pose, never a silent jump;
docs/mechanism.md) and the forces F_i = t_rho_i each actuator applies to the mechanism along its
guide, positive upward (inverse dynamics). The actuators feel -F_i: the mechanism is
their disturbance (paper section 2).

The mechanism is the one its parameters describe (``designs.py``: the geometry set with its
``kinematics`` model, the bodies, an optional payload), computed by the generic engine
(``engine.py``). With ``attached = 0`` (actuators alone, paper Fig. 10) the block exerts no
force and reports the kinematics of the mechanism as if it were massless.
"""
from __future__ import annotations

import math
from typing import Mapping

from ..common.block import Block, ModelError
from ..common.parameters import ParameterError, Value
from .designs import KINEMATIC_PARAMETERS, MASS_PARAMETERS, PAYLOAD_PARAMETERS, engine
from .engine import SingularityError
from .kinematics import KinematicsError

#: the code of a direct kinematics refused at (or near) a singularity (mast_model.h: MAST_SINGULARITY_ERROR)
SINGULAR = 4


def dk(r0: float, r1: float, r2: float, warm: float, S, out) -> int:
    """One attempt of the direct kinematics of rho = (r0, r1, r2) [m] by ``S`` (a MechanismBlock or an
    InverseModel: its ``engine``), from its last solution ``S._guess`` when ``warm`` (1.0), else from the
    description's guess: 0 (the solution in ``S._found``: q, dq/drho and what ``Engine.forces_kept`` reuses of
    the pose, ``Engine.dk_kept``), SINGULAR or 1 (the exception in ``S._failure``). ``restarted_dk`` calls it;
    the native models' C has its own (``mast_dk3``)."""
    try:
        q, J, _, kept = S.engine.dk_kept((r0, r1, r2), S._guess if warm == 1.0 else None)
    except SingularityError as exc:
        S._failure = exc
        return SINGULAR
    except KinematicsError as exc:
        S._failure = exc
        return 1
    S._found = (q, J, kept)
    return 0


def restarted_dk(r0: float, r1: float, r2: float, warm: float, S, out) -> int:
    """The direct kinematics of rho = (r0, r1, r2) [m] (``dk``, its solution in ``out``), from the last solution
    when ``warm`` (1.0), else from the description's guess; a warm start that fails starts again from the guess,
    but never after a singularity (a cold start could jump to another pose). 0, or the last attempt's code.
    Written in the generated-code subset: the native mechanism and controllers run this source."""
    c = dk(r0, r1, r2, warm, S, out)
    if c != 0 and c != SINGULAR and warm == 1.0:
        c = dk(r0, r1, r2, 0.0, S, out)
    return c


class MechanismBlock(Block):
    """3PRS mechanism: DK and IDP; outputs the actuator forces and the platform pose."""

    INPUTS = ("rho_1", "rho_2", "rho_3",
              "rho_dot_1", "rho_dot_2", "rho_dot_3",
              "rho_ddot_1", "rho_ddot_2", "rho_ddot_3")
    OUTPUTS = ("F_1", "F_2", "F_3", "x", "y", "z", "psi", "theta", "phi")
    PARAMETERS = (*KINEMATIC_PARAMETERS, *MASS_PARAMETERS, *PAYLOAD_PARAMETERS)
    UNITS = {
        **{f"rho_{i}": "m" for i in (1, 2, 3)},
        **{f"rho_dot_{i}": "m/s" for i in (1, 2, 3)},
        **{f"rho_ddot_{i}": "m/s2" for i in (1, 2, 3)},
        **{f"F_{i}": "N" for i in (1, 2, 3)},
        "x": "m", "y": "m", "z": "m", "psi": "rad", "theta": "rad", "phi": "rad",
    }
    DESCRIPTIONS = {
        **{f"rho_{i}": f"Position of slider {i} along its guide from the base plane (vertical guides: "
                       f"its height)" for i in (1, 2, 3)},
        **{f"rho_dot_{i}": f"Velocity of slider {i} along its guide (up positive)" for i in (1, 2, 3)},
        **{f"rho_ddot_{i}": f"Acceleration of slider {i} along its guide (up positive)" for i in (1, 2, 3)},
        **{f"F_{i}": f"Force actuator {i} applies to the mechanism along its guide, positive upward "
                     f"(inverse dynamics t_rho_{i})" for i in (1, 2, 3)},
        "x": "Platform centre P, x (parasitic)",
        "y": "Platform centre P, y (parasitic)",
        "z": "Platform centre P, height above the base plane",
        "psi": "Platform roll about x (R = Rz(phi) Ry(theta) Rx(psi))",
        "theta": "Platform pitch about y",
        "phi": "Platform yaw about z (parasitic)",
    }

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        super().__init__(params, name)
        self.engine = engine(self.params, self.name)
        self.attached = bool(self.params["attached"])
        self._guess = None
        self._found = self._failure = None      # the last direct kinematics' solution, or failure (``dk``)

    # -------------------------------------------------------------------------------------
    def _compute(self, t: float) -> None:
        vals = self.values
        for k in range(9):
            v = vals[k]
            if not math.isfinite(v):
                raise ModelError(f"{self.name}: input '{self.INPUTS[k]}' = {v!r} is not finite at t = {t!r} s")
        rho = (vals[0], vals[1], vals[2])
        eng = self.engine
        try:
            if restarted_dk(vals[0], vals[1], vals[2], 0.0 if self._guess is None else 1.0, self, None):
                raise self._failure
            q, J, kept = self._found
            if self.attached:   # the forces reuse the pose's geometry the direct kinematics computed at q
                out = eng.forces_kept(kept, q, J, (vals[3], vals[4], vals[5]), (vals[6], vals[7], vals[8]))
            else:
                out = (0.0, 0.0, 0.0) + eng.pose(q)
        except KinematicsError as exc:
            raise type(exc)(f"{self.name}: at t = {t!r} s, rho = {rho!r} m: {exc}") from exc   # SingularityError stays one
        except OverflowError as exc:   # the equations built for these parameters (engine.overflow_hint)
            raise ParameterError(f"{self.name}: {exc}") from None
        self._guess = q
        vals[9:18] = out

    def initialize(self, t0: float) -> None:
        """Outputs at t0 from the current inputs (direct kinematics from the level pose)."""
        self._guess = None
        self._compute(t0)

    def do_step(self, t: float, h: float) -> None:
        """Outputs at t + h for the inputs held (algebraic: DK warm-started, then IDP)."""
        self._compute(t + h)
