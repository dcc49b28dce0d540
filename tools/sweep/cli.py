"""`hbench sweep` / `python -m sweep`: run a study file, resumable, locally or on Dask."""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections import Counter
from pathlib import Path

from . import report, runner, scenario
from .evaluate import METRICS
from .study import StudyError, load

EPILOG = """\
metrics (SI in the CSV files; the plots show um, bar, J):
""" + "\n".join(f"  {name:<14} {text}" for name, text in METRICS.items()) + """

DIR receives: study.json (the points), results.jsonl (one record per finished point,
appended as points finish), results.csv (one row per point), sensitivity.csv,
metric_<name>.png and sensitivity.png, runs.jsonl (throughput of each session), and
scenario/ (the scenario's input table). Running the same command again resumes: points
already recorded are not recomputed. Ready-made studies: studies/*.toml; the study file
format is described in docs/sweeps.md.

examples:
  hbench sweep --study studies/payload_robustness.toml --out out/payload
  hbench sweep --study studies/monte_carlo.toml --out out/mc --scheduler tcp://HOST:8786
"""


def default_workers() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hbench sweep",
        description="Run a parameter study of a HydroBench FMU (grid, random or Latin-hypercube "
                    "points; robustness and sensitivity metrics) on all cores of this machine, or on "
                    "a Dask cluster; interrupted studies resume without recomputing finished points.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--study", required=True, type=Path, help="study file (TOML)")
    p.add_argument("--out", required=True, type=Path, help="directory for the results (created; reused to resume)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="Dask scheduler to run on, e.g. tcp://HOST:8786 (workers need the venv's "
                            "packages: fmpy, numpy, dask[distributed]; not this repository)")
    where.add_argument("--serial", action="store_true",
                       help="run every point in this process, without Dask (debugging, reference numbers)")
    p.add_argument("--workers", type=int, default=default_workers(),
                   help="worker processes of the local cluster (default: all cores, %(default)s here)")
    p.add_argument("--fmu", type=Path, help="FMU file to use instead of the study's")
    p.add_argument("--restart", action="store_true", help="discard the results already in DIR and start over")
    p.add_argument("--retry-failed", action="store_true", help="run failed and timed-out points again")
    p.add_argument("--check", action="store_true",
                   help="check the study against the FMU and scenario, print the points, run nothing")
    p.add_argument("--no-plots", action="store_true", help="write the CSV files only")
    p.add_argument("--quiet", action="store_true", help="no progress bar or messages")
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    if args.workers < 1:
        print("hbench sweep: --workers must be at least 1", file=sys.stderr)
        return 2
    try:
        return _run(args)
    except (StudyError, scenario.ScenarioError) as e:
        print(f"hbench sweep: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


def _run(args: argparse.Namespace) -> int:
    from fmpy import read_model_description

    study = load(args.study, args.fmu)
    args.out.mkdir(parents=True, exist_ok=True)
    scen = scenario.load(study.scenario, args.out)
    try:
        md = read_model_description(str(study.fmu), validate=False)
    except Exception as e:
        raise StudyError(f"{study.fmu}: not a readable FMU: {e}") from None
    plan = runner.plan(study, scen, md, runner.sha256_file(study.fmu))
    factors = report.factor_columns(plan.points, plan.factor_names)
    if args.check:
        print(f"{study.name}: {len(plan.jobs)} points, scenario {scen.name} "
              f"({plan.shared['stop_time']} s at {plan.shared['step']} s), FMU {study.fmu}")
        for p in plan.points:
            print(p["id"], json.dumps({"case": p["case"], **p["values"]}, default=repr))
        return 0
    if not args.quiet and "energy" in study.metrics and "Q_supply" not in {v.name for v in md.modelVariables}:
        print(f"sweep: note: {study.fmu.name} has no output Q_supply yet: the energy metric is "
              "skipped (left empty)", file=sys.stderr)
    store = runner.Store(args.out)
    store.open(study, plan, args.restart)
    records_by_id, summary = runner.execute(
        study, plan, store, serial=args.serial, scheduler=args.scheduler, workers=args.workers,
        retry_failed=args.retry_failed, quiet=args.quiet)
    records = list(runner.iter_records(plan, records_by_id))
    metrics = list(study.metrics)
    report.write_csv(args.out / "results.csv", records, factors, metrics)
    rows = report.sensitivity(records, factors, metrics)
    report.write_sensitivity(args.out / "sensitivity.csv", rows)
    if not args.no_plots:
        grid = {f.name for f in study.factors if f.values is not None} | {"case"}
        report.plot(args.out, study.name, records, factors, metrics, grid, rows)
    if not args.quiet:
        status = Counter(r["status"] for r in records)
        print(f"sweep: {study.name}: " + ", ".join(f"{n} {s}" for s, n in sorted(status.items()))
              + f"; results in {args.out}/results.csv", file=sys.stderr)
        if summary is not None and summary.points:
            overhead = summary.overhead_per_point
            print(f"sweep: {summary.points} points in {summary.elapsed:.1f} s ({summary.startup:.1f} s "
                  f"start-up) on {summary.workers} worker(s) ({summary.mode}): "
                  f"{summary.points_per_second:.2f} points/s, "
                  f"{summary.mean_point_time:.3f} s per point simulating"
                  + (f", {overhead:.3f} s overhead per point" if math.isfinite(overhead) else ""),
                  file=sys.stderr)
    return 0
