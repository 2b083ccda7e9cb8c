"""The master's schedule, initialization and error handling, on toy blocks with known answers."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fmus.common.block import Block, ModelError
from fmus.common.parameters import Param
from mast.core.components import BlockComponent
from mast.core.master import Master, SimulationError
from mast.core.ssp import ComponentSpec, Connection, SystemSpec


class Integrator(Block):
    """x(t+h) = x(t) + h u (exact for a held input); y = x."""

    INPUTS = ("u",)
    OUTPUTS = ("y",)
    PARAMETERS = (Param("x0", "1", "initial state"),)

    def initialize(self, t0):
        self.values[1] = self.params["x0"]

    def do_step(self, t, h):
        self.values[1] += h * self.values[0]
        if abs(self.values[1]) > 1e6:
            raise ModelError("state above 1e6")


class Gain(Block):
    """y = k u (algebraic: after a step, the output is k times the held input)."""

    INPUTS = ("u",)
    OUTPUTS = ("y",)
    PARAMETERS = (Param("k", "1", "gain"),)

    def initialize(self, t0):
        self.values[1] = self.params["k"] * self.values[0]

    def do_step(self, t, h):
        self.values[1] = self.params["k"] * self.values[0]


class Clock(Block):
    """y = time at the end of the last step, to check the times the master passes."""

    INPUTS = ()
    OUTPUTS = ("y",)
    PARAMETERS = ()

    def initialize(self, t0):
        self.values[0] = t0

    def do_step(self, t, h):
        self.values[0] = t + h


class Hold:
    reads = ()

    def __init__(self, value=0.0):
        self.value = value

    def start(self, t0, read):
        pass

    def __call__(self, t):
        return [self.value]


def loop_system(h_gain: float, k: float = -2.0, x0: float = 1.0, system_input: bool = False):
    comps = {
        "int": ComponentSpec("int", "resources/int.fmu", 0.01, ["u"], ["y"], {"x0": x0}),
        "gain": ComponentSpec("gain", "resources/gain.fmu", h_gain, ["u"], ["y"], {"k": k}),
    }
    cons = [Connection("int", "y", "gain", "u"), Connection("gain", "y", "int", "u")]
    spec = SystemSpec("loop", Path("."), comps, cons, [], 0.01, 0.0, 1.0)
    blocks = {"int": BlockComponent("int", Integrator), "gain": BlockComponent("gain", Gain)}
    return spec, blocks


def expected_loop(n: int, h: float, k: float, x0: float, m_gain: int) -> np.ndarray:
    """Independent recursion of the Jacobi schedule: the gain samples x every m_gain ticks,
    its output becomes visible m_gain ticks later; the integrator uses the visible value."""
    x = [x0]
    visible = k * x0  # initialization: consistent algebraic value
    pending = visible
    for i in range(n):
        if i % m_gain == 0:
            if i:
                visible = pending
            pending = k * x[-1]
        x.append(x[-1] + h * visible)
    return np.array(x)


@pytest.mark.parametrize("m_gain", [1, 2, 5])
def test_multirate_jacobi_schedule_matches_independent_recursion(m_gain):
    h = 0.01
    spec, blocks = loop_system(h * m_gain)
    result = Master(spec, blocks).run(1.0, Hold(), record=["int.y"])
    want = expected_loop(100, h, -2.0, 1.0, m_gain)
    np.testing.assert_allclose(result["int.y"], want, rtol=0, atol=1e-15)
    assert result.time[-1] == pytest.approx(1.0)
    # and it approximates the continuous solution exp(-2 t) to first order
    assert abs(result["int.y"][-1] - math.exp(-2.0)) < 0.02 * m_gain


def test_step_times_are_multiples_of_component_steps():
    comps = {"clk": ComponentSpec("clk", "x", 0.05, [], ["y"], {})}
    spec = SystemSpec("c", Path("."), comps, [], [], 0.01, 0.0, 1.0)
    result = Master(spec, {"clk": BlockComponent("clk", Clock)}).run(0.2, Hold(), record=["clk.y"])
    # outputs of a 0.05 s component are published at its communication points only
    expected = np.floor(np.round(result.time / 0.05, 9)) * 0.05
    np.testing.assert_allclose(result["clk.y"], expected, atol=1e-12)


def test_step_size_not_multiple_of_base_step_is_rejected():
    spec, blocks = loop_system(0.015)
    with pytest.raises(ValueError, match="gain.*not a whole multiple"):
        Master(spec, blocks)


def test_model_error_names_component_and_time_and_keeps_partial_results():
    spec, blocks = loop_system(0.01, k=1e4)  # unstable: the integrator exceeds 1e6 and raises
    with pytest.raises(SimulationError) as info:
        Master(spec, blocks).run(1.0, Hold(), record=["int.y"])
    message = str(info.value)
    assert message.startswith("int: doStep at t=") and "state above 1e6" in message
    partial = info.value.result
    assert 0 < len(partial.time) < 101 and np.all(np.isfinite(partial["int.y"]))
    # a process pool's worker hands the error back pickled: the message and the partial results survive
    import pickle

    back = pickle.loads(pickle.dumps(info.value))
    assert type(back) is SimulationError and str(back) == message
    assert np.array_equal(back.result.time, partial.time) and np.array_equal(back.result["int.y"], partial["int.y"])


class NaNMaker(Block):
    INPUTS = ()
    OUTPUTS = ("y",)
    PARAMETERS = ()

    def initialize(self, t0):
        self.values[0] = 0.0

    def do_step(self, t, h):
        self.values[0] = float("nan") if t >= 0.05 else 1.0


def test_divergence_to_nan_is_reported_with_signal_name():
    comps = {"bad": ComponentSpec("bad", "x", 0.01, [], ["y"], {})}
    spec = SystemSpec("n", Path("."), comps, [], [], 0.01, 0.0, 1.0)
    with pytest.raises(SimulationError, match=r"bad at t=0.06.*diverged.*y") as info:
        Master(spec, {"bad": BlockComponent("bad", NaNMaker)}).run(1.0, Hold(), record=["bad.y"])
    assert len(info.value.result.time) == 7


def test_unknown_parameter_and_component_overrides_are_rejected():
    spec, blocks = loop_system(0.01)
    with pytest.raises(ValueError, match="unknown component.*nope"):
        Master(spec, blocks).run(0.1, Hold(), parameters={"nope": {"k": 1}})
    spec, blocks = loop_system(0.01)
    with pytest.raises(Exception, match="unknown parameter.*kk"):
        Master(spec, blocks).run(0.1, Hold(), parameters={"gain": {"kk": 1}})


def test_system_input_drives_component_and_start_reads_outputs():
    comps = {"gain": ComponentSpec("gain", "x", 0.01, ["u"], ["y"], {"k": 3.0})}
    spec = SystemSpec("s", Path("."), comps, [Connection("", "cmd", "gain", "u")], ["cmd"], 0.01, 0.0, 1.0)

    class Ramp:
        reads = ()

        def start(self, t0, read):
            self.t0 = t0

        def __call__(self, t):
            return [t]

    result = Master(spec, {"gain": BlockComponent("gain", Gain)}).run(0.1, Ramp(), record=["cmd", "gain.y"])
    np.testing.assert_allclose(result["cmd"], result.time)
    # the gain's output at t_n is 3 * the input it held over the previous step
    np.testing.assert_allclose(result["gain.y"][1:], 3 * result.time[:-1], atol=1e-12)


def test_stop_time_between_ticks_ends_at_the_next_tick():
    spec, blocks = loop_system(0.01)
    result = Master(spec, blocks).run(0.1234, Hold(), record=["int.y"])
    assert result.time[-1] == pytest.approx(0.13)


@pytest.mark.parametrize("record_step", [0.015, 0.001, 0.0])
def test_record_step_not_a_multiple_of_the_base_step_is_refused_not_rounded(record_step):
    spec, blocks = loop_system(0.01)  # base step 0.01 s
    with pytest.raises(ValueError, match=rf"record step {record_step!r} s: expected .*(whole multiple|positive)"):
        Master(spec, blocks).run(0.1, Hold(), record=["int.y"], record_step=record_step)
    result = Master(spec, blocks).run(0.1, Hold(), record=["int.y"], record_step=0.02)
    np.testing.assert_allclose(np.diff(result.time), 0.02, rtol=1e-9)


class SampledGain(Block):
    """y = k u with direct feedthrough: after its input is set at a communication point, y follows it."""

    INPUTS = ("u",)
    OUTPUTS = ("y",)
    PARAMETERS = (Param("k", "1", "gain"),)
    FEEDTHROUGH = {"y": ("u",)}

    def initialize(self, t0):
        self.evaluate()

    def evaluate(self):
        self.values[1] = self.params["k"] * self.values[0]

    def do_step(self, t, h):
        self.evaluate()


def feedthrough_loop(gain_class, m_gain: int = 1, k: float = -2.0):
    """The integrator and a gain in a loop; the gain listed last, so only the dependency order puts it first."""
    spec, _ = loop_system(0.01 * m_gain, k)
    spec.components = {"int": spec.components["int"], "gain": spec.components["gain"]}
    return spec, {"int": BlockComponent("int", Integrator), "gain": BlockComponent("gain", gain_class)}


@pytest.mark.parametrize("m_gain", [1, 2])
def test_feedthrough_output_reaches_the_next_component_in_the_same_exchange(m_gain):
    """With ``feedthrough=True`` (outside FMI 2.0's calling sequence). Independent route, a hand-written sampled
    loop: the gain samples x at its communication points and the integrator applies k x(t_n) from t_n on. A
    command one exchange late (Jacobi, the default) is another sequence."""
    h, k, n = 0.01, -2.0, 100
    spec, blocks = feedthrough_loop(SampledGain, m_gain, k)
    master = Master(spec, blocks, feedthrough=True)
    assert master.exchange_order == ["gain", "int"]
    result = master.run(1.0, Hold(), record=["int.y"])
    x, command = [1.0], None
    for i in range(n):
        if i % m_gain == 0:
            command = k * x[-1]
        x.append(x[-1] + h * command)
    np.testing.assert_allclose(result["int.y"], x, rtol=0, atol=1e-15)
    late = Master(*feedthrough_loop(Gain, m_gain, k)).run(1.0, Hold(), record=["int.y"])
    assert np.max(np.abs(late["int.y"] - np.array(x))) > 1e-3
    default = Master(*feedthrough_loop(SampledGain, m_gain, k))  # Jacobi: the declared feedthrough not used
    assert default.exchange_order == ["int", "gain"]
    np.testing.assert_array_equal(default.run(1.0, Hold(), record=["int.y"])["int.y"], late["int.y"])


def test_a_loop_through_feedthrough_outputs_alone_is_refused():
    spec, _ = loop_system(0.01)
    blocks = {"int": BlockComponent("int", SampledGain), "gain": BlockComponent("gain", SampledGain)}
    with pytest.raises(ValueError, match="algebraic loop through the direct feedthrough of int, gain"):
        Master(spec, blocks, feedthrough=True)
    assert Master(spec, blocks).exchange_order == ["int", "gain"]  # Jacobi by default: no loop to refuse


def test_fmu_feedthrough_is_read_from_the_model_structure(tmp_path):
    """ModelStructure dependencies: an explicit list of inputs is feedthrough; an empty or absent one is none."""
    from fmpy import read_model_description

    from mast.core.components import feedthrough_of

    start = {"input": ' start="0"', "output": ""}
    variables = "".join(
        f'<ScalarVariable name="{n}" valueReference="{i}" causality="{c}"><Real{start[c]}/></ScalarVariable>'
        for i, (n, c) in enumerate([("a", "input"), ("b", "input"), ("y", "output"), ("z", "output"), ("w", "output")])
    )
    (tmp_path / "modelDescription.xml").write_text(
        '<?xml version="1.0" encoding="UTF-8"?><fmiModelDescription fmiVersion="2.0" modelName="m" guid="{g}">'
        '<CoSimulation modelIdentifier="m"/>'
        f"<ModelVariables>{variables}</ModelVariables><ModelStructure><Outputs>"
        '<Unknown index="3" dependencies="2"/><Unknown index="4" dependencies=""/><Unknown index="5"/>'
        "</Outputs></ModelStructure></fmiModelDescription>"
    )
    assert feedthrough_of(read_model_description(str(tmp_path / "modelDescription.xml"))) == {"y": frozenset({"b"})}
