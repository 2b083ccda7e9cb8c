"""The controller's own inverse dynamic model of the machine (computed torque, torque feed-forward).

Motor torque [N m] axis j needs for the joint motion (rho, rho_dot, rho_ddot), everything
referred to the motor shaft through i_R = p / (2 pi i_r) (paper Eq. 1):

    tau_m_j = J rho_ddot_j / i_R + b_v w_j + tau_f(w_j) + i_R (M_load g_guide + F_j),   w_j = rho_dot_j / i_R

J = J1 + J2 is the actuator's inertia with its transmission taken rigid (Eqs. 20-22; the
733 Hz transmission mode lies far above any control bandwidth here), tau_f the guide
friction (Eq. 23, with the Stribeck excess when the set has one), M_load g_guide the
carriage's weight along the guide (M_load = 0: an actuator whose moving part is a body of the
mechanism, as a 3-RPS's or 6-UPS's leg, which is then in F), and F_j the force the mechanism
needs from actuator j: its inverse dynamics (Eq. 32, the engine of ``fmus/mechanism``, with the payload; zero
when ``attached`` = 0).

How the controller gets the model: its own copy. The same model code as the mechanism FMU
runs here, parametrised by the same parameter sets the SSP binds to the plant (actuator,
geometry, masses), so the controller is exact by default, and a mismatch is a binding:
give the mechanism a payload the controller's sets do not have (``--set
mechanism.m_payload=5``), or bind the controller other sets. The alternative, the
mechanism FMU exchanging M(q) and the bias forces as signals, would be exact always
(no mismatch to study), would add 12 signals and a step of delay to the interface, and no
real controller can ask its plant for its mass matrix. The price of the copy is
computation in the controller: one direct kinematics (warm-started Newton) and one
inverse dynamics per evaluation, about 0.1 ms.
"""

from __future__ import annotations

from typing import Mapping, Optional, Sequence

from ..actuator.model import PARAMETERS as ACTUATOR_PARAMETERS
from ..actuator.model import guide_friction, real_or_traced, transmission_ratio, two_inertia
from ..common.parameters import Value
from ..mechanism.designs import MASS_PARAMETERS, PAYLOAD_PARAMETERS, engine, kinematic_engine
from ..mechanism.engine import Engine
from ..mechanism.kinematics import KinematicsError
from ..mechanism.model import restarted_dk

_ACTUATOR = {p.name: p for p in ACTUATOR_PARAMETERS}

#: the model's parameters: the plant's own declarations (bind the plant's sets to the controller)
MODEL_PARAMETERS = (
    *(_ACTUATOR[n] for n in ("k_T", "J_motor", "J_gearbox", "J_coupling", "J_brake", "J1_scale", "J_guide")),
    # the actuator's own carriage on its guide (0: an actuator without one, e.g. a 3-RPS's or 6-UPS's leg, whose
    # moving part is a body of the mechanism and so in its inverse dynamics F: docs/designs/3rps.md)
    _ACTUATOR["M_load"],
    *(_ACTUATOR[n] for n in ("tau_c", "omega_c", "b_v", "tau_s", "omega_s", "g_guide")),
    *MASS_PARAMETERS,
    *PAYLOAD_PARAMETERS,
)


def motor_torque(
    rho_dot: float,
    rho_ddot: float,
    F: float,
    J: float,
    i_R: float,
    b_v: float,
    weight: float,
    tau_c: float,
    omega_c: float,
    tau_s: float,
    omega_s: float,
) -> float:
    """tau_m [N m] of one axis (module docstring) for its joint motion and the mechanism's force F [N].
    Written in the generated-code subset: the native controllers run this source (mast.core.native.models)."""
    w = rho_dot / i_R
    return J * rho_ddot / i_R + b_v * w + guide_friction(w, tau_c, omega_c, tau_s, omega_s) + i_R * (weight + F)


#: the numbers ``motor_torque`` takes from the actuator's parameters (``model_constants``), in its argument order
#: after F, and k_T
CONSTANTS = ("J", "i_R", "b_v", "weight", "tau_c", "omega_c", "tau_s", "omega_s", "k_T")


