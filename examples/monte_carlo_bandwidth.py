"""Monte Carlo tolerance study: the z bandwidth of the MAST with platform mass, Coulomb friction and J1
drawn within their tolerances (examples/monte_carlo_bandwidth.toml), against the nominal machine.

    python examples/monte_carlo_bandwidth.py [--out results/monte_carlo] [--samples 30] [--workers 2]
                                             [--scheduler tcp://host:8786] [--resume]

Writes the batch folder (manifest.json, summary.csv, groups.csv, plots/) and sensitivity.json:
the nominal bandwidth, the spread of the sampled ones, and a linear sensitivity of the bandwidth to
each parameter (Hz per unit, and Hz per tolerance span, so the parameters compare).
Needs `mast build` first (build/ssp/MAST.ssp).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from mast.batch import BatchConfig, run_batch

HERE = Path(__file__).resolve().parent


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default=str(HERE / "monte_carlo_bandwidth.toml"))
    parser.add_argument("--out", default="results/monte_carlo")
    parser.add_argument("--samples", type=int, help="random machines (default: the config's)")
    parser.add_argument("--workers", type=int)
    parser.add_argument("--scheduler", help="Dask scheduler address instead of local processes")
    parser.add_argument("--resume", action="store_true")
    args = parser.parse_args(argv)

    config = BatchConfig.load(args.config)
    raw = dict(config.raw)
    if args.samples:
        raw["cases"] = {**raw["cases"], "random": {**raw["cases"]["random"], "samples": args.samples}}
    base = Path(args.config).resolve().parent
    out = Path(args.out)

    # the nominal machine: the same sweep without the random draws
    nominal_cfg = {**raw, "name": "nominal", "cases": {k: v for k, v in raw["cases"].items() if k != "random"}}
    nominal = run_batch(
        BatchConfig.from_dict(nominal_cfg, base),
        out / "nominal",
        workers=args.workers,
        scheduler=args.scheduler,
        resume=args.resume or (out / "nominal" / "batch.json").exists(),
    )
    study = run_batch(
        BatchConfig.from_dict(raw, base),
        out / "samples",
        workers=args.workers,
        scheduler=args.scheduler,
        resume=args.resume,
    )

    bw0 = nominal.groups[0].get("bandwidth_Hz") if nominal.groups else None
    keys = [k for k in raw["cases"]["random"] if k not in ("samples", "seed")]
    rows = [g for g in study.groups if isinstance(g.get("bandwidth_Hz"), float) and math.isfinite(g["bandwidth_Hz"])]
    bw = np.array([g["bandwidth_Hz"] for g in rows])
    X = np.array([[float(g[k]) for k in keys] for g in rows]) if rows else np.zeros((0, len(keys)))
    report = {
        "nominal_bandwidth_Hz": bw0,
        "machines": len(study.groups),
        "with_bandwidth": len(rows),
        "failed_cases": study.failed + study.crashed,
    }
    if len(rows) >= 2:
        report.update(
            mean_Hz=float(bw.mean()),
            std_Hz=float(bw.std(ddof=1)),
            min_Hz=float(bw.min()),
            max_Hz=float(bw.max()),
            p05_Hz=float(np.percentile(bw, 5)),
            p95_Hz=float(np.percentile(bw, 95)),
        )
    if len(rows) > len(keys) + 1:
        # least squares bw ~ b0 + sum b_k x_k; "per span" = b_k times the sampled range of x_k
        A = np.column_stack([np.ones(len(rows)), X])
        coef, *_ = np.linalg.lstsq(A, bw, rcond=None)
        fit = A @ coef
        report["r2"] = float(1 - np.sum((bw - fit) ** 2) / np.sum((bw - bw.mean()) ** 2)) if np.ptp(bw) > 0 else None
        report["sensitivity"] = {
            k: {"Hz_per_unit": float(c), "Hz_over_sampled_span": float(c * np.ptp(X[:, j]))}
            for j, (k, c) in enumerate(zip(keys, coef[1:]))
        }
    (out / "sensitivity.json").write_text(json.dumps(report, indent=2))

    print(f"\nnominal z bandwidth: {bw0:.3f} Hz" if bw0 else "\nnominal z bandwidth: not reached in the sweep")
    if "mean_Hz" in report:
        print(
            f"{len(rows)} sampled machines: {report['mean_Hz']:.3f} ± {report['std_Hz']:.3f} Hz "
            f"(5-95 %: {report['p05_Hz']:.3f} .. {report['p95_Hz']:.3f} Hz, range {report['min_Hz']:.3f} .. "
            f"{report['max_Hz']:.3f} Hz)"
        )
    for k, s in report.get("sensitivity", {}).items():
        print(f"  {k:24s} {s['Hz_over_sampled_span']:+.3f} Hz over its sampled range")
    print(f"figures: {out / 'samples' / 'plots'}; numbers: {out / 'sensitivity.json'}")
    return 0 if study.failed + study.crashed == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
