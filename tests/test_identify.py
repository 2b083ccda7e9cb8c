"""The gain identification's pieces: residual scaling and the parameter set it writes."""
from __future__ import annotations

from pathlib import Path

import pytest

from mast import paper
from mast.identify import GAINS, GainFit, _scaled_residuals, write_ssv
from mast.ssp import read_ssd
from mast.ssv import parse_ssv

ROOT = Path(__file__).resolve().parents[1]


def test_residuals_are_scaled_by_the_paper_tolerances():
    exact = {f: v for f, v in paper.POSITION_RESPONSE.items()}
    assert _scaled_residuals(exact) == pytest.approx([0.0] * 6)
    off = {f: (mag * 1.11, ph + 13.0) for f, (mag, ph) in paper.POSITION_RESPONSE.items()}
    assert _scaled_residuals(off) == pytest.approx([1.0, 1.0] * 3)


def test_written_parameter_set_is_valid_and_carries_provenance(tmp_path):
    fit = GainFit({"k_v": 21.5, "k_p": 0.062, "k_i": 3.8}, [0.1] * 6,
                  {f: v for f, v in paper.POSITION_RESPONSE.items()}, 12, 30.0)
    path = tmp_path / "fit.ssv"
    write_ssv(fit, path, "mast fit-gains --out fit.ssv")  # '--' must not break the XML
    values = parse_ssv(path)
    assert {k: values[k].value for k in GAINS} == fit.gains
    assert values["k_v"].unit == "1/s" and "mast fit-gains --out fit.ssv" in values["k_v"].source
    assert "0.4 Hz" in values["k_p"].source and "cost 0.060" in values["k_i"].source


def test_default_system_binds_the_fitted_gains_last():
    system = read_ssd(ROOT / "ssp" / "MAST.ssd")
    fitted = parse_ssv(ROOT / "ssp" / "resources" / "controller_paper_fit.ssv")
    for g in GAINS:
        assert system.components["controller"].parameters[g] == fitted[g].value
        assert "Fitted by" in fitted[g].source


def test_fit_starts_from_the_loop_shaping_design_even_in_a_built_ssp(tmp_path):
    """Built SSPs carry flattened bindings; the start set is then read from the source ssp/resources."""
    from mast.build import build_all
    from mast.identify import start_gains

    build_all(tmp_path, log=lambda *_: None)
    design = parse_ssv(ROOT / "ssp" / "resources" / "controller_joint.ssv")
    assert start_gains(str(tmp_path / "ssp" / "MAST.ssp")) == {g: design[g].value for g in GAINS}
