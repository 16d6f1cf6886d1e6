"""Measures of runs (time to a success rate, independent evaluations) and the table cells that show them."""

from __future__ import annotations

import statistics
from pathlib import Path

from agrl.report.columns import SUCCESS_KEY, TRAINING_SUCCESS_KEY, TRAINING_THRESHOLD


def time_to_reach(curve: list[dict], threshold: float) -> tuple[int, float] | None:
    """(iteration, training seconds) of the first periodic evaluation of ``curve`` at or above ``threshold``."""
    for row in curve:
        if row["success"] is not None and row["success"] >= threshold:
            return int(row["iteration"] or 0), float(row["seconds"] or 0.0)
    return None


def run_time_to_reach(run: dict, threshold: float, key: str = SUCCESS_KEY) -> tuple[int, float] | None:
    """(iteration, training seconds) when ``run`` first reached ``threshold``, or None.

    For evaluation success (``key`` :data:`SUCCESS_KEY`), the final evaluation counts as the last point (at the
    training's end), so a run whose last periodic evaluation came before the target but whose final policy meets
    it is not reported as never reaching it. For training success (:data:`TRAINING_SUCCESS_KEY`, every
    iteration's training episodes), the threshold must be :data:`TRAINING_THRESHOLD`, the one the data keeps."""
    if key == TRAINING_SUCCESS_KEY:
        if threshold != TRAINING_THRESHOLD:
            raise ValueError(f"training success threshold {threshold:g} is not kept; allowed: {TRAINING_THRESHOLD}")
        seconds = run["train_95_seconds"]
        return None if seconds is None else (run["train_95_iteration"] or 0, seconds)
    if key != SUCCESS_KEY:
        raise ValueError(f"{key}: not a kept success; allowed: {SUCCESS_KEY}, {TRAINING_SUCCESS_KEY}")
    hit = time_to_reach(run["curve"], threshold)
    if hit is None and (run["success"] or 0.0) >= threshold and run["training_seconds"] is not None:
        return int(run["iterations"] or 0), float(run["training_seconds"])
    return hit


def _mean_std(values: list[float], fmt: str) -> str:
    values = [v for v in values if v is not None]
    if not values:
        return "not reached"
    if len(values) == 1:
        return format(values[0], fmt)
    return f"{format(statistics.mean(values), fmt)} ± {format(statistics.stdev(values), fmt)}"


def _reached(runs: list[dict], threshold: float) -> tuple[list, list, int]:
    hits = [run_time_to_reach(run, threshold) for run in runs]
    iterations = [hit[0] for hit in hits if hit]
    minutes = [hit[1] / 60 for hit in hits if hit]
    return iterations, minutes, sum(hit is not None for hit in hits)


def median_minutes_to(runs: list[dict], threshold: float, key: str = SUCCESS_KEY) -> float:
    """Median over runs of the training minutes until ``key`` (evaluation success by default) reaches
    ``threshold``; a run that never got there counts as infinitely slow (so the median is infinite when half the
    runs missed)."""
    hits = [run_time_to_reach(run, threshold, key) for run in runs]
    return statistics.median([hit[1] / 60 if hit else float("inf") for hit in hits])


def independent_evaluations(run: dict, selector: str) -> list[dict]:
    """``run``'s independent evaluations that ``selector`` names: by folder name (``eval_777``) or evaluation
    seed (``777``)."""
    return [row for row in run["evaluations"]
            if Path(row["evaluation"]).name == selector or str(row["seed"]) == selector]


def _selector_label(groups: list[list[dict]], selector: str) -> str:
    """A column's name for the evaluations ``selector`` picked: their seed and episodes when all share them."""
    found = [row for group in groups for run in group for row in independent_evaluations(run, selector)]
    kinds = {(row["seed"], row["episodes"]) for row in found}
    if len(kinds) == 1 and None not in next(iter(kinds)):
        seed, episodes = next(iter(kinds))
        return f"seed {seed} ({format(episodes, ',').replace(',', ' ')})"
    return selector


def _independent_cell(group: list[dict], selector: str) -> str:
    found = [rows[0] for run in group if (rows := independent_evaluations(run, selector))]
    if not found:
        return "-"
    return (f"{_mean_std([row['success'] * 100 for row in found], '.2f')} %, "
            f"{_mean_std([row['instructions'] for row in found], '.2f')} ({len(found)}/{len(group)})")


def _cell(value: float | None, fmt: str = "{:.1f}") -> str:
    return "-" if value is None else fmt.format(value)
