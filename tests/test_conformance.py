"""`mast check-mechanism`: the project's designs pass, and each check catches what it is for."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fmus.common.block import Block
from fmus.mechanism import designs
from fmus.mechanism.model import MechanismBlock
from mast.cli import main as cli_main
from mast.core.designs import DESIGNS, MECHANISMS
from mast.core.ssp import read_ssd
from mast.hosts.conformance import BlockSubject, check, check_mechanism


def verdicts(results) -> dict:
    return {c.name: c.passed for c in results}


@pytest.mark.parametrize("design", DESIGNS + MECHANISMS, ids=lambda d: d.name)
def test_every_design_passes(design):
    """The 3PRS designs and the other mechanisms' (3-RPS, 6-UPS, 6-PUS: their own interface and controller
    kinematics, the description's geometry)."""
    params = read_ssd(design.ssd).components["mechanism"].parameters
    results = check_mechanism("", parameters=params)
    assert all(c.passed for c in results), "\n".join(map(str, results))
    assert len(results) == 7


#: the mechanism contract's own variables (``Variables.required``): no condensed interface
REQUIRED = (MechanismBlock.INPUTS[:9], MechanismBlock.OUTPUTS[:9])


class Broken(Block):
    """A test double with the mechanism's variables; ``kind`` says what it gets wrong."""

    INPUTS, OUTPUTS = REQUIRED
    UNITS = {k: v for k, v in MechanismBlock.UNITS.items() if k in REQUIRED[0] + REQUIRED[1]}
    kind = ""

    def __init__(self, params, name=""):
        self.name, self.params = name or "broken", params
        self.values = [0.0] * 18
        self.engine = designs.engine(params)
        self.geometry = designs.kinematic_engine({**params, "r": params["r"] + 0.001})

    def initialize(self, t0):
        self.do_step(t0, 0.0)

    def do_step(self, t, h):
        v = self.values
        rho, rd, rdd = v[0:3], v[3:6], v[6:9]
        if not all(map(math.isfinite, v[:9])):
            if self.kind != "nan":
                raise ValueError("non-finite input")
            v[9:18] = [math.nan] * 9
            return
        try:
            q, J, _ = self.engine.dk(rho)
        except Exception:
            if self.kind == "nan":
                v[9:18] = [math.nan] * 9
                return
            raise
        if self.kind == "no velocity terms":
            rd = (0.0, 0.0, 0.0)
        F = list(self.engine.forces(q, J, rd, rdd))
        if self.kind == "asymmetric":
            F[0] += 0.3 * rdd[1]
        if self.kind == "other geometry":
            q = self.geometry.dk(rho)[0]
            F[3:9] = self.geometry.pose(q)
        v[9:18] = F


@pytest.mark.parametrize(
    "kind, fails",
    [
        ("no velocity terms", {"closed cycle"}),
        ("asymmetric", {"mass matrix", "closed cycle"}),
        ("other geometry", {"controller kinematics"}),
        ("nan", {"refuses what it cannot compute"}),
    ],
)
def test_each_check_catches_its_fault(mechanism_params, kind, fails):
    cls = type(f"Broken_{kind.replace(' ', '_')}", (Broken,), {"kind": kind})
    results = verdicts(check(BlockSubject(cls, mechanism_params)))
    assert {name for name, ok in results.items() if not ok} == fails, results


def test_wrong_units_and_missing_variables_are_reported(mechanism_params):
    cls = type("WrongUnits", (Broken,), {"UNITS": {**Broken.UNITS, "F_2": "kN"}})
    results = check(BlockSubject(cls, mechanism_params))
    assert not results[0].passed and "F_2 [kN]" in results[0].detail
    cls = type("Missing", (Broken,), {"OUTPUTS": Broken.OUTPUTS[:-1]})
    results = check(BlockSubject(cls, mechanism_params))
    assert len(results) == 1 and "phi" in results[0].detail


def test_cli_checks_an_fmu(tmp_path):
    from mast.core.build import FMUS, build_fmu

    spec = next(s for s in FMUS if s.model_identifier == "MastActuatorsOnly")
    fmu = build_fmu(spec, tmp_path)
    assert cli_main(["check-mechanism", str(fmu)]) == 0
    np.testing.assert_equal(len(check_mechanism(fmu)), 7)


def test_worked_example_passes_and_a_host_trap_is_caught(tmp_path):
    """docs/examples/lumped_mechanism.py passes; without following its inputs in initialization
    mode (where the master reads the home pose) it fails the home check."""
    from pythonfmu import FmuBuilder

    source = (Path(__file__).resolve().parents[1] / "docs" / "examples" / "lumped_mechanism.py").read_text()
    good = tmp_path / "lumped_mechanism.py"
    good.write_text(source)
    start, end = source.index("    def get_real(self, vrs):"), source.index("    def exit_initialization_mode")
    bad = tmp_path / "lumped_no_init.py"
    bad.write_text((source[:start] + source[end:]).replace("LumpedMechanism", "LumpedNoInit"))
    results = {}
    for script in (good, bad):
        fmu = FmuBuilder.build_FMU(script, dest=tmp_path / "fmus", needsExecutionTool=False)
        results[script.stem] = verdicts(check_mechanism(fmu))
    assert all(results["lumped_mechanism"].values()), results
    assert {k for k, ok in results["lumped_no_init"].items() if not ok} == {"home"}, results
