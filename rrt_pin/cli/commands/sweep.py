"""``rrt-pin sweep``: many variants of a run (a spec file), locally or on a Dask cluster."""

from __future__ import annotations

import argparse
import os
import sys

from rrt_pin.cli.commands._common import (
    add_config_argument,
    nonempty,
    positive_float,
    positive_int,
    refuse_run_file_params,
    termination_as_interrupt,
)
from rrt_pin.core._logging import note
from rrt_pin.simulate.metrics import METRICS

HELP = "run a sweep spec (TOML): many variants, metrics to Parquet, locally or on Dask (SI units)"

_EPILOG = """\
The spec (TOML) names the base run, what varies (grids, ranges, random samples
over the chapter's symbols, gains, q0, qd0, qf) and what to keep (metrics, a
few dense trajectories); see rrt_pin/sweeps/spec.py or the README.
OUT/chunks/chunk-NNNNNN.parquet holds, per variant: its index, the varied
values and the metrics (units in the Parquet metadata, "rrt_pin.units"):
{metrics}
Read it with pandas: pandas.read_parquet("OUT/chunks") (chunks/ holds chunks only:
--resume refuses any other file there). One run at a time writes into OUT (it holds
OUT/sweep.lock); a new sweep needs a new or empty folder.
Without --scheduler Dask's local cluster runs the chunks with a thread per core
(the compiled batch releases the GIL; --workers 1 runs them in this process without
Dask). --resume finishes an
interrupted sweep (the spec must be unchanged): it checks every chunk listed as
done (readable, the spec's hash, its variants) and recomputes those that fail."""


def _metric_lines() -> str:
    """The metrics' columns and units, from the registry (:data:`rrt_pin.simulate.metrics.METRICS`)."""
    kinds = {"coordinate": "<q>", "effort": "<effort>", "run": ""}
    units = {"coordinate": "rad or m", "effort": "N·m or N"}
    lines = []
    for metric in METRICS.values():
        parts = []
        for c in metric.columns:
            name = f"{c.prefix}_{kinds[c.per]}" if kinds[c.per] else c.prefix
            unit = c.unit if c.unit is not None else units[c.per]
            parts.append(f"{name} [{unit}]" if unit else name)
        tasks = "" if len(metric.tasks) > 1 else f" ({metric.tasks[0]} only)"
        lines.append(f"  {metric.name}{tasks}: " + ", ".join(parts))
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``rrt-pin sweep``."""
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _EPILOG.format(metrics=_metric_lines())
    parser.add_argument(
        "spec", metavar="SPEC.toml", nargs="?", type=nonempty,
        help="the sweep spec (or spec = \"...\" in the run file's [sweep] table)",
    )  # fmt: skip
    parser.add_argument(
        "--out",
        type=nonempty,
        metavar="DIR",
        help="output folder: new or empty (created), or a sweep to --resume; one run at a time",
    )
    parser.add_argument(
        "--scheduler", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://10.0.0.5:8786"
    )
    parser.add_argument(
        "--workers", type=positive_int, metavar="N", help="local worker processes (default: CPUs)"
    )
    parser.add_argument("--resume", action="store_true", help="finish a sweep started in --out")
    parser.add_argument(
        "--plot",
        metavar="METRIC",
        help="after the sweep, draw METRIC (a column, e.g. final_error_q3) over the varied "
        "values: a line over one, a heat map over two (mean over the others); "
        "written to OUT/METRIC.png",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    parser.add_argument(
        "--worker-timeout",
        type=positive_float,
        default=60.0,
        metavar="SECONDS",
        help="stop when the Dask cluster has had no worker for this long (the chunks done "
        "are kept: --resume continues) [s] (default 60)",
    )
    add_config_argument(parser, "sweep")


def run(args: argparse.Namespace) -> int:
    """Run the sweep, print its summary, draw the plot.

    SIGTERM and SIGHUP end it as Ctrl-C does: the chunks stored stay, and one line
    says so and how to continue.
    """
    from rrt_pin.core.errors import InputError

    refuse_run_file_params(args, "sweep", "the spec's [base] sets the values")
    if args.spec is None:
        raise InputError('sweep needs a spec: SPEC.toml (or spec = "..." in a run file\'s [sweep])')
    if args.out is None:
        raise InputError('sweep needs --out DIR (or out = "..." in a run file\'s [sweep])')
    if args.plot:  # before any work: a sweep must not run for a plot it cannot draw
        from rrt_pin.sweeps.plot import check_metric

        check_metric(args.spec, args.plot)
    from rrt_pin.sweeps.run import sweep

    try:
        with termination_as_interrupt():
            result = sweep(
                args.spec,
                args.out,
                scheduler=args.scheduler,
                workers=args.workers,
                resume=args.resume,
                progress=not args.no_progress,
                worker_timeout=args.worker_timeout,
            )
    except KeyboardInterrupt:
        from pathlib import Path

        from rrt_pin.sweeps.store import MANIFEST

        hint = ""
        if os.path.isfile(Path(args.out) / MANIFEST):
            hint = f"; the chunks done are kept in {args.out!r}: add --resume to continue"
        print(f"rrt-pin: interrupted{hint}", file=sys.stderr)
        return 130
    sys.stdout.write(result.summary())
    if args.plot:
        from rrt_pin.sweeps.plot import plot_metric

        path = plot_metric(result.out, args.plot)
        note(f"wrote {path}")
    return 0
