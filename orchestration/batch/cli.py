"""``mast batch CONFIG --out DIR [--workers N] [--scheduler ADDRESS] [--resume] [--max-cases N]``.

Exit codes: 0 every case ok, 1 some cases failed or crashed (the batch went on and is complete),
2 the config or the command is wrong (a config over --max-cases cases among them), 130 interrupted (resume with
--resume).
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..core.specimen import MECHANISM, PAYLOAD_NAMES
from . import DEFAULT_MAX_CASES, BatchConfig, BatchConfigError, describe, expand, run_batch


def with_specimen(config: BatchConfig, specimen) -> dict:
    """The config's ``[parameters]`` with the specimen's on the mechanism (``--specimen``), once every SSP variant's
    drives are found to hold it at rest at home; one of them set in ``[parameters]`` too is refused."""
    from ..analyses.specimen import check_held, held_text

    given = {k.partition(".")[2]: v for k, v in config.parameters.items() if k.partition(".")[0] == MECHANISM}
    clash = sorted(set(given) & set(PAYLOAD_NAMES))
    if clash:
        raise BatchConfigError(
            f"--specimen {specimen.label} and [parameters] {', '.join(f'{MECHANISM}.{k}' for k in clash)} of "
            "the config both set the payload: give one"
        )
    for ssp in config.ssp.values():
        print(held_text(check_held(ssp, specimen, {MECHANISM: given})))
    return {**config.parameters, **{f"{MECHANISM}.{k}": v for k, v in specimen.parameters().items()}}


def main(args) -> int:
    max_cases = DEFAULT_MAX_CASES if args.max_cases is None else args.max_cases
    try:
        config = BatchConfig.load(args.config)
        if getattr(args, "specimen", None) is not None:
            config.parameters = with_specimen(config, args.specimen)
        if args.dry_run:
            print(describe(expand(config, max_cases=max_cases)))
            return 0
        if args.retry_failed and not args.resume:
            raise BatchConfigError("--retry-failed goes with --resume")
        result = run_batch(
            config,
            Path(args.out),
            workers=args.workers,
            scheduler=args.scheduler,
            resume=args.resume,
            retry_failed=args.retry_failed,
            plots=not args.no_plots,
            max_cases=max_cases,
        )
    except BatchConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            f"\ninterrupted: the finished cases are saved in {args.out}; go on with "
            f"`mast batch {args.config} --out {args.out} --resume`",
            file=sys.stderr,
        )
        return 130
    total = len(result.records)
    ran = len(result.ran)
    rate = f", {60 * ran / result.wall_s:.1f} cases/min" if ran and result.wall_s > 0 else ""
    print(
        f"{total} cases: {result.ok} ok, {result.failed} failed, {result.crashed} crashed "
        f"({ran} run now in {result.wall_s:.0f} s{rate}, {len(result.skipped)} finished before)"
    )
    for g in result.groups[:10]:
        bw = g.get("bandwidth_Hz")
        if bw is not None:
            print(
                f"  sweep {g['group'][:8]} ({g['axis']}, {g['ok']}/{g['cases']} ok): bandwidth "
                + (f"{bw:.3g} Hz" if bw == bw else "not reached in the swept range")
            )
    if len(result.groups) > 10:
        print(f"  ... {len(result.groups) - 10} more sweeps in {Path(args.out) / 'groups.csv'}")
    print(
        f"wrote {Path(args.out) / 'manifest.json'}, summary.csv"
        + (", groups.csv" if result.groups else "")
        + ("" if args.no_plots else ", plots/")
    )
    return 0 if result.ok == total else 1
