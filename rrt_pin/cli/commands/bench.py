"""``rrt-pin bench``: work-precision and inverse-dynamics benchmarks, energy drift."""

from __future__ import annotations

import argparse

from rrt_pin.cli.commands._common import add_config_argument, refuse_run_file_params

HELP = (
    "benchmark run time against error (direct dynamics), inverse-dynamics backends, energy "
    "drift, kernels against the machine's FMA limit"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``rrt-pin bench``."""
    parser.add_argument(
        "--quick", action="store_true", help="fewer settings, one repeat: finishes within a minute"
    )
    parser.add_argument(
        "--out",
        default="bench-out",
        metavar="DIR",
        help="folder for work_precision.csv/.png, inverse.csv, energy_drift.csv, kernels.csv "
        "(default bench-out/)",
    )
    add_config_argument(parser, "bench")


def run(args: argparse.Namespace) -> int:
    """Run the benchmarks; progress on stderr, summary on stdout."""
    from rrt_pin.core.extras import require

    refuse_run_file_params(args, "bench", "the benchmarks run the chapter's values")
    # Checked before anything runs or is written (not halfway through).
    require("sympy", "symbolic", "the benchmark's 30-digit reference")
    require("mpmath", "symbolic", "the benchmark's 30-digit reference")
    require("matplotlib", "plot", "the work-precision plot")
    from rrt_pin.cli.bench_report import Progress, run_bench, summary

    report = run_bench(args.out, quick=args.quick, progress=Progress(0))
    print(summary(report))
    return 0
