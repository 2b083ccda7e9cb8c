"""Batch co-simulation: session reuse (reset = fresh), config expansion, metrics, crash safety,
atomic results and resume, the CLI, and the same batch on a Dask LocalCluster."""

from __future__ import annotations

import json
import math
import os
import re
import signal
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from mast.analyses.metrics import case_metrics, sweep_metrics
from mast.batch import BatchConfig, BatchConfigError, expand, read_batch, run_batch
from mast.cli import main as cli_main
from mast.core.build import FMUS, SSP_SRC, build_fmu, build_ssp
from mast.core.components import BlockComponent
from mast.core.master import Master, Result, SimulationError
from mast.core.motion import SineMotion
from mast.core.run import simulate
from mast.core.session import Session
from mast.core.ssp import ComponentSpec, Connection, SystemSpec, read_ssd

# test_master's toy blocks
sys.path.insert(0, str(Path(__file__).parent))
from test_master import Gain, Hold, Integrator  # noqa: E402


@pytest.fixture(scope="module")
def ssp(tmp_path_factory) -> Path:
    """build/ssp/MAST.ssp of the default system, built from this tree."""
    out = tmp_path_factory.mktemp("batch_build")
    needed = {Path(c.source).stem for c in read_ssd(SSP_SRC / "MAST.ssd").components.values()}
    for spec in FMUS:
        if spec.model_identifier in needed:
            build_fmu(spec, out / "fmus")
    return build_ssp(SSP_SRC / "MAST.ssd", out / "fmus", out / "ssp")


# -- the master and the session ---------------------------------------------------------------
class Counting(BlockComponent):
    closed = 0

    def close(self) -> None:
        Counting.closed += 1
        super().close()


def _loop():
    comps = {
        "int": ComponentSpec("int", "x", 0.01, ["u"], ["y"], {"x0": 1.0}),
        "gain": ComponentSpec("gain", "x", 0.01, ["u"], ["y"], {"k": -2.0}),
    }
    cons = [Connection("int", "y", "gain", "u"), Connection("gain", "y", "int", "u")]
    spec = SystemSpec("loop", Path("."), comps, cons, [], 0.01, 0.0, 1.0)
    return spec, {"int": Counting("int", Integrator), "gain": Counting("gain", Gain)}


def test_master_closes_only_components_it_owns():
    spec, blocks = _loop()
    Counting.closed = 0
    first = Master(spec, blocks, own_components=False).run(0.5, Hold(), record=["int.y"])
    assert Counting.closed == 0
    again = Master(spec, blocks, own_components=False).run(0.5, Hold(), record=["int.y"])
    np.testing.assert_array_equal(first["int.y"], again["int.y"])
    assert first.stats["init_s"] >= 0
    Master(spec, blocks).run(0.1, Hold(), record=["int.y"])  # the default: the master owns them
    assert Counting.closed == 2


def test_reset_instances_reproduce_fresh_ones(ssp):
    """fmi2Reset (pythonfmu 0.7.0 creates a new Python slave): no parameter or state leaks between runs."""
    motion = dict(axis="z", amplitude=0.004, frequency=4.0)
    heavy = {"mechanism": {"m_platform": 3.0}, "actuator_2": {"tau_c": 0.07}}
    with Session(ssp) as session:
        a = session.run(SineMotion(**motion), 0.15, parameters=heavy)  # fresh instances
        b = session.run(SineMotion(**motion), 0.15)  # reset: the SSD's parameters again
        c = session.run(SineMotion(**motion), 0.15, parameters=heavy)  # reset: the overrides again
        assert (session.instantiations, session.resets) == (1, 2)
        with pytest.raises(SimulationError):  # a failing run discards the instances
            session.run(SineMotion(**motion), 0.5, parameters={"actuator_1": {"g_guide": 5000.0}})  # off its stroke
        d = session.run(SineMotion(**motion), 0.15)
        assert session.instantiations == 2
    fresh = simulate(ssp, SineMotion(**motion), 0.15)
    fresh_heavy = simulate(ssp, SineMotion(**motion), 0.15, parameters=heavy)
    for name in fresh.signals:
        np.testing.assert_allclose(b[name], fresh[name], rtol=1e-12, atol=1e-15, err_msg=name)
        np.testing.assert_allclose(d[name], fresh[name], rtol=1e-12, atol=1e-15, err_msg=name)
        np.testing.assert_allclose(a[name], fresh_heavy[name], rtol=1e-12, atol=1e-15, err_msg=name)
        np.testing.assert_allclose(c[name], fresh_heavy[name], rtol=1e-12, atol=1e-15, err_msg=name)
    assert np.ptp(a["actuator_1.tau_m"] - b["actuator_1.tau_m"]) > 1e-3  # the overrides did change the run


