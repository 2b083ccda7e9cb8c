"""The project's co-simulation master: fixed base step, multi-rate, Jacobi.

Schedule. Every component c has a step size h_c, an integer multiple m_c of the
base step h. At base tick n (t_n = t0 + n h) the components with n % m_c == 0
are *due*. For them the master first publishes the outputs their previous step
produced (valid at t_n), then gives each due component its inputs from the
outputs published so far (every value valid at t_n or sampled at the source's
last communication point) and calls doStep(t_n, h_c). This is a Jacobi scheme:
within one tick the order of the components does not matter, and the FMU
co-simulation and the direct composition are bit-for-bit the same computation.

The calling sequence of FMI 2.0 Co-Simulation (section 4.2.4): in step mode no output is read
after an input was set without a doStep in between. The master keeps it by default: every
component is Jacobi, whatever it declares, so any fixed-step host that follows the standard
(libcosim, ecos) computes the same trajectories at the same step sizes (tests/test_hosts.py,
tests/test_calling_sequence.py).

Direct feedthrough, outside the standard (``feedthrough=True``). An output a component declares
to depend directly on its inputs (FMI 2.0 ModelStructure ``dependencies``; ``Block.FEEDTHROUGH``
in the direct composition) then follows them at a communication point, without a step: at each
tick the master sets the due components' inputs in dependency order (a component whose
feedthrough output feeds another comes first), reads a feedthrough component's outputs right
after setting its inputs (the get after a set that FMI 2.0 forbids in step mode) and passes them
on in the same tick; then it steps the due components. A loop through feedthrough outputs alone
is an algebraic loop: refused when the master is built. Recorded values at t are those before
the exchange at t (a feedthrough output as its last step left it).

Initialization. All components enter initialization mode and get their
parameters (bindings in SSD order, then the caller's overrides). Components
fed by no system input are brought to a consistent initial point first
(``initial.settle``: repeated Jacobi passes until values stop changing, Newton's method
on a loop where the passes do not contract); then the stimulus starts,
reading any output it needs (for example the platform's home pose); pose commands
that would leave the workspace are refused there, before any step (``admissible.py``);
the whole system is iterated to a consistent point before leaving initialization.
"""

from __future__ import annotations

import math
import operator
import time
from dataclasses import dataclass, field
from typing import Callable, Mapping, Optional, Protocol, Sequence

import numpy as np

from fmus.common.parameters import Value
from fmus.mechanism.topology import POSE

from .admissible import check_commands, trajectory_extremes
from .initial import settle
from .ssp import SystemSpec, applicable_parameters


class SimulationError(RuntimeError):
    """The co-simulation stopped; ``result`` keeps everything computed before the failure."""

    def __init__(self, message: str, result: "Result") -> None:
        super().__init__(message)
        self.result = result

    def __reduce__(self) -> tuple:
        """Pickled with its message and result (a process pool's worker hands it back whole)."""
        return type(self), (str(self), self.result)


class Stimulus(Protocol):
    """Drives the system inputs (SSD system connectors)."""

    reads: Sequence[str]  # outputs (element.connector) that start() may read

    def start(self, t0: float, read: Callable[[str], float]) -> None: ...
    def __call__(self, t: float) -> Sequence[float]: ...


@dataclass
class Result:
    """Recorded signals: ``time`` and one array per ``element.connector`` (system inputs by name).

    ``stats`` (from ``Master.run``): base_step [s], ticks, multiples, init_s [s] and ``parameters``, per
    component the values the master set (the SSP's bindings, then the caller's overrides; any other parameter
    has its FMU's default)."""

    time: np.ndarray
    signals: dict[str, np.ndarray]
    wall_time_s: float = 0.0
    error: Optional[str] = None
    stats: dict = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.signals[name]

    def drives(self) -> list[int]:
        """The drives k = 1..n recorded (``actuator_k.rho`` or ``actuator_k.tau_m``: the connector convention)."""
        ks: list[int] = []
        while any(f"actuator_{len(ks) + 1}.{s}" in self.signals for s in ("rho", "tau_m")):
            ks.append(len(ks) + 1)
        return ks

    def coordinates(self) -> list[str]:
        """The coordinates commanded (the system inputs ``<c>_cmd`` recorded), in the pose's order x .. phi."""
        return [c for c in POSE if f"{c}_cmd" in self.signals]

    def write_csv(self, path) -> None:
        names = list(self.signals)
        table = (
            np.column_stack([self.time] + [self.signals[n] for n in names])
            if len(self.time)
            else np.zeros((0, len(names) + 1))
        )
        np.savetxt(path, table, delimiter=",", header=",".join(["time"] + names), comments="", fmt="%.12g")

    @classmethod
    def read_csv(cls, path) -> "Result":
        """The signals of a CSV ``write_csv`` wrote (a header line ``time,NAME,...``, then one row per time)."""
        with open(path, encoding="utf-8") as handle:
            names = handle.readline().strip().split(",")
            rows = handle.read().splitlines()
        table = np.loadtxt(rows, delimiter=",", ndmin=2) if rows else np.empty((0, len(names)))
        if table.shape[1] != len(names):
            raise ValueError(f"{table.shape[1]} columns of numbers under a header of {len(names)} names")
        return cls(table[:, 0].copy(), {n: table[:, j + 1].copy() for j, n in enumerate(names[1:])})