def model_constants(params: Mapping[str, Value]) -> dict[str, float]:
    """The model's actuator constants (``CONSTANTS``) from the actuator's parameters: J = J1 + J2 [kg m^2]
    (``two_inertia``, Eqs. 20-22), i_R [m/rad], b_v [N m s/rad], weight = M_load g_guide [N], the guide
    friction's tau_c, omega_c, tau_s, omega_s and k_T [N m/A]. A traced number passes through (``real_or_traced``):
    the native feed-forward and computed-torque controllers compute them at initialisation with this code."""
    J1, J2 = two_inertia(params)
    f = {
        k: real_or_traced(params[k])
        for k in ("p", "i_r", "b_v", "M_load", "g_guide", "tau_c", "omega_c", "tau_s", "omega_s", "k_T")
    }
    return {
        "J": J1 + J2,
        "i_R": transmission_ratio(f["p"], f["i_r"]),
        "b_v": f["b_v"],
        "weight": f["M_load"] * f["g_guide"],
        "tau_c": f["tau_c"],
        "omega_c": f["omega_c"],
        "tau_s": f["tau_s"],
        "omega_s": f["omega_s"],
        "k_T": f["k_T"],
    }


class InverseModel:
    """Motor torques for a joint motion (module docstring), from validated parameters.

    ``dynamics``: the mechanism's engine (with its bodies), by default the one the parameter sets select
    (designs.engine; none when ``attached`` = 0); ``n``: the number of axes, by default the mechanism's.
    """

    def __init__(
        self, params: Mapping[str, Value], owner: str = "", dynamics: Optional[Engine] = None, n: Optional[int] = None
    ) -> None:
        P = params
        self.owner = owner or "controller"
        c = model_constants(P)
        self.i_R = c["i_R"]
        #: rigid actuator inertia at the motor shaft [kg m^2]
        self.J = c["J"]
        self.k_T = c["k_T"]
        self.b_v = c["b_v"]
        self._friction = tuple(c[n] for n in ("tau_c", "omega_c", "tau_s", "omega_s"))
        self.weight = c["weight"]  # [N] along the guide
        attached = bool(int(P["attached"]))
        self.engine = (dynamics if dynamics is not None else engine(P, self.owner)) if attached else None
        #: the number of axes (motors)
        self.n = n if n is not None else (self.engine or kinematic_engine(P, self.owner)).n
        if attached and self.engine.n != self.n:
            raise ValueError(f"{self.owner}: inverse model of {self.n} axes with a mechanism of {self.engine.n} drives")
        self._guess = None
        self._found = self._failure = None  # the last direct kinematics' solution, or failure (mechanism.model.dk)

    @property
    def warm_start(self):
        """The direct kinematics' last solution (the next one starts from it; None: a cold start)."""
        return self._guess

    @warm_start.setter
    def warm_start(self, q) -> None:
        self._guess = q

    def torques(self, rho: Sequence[float], rho_dot: Sequence[float], rho_ddot: Sequence[float]) -> list[float]:
        """tau_m [N m] of the n motors; KinematicsError (naming the controller) if rho is unreachable."""
        i_R = self.i_R
        if self.engine is None:
            F = (0.0,) * self.n
        else:
            try:  # as the mechanism block: warm start, else cold; no cold restart across a singularity
                if restarted_dk(rho, 0.0 if self._guess is None else 1.0, self, None):
                    raise self._failure
                q, Jq, _ = self._found
                F = self.engine.forces(q, Jq, rho_dot, rho_ddot)
            except KinematicsError as exc:
                raise KinematicsError(f"{self.owner}: inverse dynamic model at rho = {tuple(rho)!r} m: {exc}") from exc
            self._guess = q
        return [
            motor_torque(rho_dot[j], rho_ddot[j], F[j], self.J, i_R, self.b_v, self.weight, *self._friction)
            for j in range(self.n)
        ]

    def currents(self, rho: Sequence[float], rho_dot: Sequence[float], rho_ddot: Sequence[float]) -> list[float]:
        """The motor currents [A] of ``torques`` (tau_m / k_T)."""
        return [tau / self.k_T for tau in self.torques(rho, rho_dot, rho_ddot)]
