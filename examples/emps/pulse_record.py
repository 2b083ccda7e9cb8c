"""A synthetic held-out EMPS record with excitation pulses added to the drive command (docs/emps.md).

The benchmark's own pulse record is kept out of the project; this one has its form, to try the
path (`mast import` with examples/emps/map_pulses.toml, `mast replay`) and to score a model
diagnosed on DATA_EMPS.mat on data it never saw:

    .venv/bin/python examples/emps/pulse_record.py ../shared/data/emps/DATA_EMPS.mat data/emps_pulses.mat

- reference: DATA_EMPS.mat's own qg (and its gains gtau, kp, kv);
- pulses: 5 V added after the saturation, 20 ms long every 0.5 s from 0.25 s on (assumed: the form
  the benchmark describes, pulses of the amplitude its record holds; their timing is ours);
- plant (the truth): the benchmark's published asymmetric inverse-model estimates (../shared/data/
  emps/README.md: M 95.15 kg, F_v+ 166.7, F_v- 240.4 N s/m, F_c+ 20.14, F_c- 20.63 N), independent of
  any diagnosis here, in the bench build/ssp/EMPS_bench.ssp (controller at 1 kHz, axis at 0.1 ms);
- the log: qm at the samples, vir(k) = the drive command applied at sample k (the controller's output
  after the saturation plus the pulse: at every edge vir steps by 5 V at the edge's sample), the
  pulses as `pulse_N` in volts (named like the benchmark's, with an _N that is not its unit).
  Noise-free: a model's error on it is its difference from the truth, nothing else.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import scipy.io

from mast.analyses.replay import simulate_record
from mast.core.build import default_build_dir
from mast.data.record import SignalSpec, load_records, write_records

BENCH = default_build_dir() / "ssp" / "EMPS_bench.ssp"
#: the truth: the benchmark's asymmetric estimates as the load axis's parameters (mean and half-difference)
TRUTH = {
    "M": 95.15,
    "F_v": (166.7 + 240.4) / 2,
    "dF_v": (166.7 - 240.4) / 2,
    "F_c": (20.14 + 20.63) / 2,
    "dF_c": (20.14 - 20.63) / 2,
    "F_offset": 0.0,
}
#: pulses [V], their length and period [s], the first one's start [s] (assumed, module docstring)
PULSE_V, PULSE_S, PERIOD_S, FIRST_S = 5.0, 0.02, 0.5, 0.25


def pulse_train(t: np.ndarray) -> np.ndarray:
    """The injected input [V] at the samples ``t``."""
    phase = (t - FIRST_S) % PERIOD_S
    return np.where((t >= FIRST_S) & (phase < PULSE_S - 1e-9), PULSE_V, 0.0)


def make(source: Path, out: Path, bench: Path = BENCH) -> dict:
    """Simulate the truth on ``source``'s reference with the pulses and write the .mat ``out``."""
    d = scipy.io.loadmat(str(source))
    t, qg = d["t"].ravel(), d["qg"].ravel()
    pulse = pulse_train(t - t[0])
    specs = {
        "q_ref": SignalSpec("q_ref", "command", "m", input="q_ref"),
        "u_inj": SignalSpec("u_inj", "injected", "V", input="u_inj"),
        "q_m": SignalSpec("q_m", "position", "m", model="axis.q"),
        "u": SignalSpec("u", "effort", "V", model="controller.u", sampled=True),
    }
    start = float(d["qm"].ravel()[0])
    with tempfile.TemporaryDirectory(prefix="mast_pulses_") as tmp:
        write_records(
            Path(tmp),
            specs,
            [
                {
                    "name": "pulses",
                    "time": t - t[0],
                    "values": {"q_ref": qg, "u_inj": pulse, "q_m": np.full(len(t), start), "u": np.zeros(len(t))},
                }
            ],
        )
        sim = simulate_record(bench, load_records(tmp).tests[0], {"axis": TRUTH})
    out.parent.mkdir(parents=True, exist_ok=True)
    scipy.io.savemat(
        str(out),
        {
            "t": t[:, None],
            "qg": qg[:, None],
            "qm": sim["q_m"][:, None],
            "vir": sim["u"][:, None],
            "pulse_N": pulse[:, None],
            "gtau": d["gtau"],
            "kp": d["kp"],
            "kv": d["kv"],
        },
    )
    return {
        "samples": len(t),
        "edges": int(np.count_nonzero(np.diff(pulse))),
        "vir_max_V": float(np.abs(sim["u"]).max()),
    }


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: pulse_record.py DATA_EMPS.mat OUT.mat")
    info = make(Path(sys.argv[1]), Path(sys.argv[2]))
    print(
        f"wrote {sys.argv[2]}: {info['samples']} samples, {info['edges']} pulse edges, |vir| up to "
        f"{info['vir_max_V']:.3g} V"
    )