# -- metrics ------------------------------------------------------------------------------------
def test_metrics_of_a_known_signal():
    t = np.arange(0.0, 2.0 + 1e-9, 1e-3)
    f, amp = 2.0, 0.01
    cmd = 0.2 + amp * np.sin(2 * np.pi * f * t)
    got = 0.2 + 0.5 * amp * np.sin(2 * np.pi * f * t - np.pi / 4)
    i_cmd = np.where(t >= 1.5, 10.0, 1.0)  # at the 10 A limit from 1.5 s on
    signals = {
        "z_cmd": cmd,
        "mechanism.z": got,
        "psi_cmd": 0 * t,
        "mechanism.psi": 0 * t,
        "actuator_1.tau_m": 0.3 * np.sin(2 * np.pi * f * t),
        "actuator_1.i_m": 2.0 * np.ones_like(t),
        "controller.i_cmd_1": i_cmd,
        "actuator_1.u": 0 * t,
    }
    m = case_metrics(
        Result(t, signals),
        motion={"axis": "z", "amplitude": amp, "frequency": f},
        start=1.0,
        stop=2.0,
        limits={"i_max": 10.0, "u_max": 24.0},
    )
    assert m["magnitude"] == pytest.approx(0.5, rel=1e-9)
    assert m["phase_deg"] == pytest.approx(-45.0, abs=1e-6)
    assert m["magnitude_dB"] == pytest.approx(20 * math.log10(0.5))
    err = cmd - got
    steady = t >= 1.0 - 1e-9
    assert m["tracking_z_rms_m"] == pytest.approx(np.sqrt(np.mean(err[steady] ** 2)))
    assert m["tracking_z_peak_m"] == pytest.approx(np.max(np.abs(err[steady])))
    assert m["tracking_psi_peak_rad"] == 0.0 and "tracking_theta_rms_rad" not in m  # theta not recorded
    assert m["tau_m_1_peak_Nm"] == pytest.approx(0.3, rel=1e-4)
    assert m["tau_m_1_rms_Nm"] == pytest.approx(0.3 / math.sqrt(2), rel=1e-3)
    assert m["i_m_1_rms_A"] == pytest.approx(2.0) and m["i_m_1_peak_A"] == pytest.approx(2.0)
    assert m["saturation_1_s"] == pytest.approx(0.5, abs=2e-3) and m["saturation_s"] == m["saturation_1_s"]
    assert m["saturation_fraction"] == pytest.approx(0.5, abs=2e-3)


def test_sweep_metrics_bandwidth_by_the_frequency_module():
    f = [1.0, 2.0, 4.0, 8.0]
    mags = [1.0, 0.9, 0.6, 0.3]  # -3 dB (0.708) between 2 and 4 Hz
    m = sweep_metrics(f, mags, [-5, -20, -60, -100])
    expect = math.exp(math.log(2) + (-3 - 20 * math.log10(0.9)) / (20 * math.log10(0.6 / 0.9)) * math.log(2))
    assert m["bandwidth_Hz"] == pytest.approx(expect)
    assert m["peak_frequency_Hz"] == 1.0 and m["n_frequencies"] == 4
    assert math.isnan(sweep_metrics([1.0, 2.0], [1.0, 0.99], [0, -1])["bandwidth_Hz"])  # never crosses


