"""``python -m agrl.report``: the results pages' tables and figures, from small data files extracted from runs.

    python -m agrl.report extract runs/moving docs/results/data/moving    # run folders -> runs/evaluations/curves.csv
    python -m agrl.report table3 docs/results/data/table3_2026-12-03 --independent 777 4242  # tables to standard output
    python -m agrl.report moving docs/results/data/moving --figures docs/results/figures
    python -m agrl.report runs docs/results/data/moving --times 60 120 180 240       # one line per run
    python -m agrl.report summary docs/results/data/switch_finetune --by variant    # mean ± sd over seeds per group
    python -m agrl.report evaluations docs/results/data/zero_shot_2026-12-03     # one line per independent evaluation
    python -m agrl.report bench docs/results/data/bench_2026-12-06/bench.jsonl   # one line per `make bench` JSON line
    python -m agrl.report pages                    # rerun every report block of docs/results/*.md, docs/benchmarks.md
    python -m agrl.report pages --check            # exit 1 naming each block whose text is out of date

**Extraction.** A run is a folder below the runs folder (any depth) with a training config (``.hydra/config.yaml``,
or ``hydra/`` in the oldest runs) and/or a final evaluation (``eval/eval.json``, or ``eval.json`` beside the config
in the oldest runs). An evaluation is a folder with an ``eval.json`` of ``python -m agrl.evaluate`` (episodes no
training used): it belongs to the run it lies in, or else to the run its checkpoint was saved in, if that run is
below the same folder. ``extract`` writes ``runs.csv`` (a row per run), ``evaluations.csv`` (a row per evaluation,
the final ones included) and ``curves.csv`` (a row per periodic evaluation, from the run's TensorBoard scalars, the
one metrics sink of :mod:`agrl.rl.metrics`, or its ``metrics.csv`` when it has no TensorBoard log), and copies the
folder's own small result files (JSON lines, logs, scripts; :data:`COPIED_SUFFIXES`) as they are. Their columns
and units: ``docs/results/data/README.md``.

**Tables.** Every table command reads such a data folder, a path below one (its runs and evaluations below that
path, as if it were their folder), or a folder of runs, which it extracts in memory first (so fresh runs of
``make experiments-*`` can be tabled before they are extracted). ``--runs PATTERN`` keeps the runs whose path
matches one of the shell patterns (``'defaults_sweep/*'``). ``--independent 777`` (an evaluation seed, or a folder
name such as ``eval_777``) adds a column of each run's independent evaluation. ``summary --by`` groups runs by
``runs.csv`` columns or ``variant`` / ``series`` / ``folder`` (:data:`DERIVED_KEYS`); grouped by a column only
``evaluations.csv`` has (``evaluation``, ``checkpoint``), or in a folder without runs, it groups evaluations.

**Pages.** A results page holds blocks

    <!-- report: moving docs/results/data/moving --figures docs/results/figures -->
    (the command's output)
    <!-- /report -->

whose first line is the argument list of ``python -m agrl.report`` (paths relative to the repository root, the
folder ``pages`` is run from). ``pages`` reruns each block and replaces its body with the output (and writes the
figures where the command says); ``pages --check`` writes nothing and exits 1 naming each block whose text differs,
or whose linked figures are missing.
"""

# The modules, each importing only those above it: columns (the data files' columns, CSV, ReportError) ->
# extract (run folders -> rows) -> data (data folders -> runs) -> measures -> paper, tables, bench (the tables)
# -> commands (the parser, every command but pages) -> pages (the report blocks) -> cli (main).
from agrl.report.bench import BENCH_COMPARISONS, BENCH_SETTING_FIELDS, bench_table
from agrl.report.cli import main
from agrl.report.columns import (
    CURVE_COLUMNS,
    DATA_FILES,
    EVALUATION_COLUMNS,
    RUN_COLUMNS,
    SUCCESS_KEY,
    TRAINING_SUCCESS_KEY,
    TRAINING_THRESHOLD,
    ReportError,
    read_csv,
    write_csv,
)
from agrl.report.commands import DEFAULT_PAGES, TABLES
from agrl.report.data import assemble_runs, data_folder_above, finished, load_data
from agrl.report.extract import (
    COPIED_SUFFIXES,
    MAX_COPIED_BYTES,
    extract,
    read_metrics,
    read_metrics_csv,
    reward_label,
    write_data,
)
from agrl.report.measures import independent_evaluations, median_minutes_to, run_time_to_reach, time_to_reach
from agrl.report.pages import BLOCK_END, BLOCK_START, IMAGE_LINK, page_files, run_block, update_pages
from agrl.report.paper import (
    METHOD_LABELS,
    METHODS,
    PAPER_TABLE3,
    PAPER_TABLE4,
    PAPER_TABLE5,
    moving_tables,
    table3,
    targets_table,
)
from agrl.report.tables import (
    DERIVED_KEYS,
    derived_value,
    evaluation_summary_table,
    evaluations_table,
    runs_table,
    summary_table,
)

__all__ = [
    "BENCH_COMPARISONS", "BENCH_SETTING_FIELDS", "BLOCK_END", "BLOCK_START", "COPIED_SUFFIXES", "CURVE_COLUMNS",
    "DATA_FILES", "DEFAULT_PAGES", "DERIVED_KEYS", "EVALUATION_COLUMNS", "IMAGE_LINK", "MAX_COPIED_BYTES",
    "METHODS", "METHOD_LABELS", "PAPER_TABLE3", "PAPER_TABLE4", "PAPER_TABLE5", "RUN_COLUMNS", "SUCCESS_KEY",
    "TABLES", "TRAINING_SUCCESS_KEY", "TRAINING_THRESHOLD", "ReportError", "assemble_runs", "bench_table",
    "data_folder_above", "derived_value", "evaluation_summary_table", "evaluations_table", "extract", "finished",
    "independent_evaluations", "load_data", "main", "median_minutes_to", "moving_tables", "page_files",
    "read_csv", "read_metrics", "read_metrics_csv", "reward_label", "run_block", "run_time_to_reach", "runs_table",
    "summary_table", "table3", "targets_table", "time_to_reach", "update_pages", "write_csv", "write_data",
]