@dataclass
class _Wiring:
    """Compiled data paths of one component."""

    name: str
    multiple: int
    step: float
    sources: list[tuple[int, int]]  # (source slot, index in its published list); slot -1: system inputs
    feedthrough: bool  # outputs follow the inputs at a communication point: read them again after setting
    input_names: list[str]
    set_inputs: Callable
    get_outputs: Callable
    do_step: Callable
    output_names: list[str]


def _gather(indices: Sequence[int]) -> Callable[[Sequence[float]], tuple]:
    """A function picking ``indices`` out of a list, as a tuple (operator.itemgetter, also for 0 or 1 index)."""
    if len(indices) > 1:
        return operator.itemgetter(*indices)
    if len(indices) == 1:
        i = indices[0]
        return lambda values: (values[i],)
    return lambda values: ()


class Master:
    """Runs a SystemSpec whose components are FMUComponent or BlockComponent objects."""

    def __init__(
        self,
        system: SystemSpec,
        components: Mapping[str, object],
        base_step: Optional[float] = None,
        step_sizes: Optional[Mapping[str, float]] = None,
        own_components: bool = True,
        feedthrough: bool = False,
    ) -> None:
        """``own_components=False``: the caller keeps the components (e.g. a Session resets and reuses
        them across runs); ``run`` then leaves them open instead of closing them at the end.
        ``feedthrough=True``: pass declared direct feedthrough on within a tick, a calling sequence FMI 2.0
        Co-Simulation forbids (module docstring); by default every component is Jacobi."""
        self.system = system
        self.components = dict(components)
        self.own_components = own_components
        self.feedthrough = feedthrough
        steps = {name: (step_sizes or {}).get(name, spec.step_size) for name, spec in system.components.items()}
        self.base_step = base_step or system.base_step or min((h for h in steps.values() if h), default=None)
        if not self.base_step:
            raise ValueError(f"system '{system.name}': no base step (no osp:FixedStepAlgorithm and no step size hints)")
        self.multiples = {}
        for name, h in steps.items():
            h = h or self.base_step
            m = round(h / self.base_step)
            if m < 1 or abs(m * self.base_step - h) > 1e-9 * h:
                raise ValueError(
                    f"component '{name}': step size {h:g} s is not a whole multiple of the base step "
                    f"{self.base_step:g} s"
                )
            self.multiples[name] = m
        self.exchange_order = self._exchange_order()

    def _exchange_order(self) -> list[str]:
        """The components in the order their inputs are set at a communication point: with ``feedthrough``,
        one whose feedthrough output feeds another comes before it, SSD order otherwise (Kahn's algorithm)."""
        names = list(self.system.components)
        after: dict[str, set[str]] = {name: set() for name in names}
        for con in self.system.connections if self.feedthrough else ():
            source = self.components.get(con.start_element) if con.start_element else None
            if source is not None and con.start_connector in getattr(source, "feedthrough", {}):
                after[con.end_element].add(con.start_element)
        order: list[str] = []
        while len(order) < len(names):
            ready = [name for name in names if name not in order and after[name] <= set(order)]
            if not ready:
                rest = [name for name in names if name not in order]
                raise ValueError(
                    f"system '{self.system.name}': an algebraic loop through the direct feedthrough of "
                    f"{', '.join(rest)} (each waits for another's feedthrough output at the same "
                    "communication point)"
                )
            order.append(ready[0])
        return order

    # -- initialization -----------------------------------------------------------
    def _initialize(
        self,
        t0: float,
        t1: float,
        parameters: Mapping[str, Mapping[str, Value]],
        stimulus: Stimulus,
        record: Sequence[str],
    ) -> tuple[list[_Wiring], list[list[float]], list[str]]:
        system = self.system
        unknown = sorted(set(parameters) - set(system.components))
        if unknown:
            raise ValueError(
                f"parameter overrides name unknown component(s) {', '.join(unknown)}; components: "
                f"{', '.join(system.components)}"
            )
        order = list(system.components)
        bound = applicable_parameters(
            system,
            {name: self.components[name].parameter_names for name in order},
            {name: getattr(self.components[name], "parameter_units", {}) for name in order},
        )
        merged = {name: {**bound[name], **parameters.get(name, {})} for name in order}
        self.parameters_set = merged
        for name in order:
            self.components[name].enter_initialization(t0, t1, merged[name])

        published_names: dict[str, list[str]] = {name: [] for name in order}
        for con in system.connections:
            if con.start_element and con.start_connector not in published_names[con.start_element]:
                published_names[con.start_element].append(con.start_connector)
        record = list(record)
        for signal in list(record) + list(getattr(stimulus, "reads", ())):
            element, _, connector = signal.rpartition(".")
            if not element:
                if signal not in system.system_inputs:
                    raise ValueError(f"cannot record '{signal}': not a system input; use element.connector")
                continue
            if element not in published_names:
                raise ValueError(f"cannot record '{signal}': no component '{element}'")
            if connector not in published_names[element]:
                published_names[element].append(connector)

        order = self.exchange_order  # the wirings, and the hot loop, in exchange order
        slots = {name: k for k, name in enumerate(order)}
        wirings: list[_Wiring] = []
        for name in order:
            comp = self.components[name]
            incoming = [c for c in system.connections if c.end_element == name]
            sources = [
                (-1, system.system_inputs.index(c.start_connector))
                if not c.start_element
                else (slots[c.start_element], published_names[c.start_element].index(c.start_connector))
                for c in incoming
            ]
            m = self.multiples[name]
            feedthrough = self.feedthrough and bool(set(getattr(comp, "feedthrough", {})) & set(published_names[name]))
            wirings.append(
                _Wiring(
                    name,
                    m,
                    m * self.base_step,
                    sources,
                    feedthrough,
                    [c.end_connector for c in incoming],
                    comp.setter([c.end_connector for c in incoming]),
                    comp.getter(published_names[name]),
                    comp.stepper(),
                    published_names[name],
                )
            )

        published = [[self.components[w.name].start_value(n) for n in w.output_names] for w in wirings]
        plant = [k for k, w in enumerate(wirings) if all(s >= 0 for s, _ in w.sources)]
        self._settle(wirings, plant, published, [0.0] * len(system.system_inputs))

        def read(signal: str) -> float:
            element, _, connector = signal.rpartition(".")
            return published[slots[element]][published_names[element].index(connector)]

        stimulus.start(t0, read)
        # pose commands (the stimulus's, a trajectory component's): refused up front if they leave the workspace
        sources = [trajectory_extremes(system, merged, t0, t1)]
        if system.system_inputs and hasattr(stimulus, "extremes"):
            sources.append(stimulus.extremes(t0, t1))
        for commands in filter(None, sources):
            check_commands(system, merged, *commands, getattr(stimulus, "home_from", "mechanism"))
        self._settle(wirings, range(len(wirings)), published, list(stimulus(t0)))
        for w in wirings:
            self.components[w.name].exit_initialization()
        for k, w in enumerate(wirings):
            published[k] = w.get_outputs()
        return wirings, published, record

    @staticmethod
    def _settle(
        wirings: Sequence[_Wiring],
        members: Sequence[int],
        published: list[list[float]],
        sys_values: Sequence[float],
    ) -> None:
        """The members' consistent initial values (``initial.settle``: Jacobi passes while they contract, Newton on a
        loop that does not, such as an actuator's load-side mass lighter than the mechanism's joint-space mass), in
        ``published``; RuntimeError naming the components whose values did not settle."""
        members = list(members)
        sizes = [len(published[k]) for k in members]
        at = dict(zip(members, np.cumsum([0] + sizes[:-1]).tolist()))
        owners = [wirings[k].name for k, size in zip(members, sizes) for _ in range(size)]
        read = sorted({at[s] + j for k in members for s, j in wirings[k].sources if s in at})

        def evaluate(values: Sequence[float]) -> list[float]:
            for k in members:
                published[k] = list(values[at[k] : at[k] + len(published[k])])
            inputs = [[sys_values[j] if s < 0 else published[s][j] for s, j in wirings[k].sources] for k in members]
            for k, given in zip(members, inputs):
                wirings[k].set_inputs(given)
            return [v for k in members for v in wirings[k].get_outputs()]

        values = settle(evaluate, [v for k in members for v in published[k]], owners, read)
        # the last evaluation's outputs, with the inputs it set (as the plain passes always left them)
        for k in members:
            published[k] = list(values[at[k] : at[k] + len(published[k])])

    def _compiled_loop(
        self,
        wirings: Sequence[_Wiring],
        flat: Sequence[float],
        n_out: int,
        sources: Sequence[int],
        offsets: Sequence[int],
    ):
        """The exchange loop in C (exchange.py) when every component is an FMU and the library is there; else None."""
        from .components import FMUComponent
        from .exchange import CompiledLoop, library

        comps = [self.components[w.name] for w in wirings]
        if not all(isinstance(c, FMUComponent) for c in comps):
            return None
        lib = library()
        if lib is None:
            return None
        units, at = [], 0
        for k, (w, comp) in enumerate(zip(wirings, comps)):
            src = list(sources[at : at + len(w.sources)])
            at += len(w.sources)
            units.append(
                (
                    comp.c_functions(),
                    w.multiple,
                    w.step,
                    w.feedthrough,
                    comp.input_references(w.input_names),
                    src,
                    comp.output_references(w.output_names),
                    offsets[k],
                )
            )
        return CompiledLoop(lib, units, flat, n_out, hold_gil=any(c.runs_python for c in comps))

    # -- run ----------------------------------------------------------------------
    def run(
        self,
        stop_time: float,
        stimulus: Stimulus,
        record: Sequence[str] = (),
        record_step: Optional[float] = None,
        parameters: Optional[Mapping[str, Mapping[str, Value]]] = None,
        start_time: Optional[float] = None,
        progress: Optional[Callable[[float], None]] = None,
    ) -> Result:
        """Simulate from the SSD start time to ``stop_time`` (rounded up to a base tick); see the module docstring."""
        t0 = self.system.start_time if start_time is None else start_time
        h = self.base_step
        if not isinstance(stop_time, (int, float)) or not math.isfinite(stop_time):
            raise ValueError(f"stop time {stop_time!r} s: expected a finite number of seconds")
        if record_step is not None and (
            not isinstance(record_step, (int, float)) or not record_step > 0 or not math.isfinite(record_step)
        ):
            raise ValueError(f"record step {record_step!r} s: expected a positive, finite number of seconds")
        n_ticks = math.ceil((stop_time - t0) / h - 1e-9)  # a stop time between ticks ends at the next tick
        if n_ticks < 1:
            raise ValueError(
                f"stop time {stop_time:g} s: expected at least one base step ({h:g} s) after the start {t0:g} s"
            )
        record_every = 1 if record_step is None else round(record_step / h)
        if record_step is not None and (record_every < 1 or abs(record_every * h - record_step) > 1e-9 * record_step):
            raise ValueError(
                f"record step {record_step!r} s: expected a whole multiple of the base step {h:g} s "
                "(None: every base step)"
            )
        wall0 = time.perf_counter()
        wirings, published, record = self._initialize(t0, stop_time, parameters or {}, stimulus, record)
        init_s = time.perf_counter() - wall0
        slot = {w.name: k for k, w in enumerate(wirings)}
        rec_paths = []
        for signal in record:
            element, _, connector = signal.rpartition(".")
            rec_paths.append(
                (-1, self.system.system_inputs.index(signal))
                if not element
                else (slot[element], wirings[slot[element]].output_names.index(connector))
            )
        cycle = math.lcm(*[w.multiple for w in wirings])
        # The hot loop works on one flat list: every component's published outputs, then the system
        # inputs; each component's inputs and the recorded signals are gathered from it by itemgetter.
        offsets, flat = [], []
        for values in published:
            offsets.append(len(flat))
            flat.extend(values)
        n_out = len(flat)
        flat.extend(stimulus(t0))
        index = lambda s, j: n_out + j if s < 0 else offsets[s] + j  # noqa: E731
        due = [
            [
                (
                    k,
                    offsets[k],
                    offsets[k] + len(w.output_names),
                    _gather([index(s, j) for s, j in w.sources]),
                    w.set_inputs,
                    w.do_step,
                    w.get_outputs,
                    w.step,
                    w.feedthrough,
                )
                for k, w in enumerate(wirings)
                if phase % w.multiple == 0
            ]
            for phase in range(cycle)
        ]
        recorded = _gather([index(s, j) for s, j in rec_paths])
        recorded_at = np.array([index(s, j) for s, j in rec_paths], dtype=np.intp)
        pending = [list(p) for p in published]
        n_rec = n_ticks // record_every + 1
        times = np.empty(n_rec)
        data = np.empty((n_rec, len(record)))
        rows = 0
        report_every = max(1, n_ticks // 100)
        error = None
        n = 0
        compiled = self._compiled_loop(
            wirings, flat, n_out, [index(s, j) for w in wirings for s, j in w.sources], offsets
        )
        self.exchange = compiled  # the last run's compiled loop (None: the Python loop), for hosts/c_host.py

        def record_tick(values) -> None:
            nonlocal rows
            times[rows] = t
            if isinstance(values, np.ndarray):  # the compiled loop's vector: gathered and summed by numpy
                data[rows] = values[recorded_at]
                total = values[:n_out].sum()
            else:
                data[rows] = recorded(values)
                total = sum(values[:n_out])  # NaN and inf propagate through the sum: details only on a hit
            rows += 1
            if total - total != 0.0:
                for k, w in enumerate(wirings):
                    bad = [name for name, v in zip(w.output_names, values[offsets[k] :]) if not math.isfinite(v)]
                    if bad:
                        raise RuntimeError(f"{w.name} at t={t:.6g} s: the run diverged: non-finite {', '.join(bad)}")
            if progress and n % report_every == 0:
                progress(n / n_ticks)

        try:
            if compiled is not None:  # the same schedule in C between recorded ticks (exchange.py)
                shared = np.frombuffer(compiled.flat, dtype=float)  # the C loop's vector itself, not a copy
                while True:
                    t = t0 + n * h
                    if n % record_every == 0:
                        record_tick(shared)
                    if n == n_ticks:
                        break
                    n_next = min(n - n % record_every + record_every, n_ticks)
                    failed = compiled.run(n, n_next, t0, h, stimulus)
                    if failed is not None:
                        n, k, call = failed
                        component = self.components[wirings[k].name]
                        raise component._error(call, t0 + n * h if call == "doStep" else None)
                    n = n_next
            for n in range(n_ticks + 1) if compiled is None else ():
                t = t0 + n * h
                now = due[n % cycle]
                recording = n % record_every == 0
                if n and (now or recording):  # a tick where nothing is due and nothing recorded costs nothing
                    for item in now:
                        flat[item[1] : item[2]] = pending[item[0]]
                    flat[n_out:] = stimulus(t)
                if recording:
                    record_tick(flat)
                if n == n_ticks:
                    break
                for _, lo, hi, gather, set_inputs, _, get_outputs, _, feedthrough in now:
                    set_inputs(gather(flat))
                    if feedthrough:  # its outputs at t, from the inputs just set, for the components after it
                        flat[lo:hi] = get_outputs()
                for k, _, _, _, _, do_step, get_outputs, step, _ in now:
                    do_step(t, step)
                    pending[k] = get_outputs()
        except Exception as err:  # keep what was computed, then report the failure
            error = str(err)
        finally:
            if self.own_components:
                for name in self.components:
                    self.components[name].close()
        result = Result(
            times[:rows].copy(),
            {name: data[:rows, j].copy() for j, name in enumerate(record)},
            wall_time_s=time.perf_counter() - wall0,
            error=error,
            stats={
                "base_step": h,
                "ticks": n,
                "multiples": dict(self.multiples),
                "init_s": init_s,
                "parameters": self.parameters_set,
            },
        )
        if error:
            raise SimulationError(error, result)
        return result
