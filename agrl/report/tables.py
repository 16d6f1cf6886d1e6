"""Tables of runs and evaluations as they are: one line per run, a summary per group of runs or of evaluations,
one line per evaluation."""

from __future__ import annotations

import re
from collections import defaultdict
from pathlib import Path
from typing import Any

from agrl.report.measures import (
    _cell,
    _independent_cell,
    _mean_std,
    _selector_label,
    independent_evaluations,
    time_to_reach,
)


def runs_table(runs: list[dict], times: list[float], independent: tuple[str, ...] = ()) -> str:
    """One line per run: its first periodic evaluation, its best evaluation by each of ``times`` (training
    seconds), the training seconds of the first evaluation at or above 95 %, the final evaluation, and the
    iterations' cost (median over all iterations but the first, then the first; relabelling in brackets); then
    a column per ``independent`` selector (:func:`independent_evaluations`): success and instructions."""
    extra = "".join(f" {_selector_label([runs], selector)}: success, instructions |" for selector in independent)
    lines = ["| run | evaluation before training | best evaluation by " + " / ".join(f"{t:g}" for t in times)
             + " s | s to 95 % | final success (episodes) | instructions | iterations "
             "| median s / iteration (relabelling) | first iteration s (relabelling) |" + extra,
             "|---|---:|---|---:|---:|---:|---:|---:|---:|" + "---:|" * len(independent)]
    for run in sorted(runs, key=lambda run: run["run"]):
        evaluations = [(row["seconds"] or 0.0, row["success"]) for row in run["curve"]]
        reached = time_to_reach(run["curve"], 0.95)  # (iteration, seconds) or None
        best = [max((success for seconds, success in evaluations if seconds <= limit), default=None)
                for limit in times]
        start = evaluations[0][1] * 100 if evaluations else None
        best_text = " / ".join(_cell(None if value is None else value * 100, "{:.0f}") for value in best)
        episodes = f" ({run['episodes']})" if run["episodes"] is not None else ""
        lines.append(
            f"| {run['run']} | {_cell(start, '{:.1f} %')} | {best_text} % "
            f"| {_cell(None if reached is None else reached[1], '{:.0f}')} | {run['success'] * 100:.1f} %{episodes} "
            f"| {_cell(run['instructions'])} "
            f"| {run['iterations_logged'] or 0} | {_cell(run['iteration_seconds_median'], '{:.2f}')} "
            f"({_cell(run['relabel_seconds_median'], '{:.2f}')}) "
            f"| {_cell(run['iteration_seconds_first'])} ({_cell(run['relabel_seconds_first'])}) |"
            + "".join(f" {_independent_run_cell(run, selector)} |" for selector in independent))
    return "\n".join(lines)


def _independent_run_cell(run: dict, selector: str) -> str:
    found = independent_evaluations(run, selector)
    return f"{found[0]['success'] * 100:.2f} %, {_cell(found[0]['instructions'], '{:.2f}')}" if found else "-"


#: Keys ``summary --by`` takes besides the ``runs.csv`` columns: ``variant``, the overrides without the seed and
#: the ``hydra.*`` ones; ``series``, the run's path without its seed (``k0.3_s1`` -> ``k0.3``, ``fast64_s0_stage2``
#: -> ``fast64_stage2``, ``a=1,seed=0,b=2`` -> ``a=1,b=2``); ``folder``, the folder the run lies in.
DERIVED_KEYS = ("variant", "series", "folder")


def derived_value(run: dict, key: str) -> Any:
    """``run``'s value of a ``runs.csv`` column or of one of :data:`DERIVED_KEYS`."""
    if key == "variant":
        return " ".join(item for item in (run["overrides"] or "").split()
                        if not item.startswith(("seed=", "hydra.")))
    if key == "series":
        name = re.sub(r"(^|,)seed=\d+(?=,|$)", "", run["run"])
        return re.sub(r"_(s|seed)\d+(?=[_/]|$)", "", name).replace(",,", ",")
    if key == "folder":
        return Path(run["run"]).parent.as_posix()
    return run[key]


