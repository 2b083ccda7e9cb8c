"""Frequency-response extraction, checked on systems with a known answer through the same harness."""

from __future__ import annotations

import math
from pathlib import Path

import control as ct
import numpy as np
import pytest

from fmus.common.block import Block
from fmus.common.parameters import Param
from mast.analyses.frequency import analyse, bandwidth, harmonic, measuring_window
from mast.core.components import BlockComponent
from mast.core.master import Master
from mast.core.motion import SineMotion
from mast.core.ssp import ComponentSpec, Connection, SystemSpec

H = 1e-3  # base step of the toy system [s]
#: a known closed loop: 2nd order, 6 Hz, damping 0.5, with a 4 ms transport delay (Pade, 3rd order)
PLANT = ct.tf([(2 * math.pi * 6) ** 2], [1, 2 * 0.5 * 2 * math.pi * 6, (2 * math.pi * 6) ** 2]) * ct.tf(
    *ct.pade(4e-3, 3)
)
DISCRETE = ct.ss(ct.c2d(PLANT, H, method="zoh"))


class LTIPose(Block):
    """A discrete state-space system from z_cmd to z, standing in for the whole MAST."""

    INPUTS = ("z_cmd",)
    OUTPUTS = ("z", "psi", "theta")
    PARAMETERS = (Param("z0", "m", "operating point"),)

    def initialize(self, t0):
        self.x = np.zeros(DISCRETE.nstates)
        self.values[1:] = [self.params["z0"], 0.0, 0.0]

    def do_step(self, t, h):
        u = self.values[0] - self.params["z0"]
        self.x = DISCRETE.A @ self.x + DISCRETE.B[:, 0] * u
        self.values[1] = self.params["z0"] + float(DISCRETE.C[0] @ self.x)


def known_system() -> tuple[SystemSpec, dict]:
    comps = {"mechanism": ComponentSpec("mechanism", "x", H, ["z_cmd"], ["z", "psi", "theta"], {"z0": 0.4})}
    cons = [Connection("", "z_cmd", "mechanism", "z_cmd")]
    spec = SystemSpec("lti", Path("."), comps, cons, ["z_cmd", "psi_cmd", "theta_cmd"], H, 0.0, None)
    return spec, {"mechanism": BlockComponent("mechanism", LTIPose)}


@pytest.mark.parametrize("f", [0.4, 2.0, 5.0, 10.0, 20.0])
def test_extracted_response_equals_python_control(f):
    spec, comps = known_system()
    start, stop = measuring_window(f)
    result = Master(spec, comps).run(stop, SineMotion("z", 0.002, f), record=["z_cmd", "mechanism.z"], record_step=H)
    measured = analyse(result, "z", 0.002, f, start).ratio
    expected = complex(DISCRETE(np.exp(1j * 2 * math.pi * f * H)))
    # the settling transient decays well within the discarded periods
    assert abs(measured - expected) < 2e-3 * max(1.0, abs(expected)), (measured, expected)
    assert abs(math.degrees(np.angle(measured) - np.angle(expected))) < 0.5


def test_bandwidth_matches_python_control():
    freqs = np.geomspace(0.4, 20.0, 40)
    ratios = [complex(DISCRETE(np.exp(1j * 2 * math.pi * f * H))) for f in freqs]
    fine = np.geomspace(0.4, 20.0, 20000)
    mag = np.abs(DISCRETE(np.exp(1j * 2 * math.pi * fine * H)))
    exact = fine[np.argmax(20 * np.log10(mag) < -3.0)]
    assert bandwidth(freqs, ratios) == pytest.approx(exact, rel=0.01)
    assert bandwidth([1.0, 2.0], [1.0, 0.9]) is None


def test_harmonic_ignores_offset_and_other_harmonics():
    t = np.arange(0, 2.0, 1e-3)
    y = 0.3 + 2.0 * np.cos(2 * np.pi * 1.5 * t - 0.7) + 0.5 * np.sin(2 * np.pi * 4.5 * t)
    assert harmonic(t, y, 1.5) == pytest.approx(2.0 * np.exp(-0.7j), abs=1e-9)
    assert abs(harmonic(t, y, 4.5)) == pytest.approx(0.5, abs=1e-9)


def test_window_is_whole_periods_after_settling():
    for f in (0.4, 3.0, 17.0):
        start, stop = measuring_window(f)
        assert start >= 1.0 and (stop - start) * f == pytest.approx(round((stop - start) * f))