def test_atomic_write_leaves_the_old_file_or_the_new_one(tmp_path, monkeypatch):
    from mast.core import atomic

    target = tmp_path / "case.json"
    atomic.atomic_write(target, b"old")
    monkeypatch.setattr(atomic.os, "replace", lambda *a: (_ for _ in ()).throw(OSError("disk full")))
    with pytest.raises(OSError):
        atomic.atomic_write(target, b"new")
    assert target.read_bytes() == b"old" and [p.name for p in tmp_path.iterdir()] == ["case.json"]
    monkeypatch.undo()
    atomic.atomic_write(target, b"new")
    assert target.read_bytes() == b"new" and len(list(tmp_path.iterdir())) == 1


# -- config and cases --------------------------------------------------------------------------------
def _config(ssp, **cases):
    return {"name": "t", "ssp": {"nominal": str(ssp)}, "run": {"stop_time": 0.1}, "cases": cases}


def test_case_expansion_dimensions_wildcards_and_seeded_samples(ssp):
    config = BatchConfig.from_dict(
        {
            **_config(
                ssp,
                motion=[{"axis": "z", "amplitude": 0.002}, {"axis": "psi", "amplitude": 0.5}],
                frequency=[2, 5],
                grid={"mechanism.m_platform": [1.5, 2.5]},
                list=[{"actuator_*.tau_c": 0.02}, {"actuator_1.tau_c": 0.07}],
                random={
                    "samples": 3,
                    "seed": 7,
                    "actuator_*.J1_scale": {"relative": 0.1},
                    "mechanism.m_leg": {"normal": [0.07, 0.01], "clip": [0.05, 0.09]},
                },
            ),
            "parameters": {"controller.k_v": 20.0},
        }
    )
    cases = expand(config)
    assert len(cases) == 3 * 2 * 2 * 2 * 2  # samples x list x grid x motions x frequencies
    assert [c.id for c in cases[:3]] == ["c00000", "c00001", "c00002"]
    first = cases[0]
    assert first.parameters["controller.k_v"] == 20.0
    assert first.parameters["actuator_3.tau_c"] == 0.02 and "actuator_3.tau_c" in first.parameters
    assert first.motion == {"axis": "z", "amplitude": 0.002, "frequency": 2.0}
    # one relative draw per sample for all actuators, around the SSP's value (J1_scale = 1)
    scales = {first.parameters[f"actuator_{k}.J1_scale"] for k in (1, 2, 3)}
    assert len(scales) == 1 and 0.9 <= scales.pop() <= 1.1
    assert 0.05 <= first.parameters["mechanism.m_leg"] <= 0.09
    # the frequency is the innermost dimension: neighbours share the group (a sweep)
    assert cases[0].group == cases[1].group != cases[2].group and cases[0].digest != cases[1].digest
    # reproducible, and sample-major: more samples keep the first ones
    again = expand(config)
    assert [c.digest for c in again] == [c.digest for c in cases]
    more = BatchConfig.from_dict(
        {**config.raw, "cases": {**config.raw["cases"], "random": {**config.raw["cases"]["random"], "samples": 5}}}
    )
    assert [c.digest for c in expand(more)[: len(cases)]] == [c.digest for c in cases]
    # SSP variants multiply the cases; cases.ssp picks some
    two = {
        **_config(ssp, motion={"axis": "z", "amplitude": 0.002}, frequency=[1, 2]),
        "ssp": {"a": str(ssp), "b": str(ssp)},
    }
    assert [(c.ssp, c.motion["frequency"]) for c in expand(BatchConfig.from_dict(two))] == [
        ("a", 1.0),
        ("a", 2.0),
        ("b", 1.0),
        ("b", 2.0),
    ]
    assert len(expand(BatchConfig.from_dict({**two, "cases": {**two["cases"], "ssp": ["b"]}}))) == 2


