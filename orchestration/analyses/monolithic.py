"""The monolithic reference: the drives and the mechanism integrated as one system, to measure what the exchange costs.

A co-simulation steps each actuator under the mechanism's force of the last exchange. Here the same models are
one system of ordinary differential equations: every drive's state (current, angles and speeds of its chain:
``fmus.actuator.model.state_matrices``, its guide friction ``guide_friction``, the carriage's weight and the
position ripple), and at every evaluation the mechanism's joint-space mass M and bias b at the pose its direct
kinematics gives for the carriages' positions (``Engine.dk``, ``Engine.inertial``), the load sides' accelerations
from the coupled equations

    (m + M) rho_ddot = m a_0 - b,        F = M rho_ddot + b,

m = diag(J_N / i_R^2) the load sides' masses, a_0 what each load side would accelerate at without the mechanism.
scipy's Radau integrates it at a tight tolerance between the drive's current-loop ticks, over which each drive's
voltage is held, as the drive holds it (``fmus.actuator.drive``: the PI on the current at each tick, its voltage
applied from the next). The controller and every other component are the co-simulation's own, stepped by the same
master at the same instants: only the drive-mechanism exchange differs.

The drives run without a torque measurement model and without backlash (refused: not what this reference measures).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Mapping, Optional, Sequence, Union

import numpy as np
from scipy.integrate import solve_ivp

from fmus.actuator.drive import DriveActuatorBlock, current_gains, pi_step
from fmus.actuator.model import guide_friction
from fmus.common.block import Block, ModelError
from fmus.common.parameters import Value
from fmus.mechanism.model import MechanismBlock

from ..core.components import BlockComponent, ComponentError
from ..core.master import Result, Stimulus
from ..core.run import simulate

__all__ = ["RTOL", "Plant", "simulate_monolithic"]

#: Radau's relative tolerance; the absolute ones follow from it per state (``Plant._atol``)
RTOL = 1e-10


class Plant:
    """The drives and the mechanism of one run as one system (module docstring): the blocks of their components
    keep the parameters, the inputs the master sets and the outputs it reads; ``advance`` integrates."""

    def __init__(self, rtol: float = RTOL) -> None:
        self.rtol = rtol
        self.drives: dict[int, DriveActuatorBlock] = {}
        self.mechanism: Optional[MechanismBlock] = None
        self._t = math.nan  # the communication point the plant was last advanced from

    def attach(self, name: str, block: Block) -> None:
        """Take the block of the component ``name`` (actuator_k or the mechanism) as a part of the plant."""
        if isinstance(block, MechanismBlock):
            self.mechanism = block
            return
        p = block.params
        if block.axis.params["backlash"] > 0.0 or not (p["T_meas"] == p["delay_meas"] == p["tau_offset"] == 0.0):
            raise ModelError(f"{name}: the monolithic reference has no backlash and no torque measurement model")
        self.drives[int(name.rsplit("_", 1)[1])] = block

    def start(self) -> None:
        """The state at rest, as the blocks' ``initialize`` left it (every drive at rest, no voltage yet)."""
        order = sorted(self.drives)
        self._order = order
        axes = [self.drives[k].axis for k in order]
        self._sizes = [2 * a.N + 1 for a in axes]
        self._x = np.zeros(sum(self._sizes))
        self._x_c = np.zeros(len(order))
        self._u = np.zeros(len(order))
        self._q = None  # the first direct kinematics starts from the description's guess, as the mechanism's
        self._atol = np.concatenate([self._tolerances(a, self.rtol) for a in axes])
        self._t = math.nan

    @staticmethod
    def _tolerances(axis, rtol: float) -> np.ndarray:
        """Absolute tolerances per state: ``rtol`` of 10 kA (1e-6 A at ``RTOL``), of a metre of carriage travel in
        rad, of a kilometre per second in rad/s."""
        N = axis.N
        turn = rtol / axis.i_R
        return np.array([1e4 * rtol] + [turn] * N + [turn * 1e3] * N)

    def advance(self, t: float, h: float) -> None:
        """From t to t + h [s] (once per communication point, whichever of its components the master steps
        first): the drives' ticks of T_cur, each integrated with its voltage held; the outputs written."""
        if t == self._t:
            return
        T = self.drives[self._order[0]].T_cur
        m = round(h / T)
        if m < 1 or abs(h - m * T) > 1e-6 * T:
            raise ModelError(f"step size h = {h!r} s is not a positive integer multiple of T_cur = {T!r} s")
        for k in range(m):
            self._tick(t + k * T, T)
        self._t = t
        self._write()

    def _tick(self, t: float, T: float) -> None:
        u_next = np.empty_like(self._u)
        at = 0
        for j, (k, size) in enumerate(zip(self._order, self._sizes)):
            drive = self.drives[k]
            p = drive.params
            gains = current_gains(float(p["k_pc"]), float(p["k_ic"]), drive.T_cur, float(p["u_max"]))
            u_next[j], self._x_c[j] = pi_step(drive.values[0] - self._x[at], self._x_c[j], *gains)
            at += size
        sol = solve_ivp(
            self._rhs, (t, t + T), self._x, method="Radau", rtol=self.rtol, atol=self._atol, first_step=T / 16
        )
        if sol.status != 0:
            raise ModelError(f"the monolithic integration failed at t = {t:.9g} s: {sol.message}")
        self._x = sol.y[:, -1]
        self._u = u_next
        self._check(t + T)

    def _split(self, x: np.ndarray):
        at = 0
        for k, size in zip(self._order, self._sizes):
            yield self.drives[k].axis, x[at : at + size]
            at += size

    def _joint(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(rho [m], rho_dot [m/s]) of the carriages."""
        rho, rate = [], []
        for axis, xs in self._split(x):
            rho.append(axis.params["rho_0"] + axis.i_R * xs[axis.N])
            rate.append(axis.i_R * xs[2 * axis.N])
        return np.array(rho), np.array(rate)

    def _forces(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple]:
        """(dx/dt, rho_ddot [m/s^2], F [N], q) of the coupled equations at the state x (module docstring)."""
        rho, rate = self._joint(x)
        eng = self.mechanism.engine
        q, J, _ = eng.dk(rho, self._q)
        n = len(rho)
        out = eng.inertial(q, J, rate, [0.0] * n)
        M = np.array(out[n + 6 : n + 6 + n * n]).reshape(n, n)
        b = np.array(out[n + 6 + n * n :])
        if not self.mechanism.attached:
            M, b = np.zeros((n, n)), np.zeros(n)
        dx, a0, m = [], np.empty(n), np.empty(n)
        for j, (axis, xs) in enumerate(self._split(x)):
            p, N = axis.params, axis.N
            u = min(max(self._u[j], -p["u_supply"]), p["u_supply"])
            d = axis.A @ xs + axis.B[:, 0] * u
            w = xs[2 * N]
            tau = -axis.constants["weight"] - guide_friction(w, p["tau_c"], p["omega_c"], p["tau_s"], p["omega_s"])
            if p["tau_ripple"] > 0.0:
                tau -= p["tau_ripple"] * math.sin(2.0 * math.pi * axis.i_R * xs[N] / p["ripple_period"])
            bw = axis.B[2 * N, 1]
            d[2 * N] += bw * tau
            a0[j] = axis.i_R * d[2 * N]
            m[j] = 1.0 / (bw * axis.i_R * axis.i_R)
            dx.append(d)
        a = np.linalg.solve(np.diag(m) + M, m * a0 - b)
        F = M @ a + b
        for j, (axis, _) in enumerate(self._split(x)):
            dx[j][2 * axis.N] = a[j] / axis.i_R
        return np.concatenate(dx), a, F, q

    def _rhs(self, t: float, x: np.ndarray) -> np.ndarray:
        return self._forces(x)[0]

    def _check(self, t: float) -> None:
        rho, _ = self._joint(self._x)
        for k, r in zip(self._order, rho):
            p = self.drives[k].axis.params
            if not p["rho_min"] <= r <= p["rho_max"]:
                raise ModelError(
                    f"actuator_{k}: carriage left the stroke [{p['rho_min']:g}, {p['rho_max']:g}] m: "
                    f"rho = {r:.6g} m at t={t:.9g} s"
                )

    def _write(self) -> None:
        """The outputs of the state into the blocks' values, where the master reads them."""
        _, a, F, q = self._forces(self._x)
        self._q = q
        rho, rate = self._joint(self._x)
        for j, (axis, xs) in enumerate(self._split(self._x)):
            drive, N = self.drives[self._order[j]], axis.N
            tau_m = axis.params["k_T"] * xs[0]
            outputs = {
                "rho": rho[j],
                "rho_dot": rate[j],
                "rho_ddot": a[j],
                "theta_m": xs[1],
                "omega_m": xs[N + 1],
                "i_m": xs[0],
                "tau_m": tau_m,
                "tau_meas": tau_m,
                "u": self._u[j],
            }
            for name, value in outputs.items():
                drive.values[drive.index(name)] = float(value)
        mech = self.mechanism
        values = dict(zip(mech.OUTPUTS, [*F, *mech.engine.pose(q)]))
        for name, value in values.items():
            mech.values[mech.index(name)] = float(value)


class PlantComponent(BlockComponent):
    """An actuator or the mechanism of a run as a part of the ``Plant``: its block holds the parameters, inputs
    and outputs; the plant steps it."""

    def __init__(self, name: str, block_class: type[Block], plant: Plant) -> None:
        super().__init__(name, block_class)
        self.plant = plant

    def enter_initialization(self, start_time: float, stop_time: float, parameters: Mapping[str, Value]) -> None:
        super().enter_initialization(start_time, stop_time, parameters)
        self._run("parameters", lambda: self.plant.attach(self.name, self.block))

    def exit_initialization(self) -> None:
        super().exit_initialization()
        if self.plant.mechanism is self.block:  # the mechanism is initialised after the drives (SSD order)
            self._run("initialization", self.plant.start)

    def stepper(self):
        def do_step(t: float, h: float) -> None:
            try:
                self.plant.advance(t, h)
            except Exception as err:
                raise ComponentError(f"{self.name}: doStep at t={t:.6g} s: {type(err).__name__}: {err}") from None

        return do_step


def simulate_monolithic(
    ssp: Union[str, Path],
    stimulus: Stimulus,
    stop_time: float,
    parameters: Optional[Mapping[str, Mapping[str, Value]]] = None,
    record: Optional[Sequence[str]] = None,
    record_step: Optional[float] = 1e-3,
    base_step: Optional[float] = None,
    step_sizes: Optional[Mapping[str, float]] = None,
    rtol: float = RTOL,
) -> Result:
    """``mast.core.run.simulate(..., direct=True)`` with the actuators and the mechanism one system (module
    docstring), integrated to the relative tolerance ``rtol``; the same arguments, the same signals."""
    plant = Plant(rtol)

    def component(name: str, block_class: type[Block]) -> BlockComponent:
        if issubclass(block_class, (DriveActuatorBlock, MechanismBlock)):
            return PlantComponent(name, block_class, plant)
        return BlockComponent(name, block_class)

    return simulate(
        ssp, stimulus, stop_time, parameters, record, record_step, direct=True, base_step=base_step,
        step_sizes=step_sizes, component=component,
    )  # fmt: skip
