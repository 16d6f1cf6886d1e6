"""The data files (``runs.csv``, ``evaluations.csv``, ``curves.csv``): their columns and types, the CSV form
:func:`write_csv` writes and :func:`read_csv` reads back, and :class:`ReportError`, the report's one-line error."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

#: Each data file's columns and their types: ``str``, ``int`` or the number of decimals a float is rounded to
#: (seconds keep 6: TensorBoard's float32 values, rounded any coarser, can land on a table's rounding boundary).
RUN_COLUMNS: dict[str, Any] = {
    "run": str, "task": str, "speed": 1, "radius": 1, "method": str, "reward": str, "switch_cost": 3, "seed": int,
    "actions": str, "overrides": str, "commit": str, "training_seconds": 1, "iterations": int, "decisions_trained": int,
    "episodes": int, "success": 5, "success_low": 5, "success_high": 5, "instructions": 4, "decisions": 4,
    "ms_per_instruction": 4, "evaluation_seed": int, "iterations_logged": int, "iteration_seconds_first": 6,
    "iteration_seconds_median": 6, "relabel_seconds_first": 6, "relabel_seconds_median": 6,
    "relabel_seconds_median_all": 6, "train_95_iteration": int, "train_95_seconds": 6,
}
EVALUATION_COLUMNS: dict[str, Any] = {
    "run": str, "evaluation": str, "final": int, "checkpoint": str, "task": str, "speed": 1, "radius": 1,
    "seed": int, "episodes": int, "success": 5, "success_low": 5, "success_high": 5, "instructions": 4,
    "instructions_successful": 4, "decisions": 4, "ms_per_instruction": 4, "mean_return": 3,
    "out_of_airspace": int, "budget_exhausted": int, "overrides": str,
}
CURVE_COLUMNS: dict[str, Any] = {
    "run": str, "iteration": int, "frames": int, "seconds": 6, "success": 5, "instructions": 3,
    "train_success": 5,
}
DATA_FILES = {"runs.csv": RUN_COLUMNS, "evaluations.csv": EVALUATION_COLUMNS, "curves.csv": CURVE_COLUMNS}
#: The training success threshold whose first iteration ``runs.csv`` keeps (``train_95_*``): the curves keep only
#: the periodic evaluations, not every iteration's training success.
TRAINING_THRESHOLD = 0.95
SUCCESS_KEY = "eval/success_rate"  # the periodic evaluation over the full start box
TRAINING_SUCCESS_KEY = "train/success_rate"  # every iteration's training episodes (with the curriculum: easier)


class ReportError(Exception):
    """A one-line error about the report's input, naming the value and what is allowed."""


def _rounded(value: Any, kind: Any) -> Any:
    """``value`` as the column ``kind`` keeps it (see :data:`RUN_COLUMNS`); None for a missing or non-finite one."""
    if value is None or value == "":
        return None
    if kind is str:
        return str(value)
    number = float(value)
    if not math.isfinite(number):
        return None
    return int(round(number)) if kind is int else round(number, kind)


def _typed(row: dict, columns: dict) -> dict:
    return {name: _rounded(row.get(name), kind) for name, kind in columns.items()}


def write_csv(path: Path, rows: list[dict], columns: dict) -> None:
    """``rows`` as a CSV with a header of ``columns``; empty cells for None, floats as rounded (no trailing
    ``.0`` for whole numbers), so the same rows give the same bytes."""
    def cell(value: Any) -> Any:
        if isinstance(value, float):
            return format(value, "g") if value.is_integer() and abs(value) < 1e15 else repr(value)
        return "" if value is None else value

    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(columns)
        for row in rows:
            writer.writerow([cell(row.get(name)) for name in columns])


def read_csv(path: Path, columns: dict) -> list[dict]:
    """Rows written by :func:`write_csv`, typed by ``columns`` (a column the file lacks is None)."""
    with open(path, newline="", encoding="utf-8") as handle:
        return [_typed(row, columns) for row in csv.DictReader(handle)]