@pytest.mark.parametrize(
    "cases, message",
    [
        ({"grid": {"mechanism.m_platfrom": [1.0]}}, "no parameter 'm_platfrom'"),
        ({"grid": {"actuatr_*.tau_c": [1.0]}}, "matches no component"),
        ({"grid": {"tau_c": [1.0]}}, "not ELEMENT.PARAMETER"),
        ({"random": {"samples": 2, "mechanism.m_platform": {"uniform": [1, 2]}}}, "seed"),
        ({"random": {"samples": 2, "seed": 1, "mechanism.m_platform": {"gauss": [1, 2]}}}, "expected one of"),
        ({"motion": {"axis": "x", "amplitude": 1, "frequency": 1}}, "axis must be one of"),
        ({"frequencies": [1]}, "unknown key"),
    ],
)
def test_config_errors_say_what_is_wrong(ssp, cases, message):
    with pytest.raises(BatchConfigError, match=message):
        expand(BatchConfig.from_dict(_config(ssp, **cases)))


@pytest.mark.parametrize(
    "cases, message",
    [
        (
            {"motion": {"axis": "z", "amplitude": 0.001}, "frequency": [1, 0]},
            "cases.frequency = 0: expected a positive",
        ),
        ({"motion": {"axis": "z", "amplitude": 0.001}, "frequency": -1}, "cases.frequency = -1: expected a positive"),
        ({"motion": {"axis": "z", "amplitude": 0.001}, "frequency": math.inf}, "cases.frequency = inf"),
        ({"motion": {"axis": "z", "amplitude": 0.001}, "frequency": "2"}, "cases.frequency = '2'"),
        ({"motion": {"axis": "z", "amplitude": 0.001, "frequency": 0}}, "frequency = 0: expected a positive, finite"),
        ({"motion": {"axis": "psi", "amplitude": 1, "frequency": math.nan}}, "frequency = nan"),
        ({"motion": {"axis": "z", "amplitude": 0.001}}, "no frequency; give it"),
    ],
)
def test_a_batch_motion_frequency_must_be_positive_and_finite(tmp_path, cases, message):
    """A 0 Hz sine was accepted and ran silently as no motion at all."""
    with pytest.raises(BatchConfigError, match=re.escape(message)):
        BatchConfig.from_dict({"ssp": str(tmp_path / "none.ssp"), "cases": cases})


def test_kept_signals_are_checked_before_running(ssp):
    config = BatchConfig.from_dict(
        {
            **_config(ssp, motion={"axis": "z", "amplitude": 0.001, "frequency": 5}),
            "outputs": {"keep": ["mechanism.zz"]},
        }
    )
    with pytest.raises(BatchConfigError, match="mechanism.zz not in"):
        expand(config)


def test_toml_and_yaml_configs_give_the_same_cases(ssp, tmp_path):
    (tmp_path / "b.toml").write_text(
        textwrap.dedent(f"""
        ssp = "{ssp}"
        [run]
        stop_time = 0.1
        [cases]
        motion = {{ axis = "theta", amplitude = 0.5, frequency = 10 }}
        [cases.grid]
        "actuator_*.tau_c" = [0.02, 0.07]
        """)
    )
    (tmp_path / "b.yaml").write_text(
        textwrap.dedent(f"""
        ssp: {ssp}
        run: {{stop_time: 0.1}}
        cases:
          motion: {{axis: theta, amplitude: 0.5, frequency: 10}}
          grid: {{"actuator_*.tau_c": [0.02, 0.07]}}
        """)
    )
    toml_cases, yaml_cases = (expand(BatchConfig.load(tmp_path / n)) for n in ("b.toml", "b.yaml"))
    assert [c.digest for c in toml_cases] == [c.digest for c in yaml_cases] and len(toml_cases) == 2


@pytest.mark.parametrize("name, count", [("monte_carlo_bandwidth.toml", 30 * 6), ("friction_sweep.yaml", 3 * 2 * 5)])
def test_example_configs_expand(ssp, name, count):
    config = BatchConfig.load(Path(__file__).resolve().parents[1] / "examples" / name)
    cases = expand(BatchConfig.from_dict({**config.raw, "ssp": str(ssp)}))
    assert len(cases) == count and all(c.motion for c in cases)


def _runaway(tmp_path: Path) -> Path:
    """A config of 10^7 cases (a grid of seven 10-value lists) on an SSP that does not exist: counting must come
    before anything is read."""
    config = tmp_path / "runaway.toml"
    grid = "\n".join(f'"mechanism.p{k}" = {list(range(10))}' for k in range(7))
    config.write_text(f'ssp = "{tmp_path / "none.ssp"}"\n[cases.grid]\n{grid}\n')
    return config


