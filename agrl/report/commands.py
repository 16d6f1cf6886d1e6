"""The command line's parser and its commands but ``pages`` (:func:`agrl.report.cli.main` runs that one, and
:func:`agrl.report.pages.run_block` runs a page's blocks with these)."""

from __future__ import annotations

import argparse
import fnmatch
import sys
from pathlib import Path

import agrl.report  # the package: its docstring is the command line's description
from agrl.cli import writable_folder
from agrl.config import ConfigError
from agrl.report.bench import bench_table
from agrl.report.columns import EVALUATION_COLUMNS, RUN_COLUMNS, ReportError
from agrl.report.data import assemble_runs, data_folder_above, finished, load_data
from agrl.report.extract import extract, write_data
from agrl.report.paper import moving_tables, table3
from agrl.report.tables import (
    DERIVED_KEYS,
    evaluation_summary_table,
    evaluations_table,
    runs_table,
    summary_table,
)

#: The results pages ``pages`` reruns when given none.
DEFAULT_PAGES = ("docs/results", "docs/benchmarks.md")


def _matches(evaluation: dict, patterns: list[str]) -> bool:
    """Whether an evaluation's folder or run matches one of ``patterns`` (all do when there are none)."""
    return not patterns or any(fnmatch.fnmatchcase(evaluation["evaluation"], pattern) or
                               fnmatch.fnmatchcase(evaluation["run"] or "", pattern) for pattern in patterns)


TABLES = ("table3", "moving", "runs", "summary", "evaluations")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m agrl.report", description=agrl.report.__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="kind", required=True, metavar="{extract,"
                                     + ",".join(TABLES) + ",bench,pages}")
    extract_parser = commands.add_parser("extract", help="run folders -> data folder (runs/evaluations/curves.csv)")
    extract_parser.add_argument("root", type=Path, help="a folder containing runs (any depth)")
    extract_parser.add_argument("data", type=Path, help="the data folder to write")
    for kind in TABLES:
        table = commands.add_parser(kind)
        table.add_argument("root", type=Path, help="a data folder (runs.csv ...) or a folder containing runs")
        table.add_argument("--runs", nargs="+", default=[], metavar="PATTERN",
                           help="only the runs whose path matches one of these shell patterns")
        if kind in ("table3", "summary", "runs"):
            table.add_argument("--independent", nargs="+", default=[], metavar="FOLDER_OR_SEED",
                               help="independent evaluations of each run, by folder name (eval_777) or "
                                    "evaluation seed (777): one column each of success and instructions")
        if kind == "moving":
            table.add_argument("--figures", type=Path, help="folder for success-against-time figures")
            table.add_argument("--figure-suffix", default="", help="appended to figure names, e.g. _8min")
        if kind == "runs":
            table.add_argument("--times", type=float, nargs="+", default=[60, 120, 180],
                               help="training seconds at which to give each run's best evaluation so far")
        if kind == "summary":
            table.add_argument("--by", nargs="+", required=True, metavar="KEY",
                               help=f"runs.csv columns or {', '.join(DERIVED_KEYS)}: one row per value; "
                                    "with a column of evaluations.csv only (evaluation, checkpoint, ...), or "
                                    "where there are no runs: one row per group of evaluations")
        if kind == "evaluations":
            table.add_argument("--final", action="store_true", help="the runs' final evaluations too")
    bench = commands.add_parser("bench", help="one line per JSON line of make bench's output")
    bench.add_argument("files", type=Path, nargs="+", help="JSON lines files")
    pages = commands.add_parser("pages", help="rerun the report blocks of results pages")
    pages.add_argument("targets", nargs="*", default=list(DEFAULT_PAGES),
                       help="markdown files or folders of them (default: " + " ".join(DEFAULT_PAGES) + ")")
    pages.add_argument("--check", action="store_true", help="write nothing; exit 1 naming each out-of-date block")
    return parser