def summary_table(runs: list[dict], keys: list[str], independent: tuple[str, ...] = ()) -> str:
    """One row per group of ``runs`` with equal ``keys`` (sorted by them): runs, final success and instructions
    (mean ± sd over the group), training seconds and iterations, then one column per independent evaluation
    (``independent`` selectors, :func:`independent_evaluations`; by default every evaluation seed found)."""
    groups: dict[tuple, list] = defaultdict(list)
    for run in sorted(runs, key=lambda run: run["run"]):
        groups[tuple(derived_value(run, key) for key in keys)].append(run)
    selectors = list(independent) or sorted({str(row["seed"]) for run in runs for row in run["evaluations"]
                                             if row["seed"] is not None}, key=int)
    header = [*keys, "runs", "final success", "instructions", "training s", "iterations",
              *(f"{_selector_label(list(groups.values()), s)}: success, instructions" for s in selectors)]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]

    def order(item: tuple) -> tuple:
        return tuple((value is None, "" if value is None else value if isinstance(value, str) else
                      format(value, "020.6f")) for value in item[0])

    for values, group in sorted(groups.items(), key=order):
        cells = ["-" if value is None else (f"`{value}`" if key in ("variant", "overrides") and value else
                                            format(value, "g") if isinstance(value, float) else str(value) or "-")
                 for key, value in zip(keys, values, strict=True)]
        cells += [str(len(group)), f"{_mean_std([run['success'] * 100 for run in group], '.2f')} %",
                  _mean_std([run["instructions"] for run in group], ".2f"),
                  _mean_std([run["training_seconds"] for run in group], ".1f").replace("not reached", "-"),
                  _mean_std([run["iterations"] for run in group], ".0f").replace("not reached", "-")]
        cells += [_independent_cell(group, selector) for selector in selectors]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def evaluation_summary_table(evaluations: list[dict], keys: list[str]) -> str:
    """One row per group of ``evaluations`` (final ones included) with equal ``keys`` (``evaluations.csv``
    columns, or ``folder``: the folder the evaluation lies in): evaluations, episodes in all, success (one
    evaluation: with its 95 % Wilson interval; several: mean ± sd), instructions and decisions per episode, and the
    episodes out of airspace and out of budget."""
    groups: dict[tuple, list] = defaultdict(list)
    for row in evaluations:
        groups[tuple(Path(row["evaluation"]).parent.as_posix() if key == "folder" else row[key]
                     for key in keys)].append(row)
    header = [*keys, "evaluations", "episodes", "success", "instructions", "decisions", "out of airspace",
              "budget exhausted"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(keys) + "---:|" * 7]

    def order(item: tuple) -> tuple:
        return tuple((value is None, "" if value is None else value if isinstance(value, str) else
                      format(value, "020.6f")) for value in item[0])

    def total(rows: list[dict], key: str) -> str:
        values = [row[key] for row in rows if row[key] is not None]
        return str(sum(values)) if values else "-"

    for values, group in sorted(groups.items(), key=order):
        cells = ["-" if value is None else format(value, "g") if isinstance(value, float) else str(value)
                 for value in values]
        if len(group) == 1 and group[0]["success_low"] is not None:
            row = group[0]
            success = (f"{row['success'] * 100:.2f} % ({row['success_low'] * 100:.2f}-"
                       f"{row['success_high'] * 100:.2f})")
        else:
            success = f"{_mean_std([row['success'] * 100 for row in group if row['success'] is not None], '.2f')} %"
        cells += [str(len(group)), total(group, "episodes"), success,
                  _mean_std([row["instructions"] for row in group], ".2f").replace("not reached", "-"),
                  _mean_std([row["decisions"] for row in group], ".1f").replace("not reached", "-"),
                  total(group, "out_of_airspace"), total(group, "budget_exhausted")]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def evaluations_table(evaluations: list[dict], final: bool = False) -> str:
    """One line per evaluation (the independent ones; with ``final``, the runs' final ones too): its folder, run,
    checkpoint, task, seed, episodes, success with its 95 % Wilson interval, instructions and decisions."""
    lines = ["| evaluation | run | checkpoint | task | seed | episodes | success (95 % interval) | instructions | "
             "decisions |", "|---|---|---|---|---:|---:|---|---:|---:|"]
    for row in evaluations:
        if row["final"] and not final:
            continue
        task = row["task"] or "-"
        if row["speed"] is not None and task in ("uniform", "irregular"):
            task += f" {row['speed']:g} m/s"
        if row["radius"] is not None and task == "curved":
            task += f" {row['radius']:g} m"
        interval = "" if row["success_low"] is None else \
            f" ({row['success_low'] * 100:.2f}-{row['success_high'] * 100:.2f})"
        success = "-" if row["success"] is None else f"{row['success'] * 100:.2f} %{interval}"
        lines.append(f"| {row['evaluation']} | {row['run'] or '-'} | {row['checkpoint'] or '-'} | {task} | "
                     f"{_cell(row['seed'], '{}')} | {_cell(row['episodes'], '{}')} | {success} | "
                     f"{_cell(row['instructions'], '{:.2f}')} | {_cell(row['decisions'], '{:.1f}')} |")
    return "\n".join(lines)


#: The fields that tell ``make bench``'s measurements of one name apart (what was measured), in this order; the