@pytest.mark.parametrize("dry_run", [[], ["--dry-run"]])
def test_a_runaway_batch_is_counted_and_refused_before_anything_is_built(tmp_path, capsys, dry_run):
    """10^7 cases ran out of memory after 85 s with a traceback; now refused at once, naming count and limit."""
    import time

    config = _runaway(tmp_path)
    t0 = time.perf_counter()
    assert cli_main(["batch", str(config), "--out", str(tmp_path / "o"), *dry_run]) == 2
    assert time.perf_counter() - t0 < 5
    err = capsys.readouterr().err
    assert "the config expands to 10000000 cases (10000000 grid points), over the limit of 10000" in err
    assert "--max-cases" in err and "Traceback" not in err
    with pytest.raises(BatchConfigError, match="10000000 cases"):
        run_batch(config, tmp_path / "o", progress=False)
    assert not (tmp_path / "o").exists()
    # a raised limit lets it through to the next check: the missing SSP
    assert cli_main(["batch", str(config), "--out", str(tmp_path / "o"), "--max-cases", "10000000", *dry_run]) == 2
    assert "none.ssp does not exist" in capsys.readouterr().err


def test_the_case_count_is_the_expansions_and_the_help_states_the_default(ssp, capsys):
    from mast.batch import DEFAULT_MAX_CASES, count_cases

    config = BatchConfig.from_dict(
        _config(
            ssp,
            motion=[{"axis": "z", "amplitude": 0.002}, {"axis": "psi", "amplitude": 0.5}],
            frequency=[2, 5, 7],
            grid={"mechanism.m_platform": [1.5, 2.5], "actuator_*.tau_c": [0.01, 0.02, 0.03]},
            list=[{"actuator_1.tau_c": 0.02}, {"actuator_1.tau_c": 0.07}],
            random={"samples": 2, "seed": 1, "mechanism.g": {"uniform": [9.7, 9.9]}},
        )
    )
    assert count_cases(config) == len(expand(config)) == 2 * 2 * 6 * 2 * 3
    with pytest.raises(BatchConfigError, match="144 cases .*2 random samples x 2 list entries x 6 grid points"):
        expand(config, max_cases=143)
    with pytest.raises(SystemExit):
        cli_main(["batch", "--help"])
    assert f"(default: {DEFAULT_MAX_CASES})" in " ".join(capsys.readouterr().out.split())


# -- running batches ------------------------------------------------------------------------------------
def crash_in(case_id: str, task) -> None:
    """Test-only ``before_case`` hook: the worker running ``case_id`` dies of a segmentation fault."""
    if task["id"] == case_id:
        os.kill(os.getpid(), signal.SIGSEGV)


def _hook(case_id: str):
    import functools

    return functools.partial(crash_in, case_id)


def _small(ssp, **extra) -> dict:
    """Six short cases: c00002 has an invalid mass (fails at initialization), the rest are fine."""
    return {
        "name": "small",
        "ssp": str(ssp),
        "run": {"stop_time": 0.12, "record_step": 0.001},
        "cases": {
            "motion": {"axis": "z", "amplitude": 0.002, "frequency": 10},
            "list": [{"mechanism.m_platform": m} for m in (2.0, 2.2, -1.0, 2.4, 2.6, 2.8)],
        },
        "outputs": {"keep": ["mechanism.z"], "metrics": ["tracking", "torque"]},
        **extra,
    }