def run_command(args: argparse.Namespace, parser: argparse.ArgumentParser, draw: bool) -> int:
    """Run a command of :func:`_parser` other than ``pages``: print its output, return the exit code; ``draw=False``
    links figures without drawing them (``pages --check``)."""
    try:
        if args.kind == "bench":
            missing = next((path for path in args.files if not path.is_file()), None)
            if missing is not None:
                parser.error(f"{missing}: no such file; allowed: JSON lines files of make bench")
            print(bench_table(args.files))
            return 0
        if args.kind == "extract":
            if not args.root.is_dir():
                parser.error(f"{args.root}: no such folder; allowed: a folder containing runs")
            writable_folder(args.data / "runs.csv")
            data = extract(args.root)
            if not data["runs.csv"] and not data["evaluations.csv"] and not data["files"]:
                raise ReportError(f"{args.root}: no runs, evaluations or result files below it")
            write_data(args.root, data, args.data)
            print(f"{args.data}: {len(data['runs.csv'])} runs, {len(data['evaluations.csv'])} evaluations, "
                  f"{len(data['curves.csv'])} curve points, {len(data['files'])} files copied")
            return 0
        if not args.root.is_dir() and data_folder_above(args.root) is None:
            parser.error(f"{args.root}: no such folder; allowed: a data folder, a path below one, or a folder "
                         "containing runs")
        if args.kind == "runs" and any(seconds <= 0 for seconds in args.times):
            parser.error(f"--times {' '.join(f'{seconds:g}' for seconds in args.times)} is not allowed: seconds > 0")
        if args.kind == "moving" and args.figures is not None and draw:
            try:
                writable_folder(args.figures / "figure.png")  # before the tables, not after them
            except ConfigError as error:
                raise ReportError(f"--figures: {error}") from None
        if args.kind == "summary":
            allowed = [*RUN_COLUMNS, *DERIVED_KEYS, *(key for key in EVALUATION_COLUMNS if key not in RUN_COLUMNS)]
            unknown = next((key for key in args.by if key not in allowed), None)
            if unknown is not None:
                parser.error(f"--by {unknown} is not allowed: one of {', '.join(allowed)}")
        data = load_data(args.root)
        if args.kind == "summary" and (any(key not in RUN_COLUMNS and key not in DERIVED_KEYS for key in args.by)
                                       or not finished(assemble_runs(data, tuple(args.runs)))):
            unknown = next((key for key in args.by if key not in EVALUATION_COLUMNS and key != "folder"), None)
            if unknown is not None:
                raise ReportError(f"--by {unknown}: not a column of evaluations.csv, which this summary groups "
                                  f"(allowed: {', '.join(EVALUATION_COLUMNS)}, folder)")
            rows = [row for row in data["evaluations.csv"] if _matches(row, args.runs)]
            if not rows:
                raise ReportError(f"no runs or evaluations in {args.root}")
            print(evaluation_summary_table(rows, args.by))
            return 0
        if args.kind == "evaluations":
            rows = [row for row in data["evaluations.csv"] if _matches(row, args.runs)]
            if not any(args.final or not row["final"] for row in rows):
                raise ReportError(f"no evaluations below {args.root}" + (
                    f" matching --runs {' '.join(args.runs)}" if args.runs else ""))
            print(evaluations_table(rows, args.final))
            return 0
        runs = finished(assemble_runs(data, tuple(args.runs)))
        if not runs:
            raise ReportError(f"no finished runs (with a final evaluation) in {args.root}" + (
                f" matching --runs {' '.join(args.runs)}" if args.runs else ""))
    except (ConfigError, ReportError) as error:
        print(f"agrl.report: error: {error}", file=sys.stderr)
        return 2
    if args.kind == "table3":
        others = sum(run["task"] != "fixed" for run in runs)
        if others == len(runs):
            print(f"agrl.report: error: no finished fixed-destination runs in {args.root} (Table 3 is the fixed "
                  "destination)", file=sys.stderr)
            return 2
        if others:
            print(f"agrl.report: {others} run{'s' if others > 1 else ''} of other tasks left out: Table 3 is the "
                  "fixed destination", file=sys.stderr)
        print(table3(runs, tuple(args.independent)))
    elif args.kind == "moving":
        print(moving_tables(runs, args.figures, args.figure_suffix, draw=draw))
    elif args.kind == "summary":
        print(summary_table(runs, args.by, tuple(args.independent)))
    else:
        print(runs_table(runs, args.times, tuple(args.independent)))
    return 0