def test_batch_records_failures_and_a_segfault_and_goes_on(ssp, tmp_path):
    out = tmp_path / "b"
    result = run_batch(_small(ssp), out, workers=2, before_case=_hook("c00003"), progress=False)
    status = {r["id"]: r["status"] for r in result.records}
    assert status == {
        "c00000": "ok",
        "c00001": "ok",
        "c00002": "failed",
        "c00003": "crashed",
        "c00004": "ok",
        "c00005": "ok",
    }
    by_id = {r["id"]: r for r in result.records}
    assert "m_platform" in by_id["c00002"]["error"] and "SIGSEGV" in by_id["c00003"]["error"]
    assert by_id["c00000"]["metrics"]["tracking_z_rms_m"] > 0 and "tau_m_1_peak_Nm" in by_id["c00000"]["metrics"]
    # one file per case, written whole; kept signals beside; no temp files left
    for case_id in status:
        saved = json.loads((out / "cases" / f"{case_id}.json").read_text())
        assert (
            saved["status"] == status[case_id]
            and saved["parameters"]["mechanism.m_platform"] == by_id[case_id]["parameters"]["mechanism.m_platform"]
        )
    signals = np.load(out / "cases" / "c00001.npz")
    assert set(signals.files) == {"time", "mechanism.z"} and len(signals["time"]) == 121
    assert not list(out.rglob("*.tmp"))
    manifest = json.loads((out / "manifest.json").read_text())
    assert (manifest["ok"], manifest["failed"], manifest["crashed"], manifest["pending"]) == (4, 1, 1, 0)
    assert (out / "summary.csv").read_text().splitlines()[0].startswith("id,status,ssp,axis")
    # a case run on reset instances in a worker gives what a fresh simulate gives
    fresh = simulate(
        ssp, SineMotion("z", 0.002, 10), 0.12, parameters={"mechanism": {"m_platform": 2.2}}, record=["mechanism.z"]
    )
    np.testing.assert_allclose(signals["mechanism.z"], fresh["mechanism.z"], rtol=1e-12, atol=1e-15)
    # resume: nothing left; retry_failed: the failed and crashed cases run again, the rest stay
    again = run_batch(_small(ssp), out, workers=2, resume=True, progress=False)
    assert again.ran == [] and len(again.skipped) == 6
    retried = run_batch(_small(ssp), out, workers=2, resume=True, retry_failed=True, progress=False)
    assert sorted(retried.ran) == ["c00002", "c00003"] and retried.crashed == 0 and retried.failed == 1


def test_interrupted_batch_resumes_without_repeating_a_finished_case(ssp, tmp_path):
    out = tmp_path / "i"
    seen = []

    def stop_after_two(state):
        seen.append(state["done"])
        if state["done"] >= 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_batch(_small(ssp), out, workers=2, progress=stop_after_two)
    first = {p.stem: p.read_bytes() for p in (out / "cases").glob("*.json")}
    assert 2 <= len(first) < 6
    assert json.loads((out / "manifest.json").read_text())["pending"] == 6 - len(first)
    with pytest.raises(BatchConfigError, match="already holds a batch"):
        run_batch(_small(ssp), out, progress=False)
    import fcntl

    with open(out / ".lock", "a+") as other_driver:  # a second driver on the same folder stops at once
        fcntl.flock(other_driver, fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(BatchConfigError, match="another mast batch is running"):
            run_batch(_small(ssp), out, resume=True, progress=False)
    changed = _small(ssp, run={"stop_time": 0.13, "record_step": 0.001})
    with pytest.raises(BatchConfigError, match="other settings"):
        run_batch(changed, out, resume=True, progress=False)
    resumed = run_batch(_small(ssp), out, workers=2, resume=True, progress=False)
    assert sorted(resumed.skipped) == sorted(first) and not set(resumed.ran) & set(first)
    assert len(resumed.ran) + len(first) == 6 and resumed.ok == 5 and resumed.failed == 1
    for case_id, data in first.items():  # finished cases untouched
        assert (out / "cases" / f"{case_id}.json").read_bytes() == data
    assert read_batch(out).ok == 5


def test_cli_batch_dry_run_run_and_exit_codes(ssp, tmp_path, capsys):
    config = tmp_path / "sweep.toml"
    config.write_text(
        textwrap.dedent(f"""
        name = "cli"
        ssp = "{ssp}"
        [run]
        stop_time = 0.1
        [cases]
        motion = {{ axis = "psi", amplitude = 0.3 }}
        frequency = [10, 20]
        """)
    )
    assert cli_main(["batch", str(config), "--out", str(tmp_path / "o"), "--dry-run"]) == 0
    assert "2 case(s)" in capsys.readouterr().out
    assert cli_main(["batch", str(config), "--out", str(tmp_path / "o"), "--workers", "1"]) == 0
    text = capsys.readouterr().out
    assert "2 cases: 2 ok, 0 failed, 0 crashed" in text
    first, second = (json.loads((tmp_path / "o" / "cases" / f"c0000{k}.json").read_text()) for k in (0, 1))
    assert first["worker"]["pid"] == second["worker"]["pid"]  # one worker: the second case reset the instances
    assert second["timing"]["setup_s"] < first["timing"]["setup_s"] / 5
    groups = (tmp_path / "o" / "groups.csv").read_text().splitlines()
    assert len(groups) == 2 and "bandwidth_Hz" in groups[0]
    assert (tmp_path / "o" / "plots" / "frequency_response.png").stat().st_size > 5000
    bad = tmp_path / "bad.toml"
    bad.write_text(f'ssp = "{ssp}"\n[cases]\ngrid = {{ "mechanism.nope" = [1] }}\n')
    assert cli_main(["batch", str(bad), "--out", str(tmp_path / "x")]) == 2
    assert "no parameter 'nope'" in capsys.readouterr().err


def test_a_case_over_its_timeout_is_failed(ssp, tmp_path):
    config = {
        "ssp": str(ssp),
        "run": {"stop_time": 3.0, "timeout": 0.2},
        "cases": {"motion": {"axis": "z", "amplitude": 0.002, "frequency": 2}},
    }
    result = run_batch(config, tmp_path / "t", workers=1, progress=False, plots=False)
    assert result.failed == 1 and "timed out after 0.2 s" in result.records[0]["error"]
    assert result.records[0]["timing"]["case_s"] < 2.0


# -- Dask ---------------------------------------------------------------------------------------------------
def test_dask_local_cluster_runs_the_same_batch_and_survives_a_dead_worker(ssp, tmp_path):
    dask = pytest.importorskip("dask")
    distributed = pytest.importorskip("distributed")
    local = run_batch(_small(ssp), tmp_path / "local", workers=2, progress=False)
    # one task per worker thread at a time and no retries: the dead worker's case, and only it, is crashed
    with dask.config.set({"distributed.scheduler.allowed-failures": 0, "distributed.scheduler.worker-saturation": 1.0}):
        with distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster:
            remote = run_batch(
                _small(ssp),
                tmp_path / "dask",
                scheduler=cluster.scheduler_address,
                before_case=_hook("c00004"),
                progress=False,
            )
    status = {r["id"]: r["status"] for r in remote.records}
    assert status == {
        "c00000": "ok",
        "c00001": "ok",
        "c00002": "failed",
        "c00003": "ok",
        "c00004": "crashed",
        "c00005": "ok",
    }
    for a, b in zip(local.records, remote.records):
        if b["status"] == "ok":
            assert a["metrics"] == b["metrics"]  # bit for bit: the same FMUs, reset between cases
    assert len({r["worker"]["pid"] for r in remote.records if r["status"] == "ok"}) >= 1


def test_a_batch_without_motion_holds_the_home_pose(ssp, tmp_path):
    """docs/batch.md: without a motion the system holds its home pose (every case failed before)."""
    config = {
        "name": "hold",
        "ssp": str(ssp),
        "run": {"stop_time": 0.05, "record_step": 0.001},
        "cases": {"list": [{"mechanism.m_platform": m} for m in (2.06, 3.0)]},
        "outputs": {"keep": ["z_cmd", "mechanism.z"]},
    }
    result = run_batch(config, tmp_path / "b", workers=1, progress=False)
    assert [r["status"] for r in result.records] == ["ok", "ok"], [r["error"] for r in result.records]
    signals = np.load(tmp_path / "b" / "cases" / "c00000.npz")
    assert np.ptp(signals["z_cmd"]) == 0.0 and signals["z_cmd"][0] == pytest.approx(signals["mechanism.z"][0], abs=1e-9)
    assert np.ptp(signals["mechanism.z"]) < 1e-4  # held: the loop takes up the load (tens of micrometres)
