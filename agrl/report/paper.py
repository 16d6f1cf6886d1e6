"""The paper's tables from runs: Table 3 (fixed destination), Tables 4 and 5 (moving destinations, with their
success-against-time figures) and the issue's targets, each beside the paper's values."""

from __future__ import annotations

import statistics
from collections import defaultdict
from pathlib import Path

from agrl.plots import plot_success_against_time
from agrl.report.columns import SUCCESS_KEY, TRAINING_SUCCESS_KEY
from agrl.report.measures import _independent_cell, _mean_std, _reached, _selector_label, median_minutes_to

PAPER_TABLE3 = {  # success rate, average number of control times, average computational time (ms)
    "none": (0.986, 11.31, 2.98),
    "continuous": (0.994, 7.26, 2.89),
    "position": (0.991, 11.52, 2.92),
    "both": (0.995, 7.22, 2.91),
}
PAPER_TABLE4 = {  # uniform motion: speed -> method -> success rate
    10: {"scratch": 0.996, "pretrained": 0.992, "reuse": 0.994},
    20: {"scratch": 0.990, "pretrained": 0.994, "reuse": 0.992},
    50: {"scratch": 0.994, "pretrained": 0.992, "reuse": 0.994},
    100: {"scratch": 0.990, "pretrained": 0.991, "reuse": 0.991},
}
PAPER_TABLE5 = {  # curved motion: radius -> method -> success rate (the paper's 500 m scratch cell is empty)
    500: {"scratch": None, "pretrained": 0.990, "reuse": 0.992},
    1000: {"scratch": 0.991, "pretrained": 0.994, "reuse": 0.995},
    2000: {"scratch": 0.994, "pretrained": 0.995, "reuse": 0.993},
    5000: {"scratch": 0.994, "pretrained": 0.997, "reuse": 0.997},
}
METHOD_LABELS = {"scratch": "Training from scratch", "pretrained": "Pre-trained algorithm",
                 "reuse": "Policy-reuse algorithm",
                 "reuse_from_baseline": "Policy reuse, Z starting from B (this project's variant)"}
METHODS = ("scratch", "pretrained", "reuse", "reuse_from_baseline")


def table3(runs: list[dict], independent: tuple[str, ...] = ()) -> str:
    """The paper's Table 3 (mean ± standard deviation over seeds) from the fixed-destination runs among ``runs``,
    one row per reward variant and method: the paper's four in its order, then ``switch`` rows by cost, then those
    of runs that started from a baseline (a fine-tune, ``+experiment=switch_finetune``). ``independent`` selects
    evaluations of each run (:func:`independent_evaluations`); each adds a column of success and instructions on
    those episodes."""
    groups: dict[str, list] = defaultdict(list)
    order: dict[str, tuple] = {}  # rows: the paper's in its order, then by method, switch cost and name
    for run in runs:
        if run["task"] != "fixed":
            continue  # Table 3 is the fixed destination (main() says how many runs were left out)
        method = run["method"]
        label = run["reward"] + ("" if method == "scratch" else f", {METHOD_LABELS[method].lower()}")
        groups[label].append(run)
        paper_row = list(PAPER_TABLE3).index(label) if label in PAPER_TABLE3 else len(PAPER_TABLE3)
        order[label] = (paper_row, METHODS.index(method), run["switch_cost"] or 0.0, label)
    extra = "".join(f" {_selector_label(list(groups.values()), selector)}: success, instructions |"
                    for selector in independent)
    lines = [
        "| Reward | Seeds | Success rate | Instructions / episode | ms / instruction | Iterations to 95 % eval | "
        "Minutes to 95 % eval | Iterations to 99 % eval | Minutes to 99 % eval |" + extra
        + " Paper: success, instructions, ms |",
        "|---|---|---|---|---|---|---|---|---|" + "---|" * len(independent) + "---|",
    ]
    for name in sorted(groups, key=order.get):
        group = sorted(groups[name], key=lambda run: run["run"])
        it95, min95, n95 = _reached(group, 0.95)
        it99, min99, n99 = _reached(group, 0.99)
        paper = PAPER_TABLE3.get(name)
        lines.append(
            f"| {name} | {len(group)} | {_mean_std([run['success'] * 100 for run in group], '.1f')} % | "
            f"{_mean_std([run['instructions'] for run in group], '.2f')} | "
            f"{_mean_std([run['ms_per_instruction'] for run in group], '.2f')} | "
            f"{_mean_std(it95, '.0f')} ({n95}/{len(group)}) | {_mean_std(min95, '.1f')} | "
            f"{_mean_std(it99, '.0f')} ({n99}/{len(group)}) | {_mean_std(min99, '.1f')} | "
            + "".join(f"{_independent_cell(group, selector)} | " for selector in independent)
            + (f"{paper[0] * 100:.1f} %, {paper[1]}, {paper[2]} ms |" if paper else "not in the paper |")
        )
    return "\n".join(lines)


def _setting(run: dict) -> tuple[str, float]:
    if run["task"] == "uniform":
        return "uniform", float(run["speed"] or 0.0)
    if run["task"] == "curved":
        return "curved", float(run["radius"] or 0.0)
    return run["task"], 0.0


def _metrics_rows(run: dict) -> list[dict[str, float]]:
    """A run's curve in :func:`agrl.plots.plot_success_against_time`'s form (the training success is the one of
    the iteration each periodic evaluation followed)."""
    return [{"wall_time": row["seconds"] or 0.0, SUCCESS_KEY: row["success"], TRAINING_SUCCESS_KEY:
             row["train_success"]} for row in run["curve"]]


def moving_tables(runs: list[dict], figure_dir: Path | None, figure_suffix: str = "", draw: bool = True) -> str:
    """The paper's Tables 4 and 5 (and the irregular destination): per setting and method, final success (mean ±
    sd over seeds) and the minutes to 95 % evaluation success; then :func:`targets_table`. With ``figure_dir``,
    each setting's success-against-time figure is linked (and drawn there, unless ``draw`` is False)."""
    groups: dict[tuple, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for run in sorted(runs, key=lambda run: run["run"]):
        groups[_setting(run)][run["method"]].append(run)
    out = []
    for kind, unit, paper in (("uniform", "m/s", PAPER_TABLE4), ("curved", "m", PAPER_TABLE5),
                              ("irregular", "", {})):
        settings = sorted(value for (task, value) in groups if task == kind)
        if not settings:
            continue
        label = {"uniform": "Destination speed", "curved": "Turning radius", "irregular": "Irregular"}[kind]
        out.append(f"### {kind.capitalize()} destination\n")
        # The irregular destination has no speed or radius: its one column is named by the kind alone.
        out.append("| Method | " + " | ".join(f"{label} {v:g} {unit}" if unit else label for v in settings) + " |")
        out.append("|---|" + "---|" * len(settings))
        for method in METHODS:
            if not any(groups[(kind, value)].get(method) for value in settings):
                continue
            cells = []
            for value in settings:
                group = groups[(kind, value)].get(method, [])
                if not group:
                    cells.append("not run")
                    continue
                success = _mean_std([run["success"] * 100 for run in group], ".1f")
                _, minutes, hits = _reached(group, 0.95)
                reference = paper.get(int(value), {}).get(method) if paper else None
                paper_text = f"; paper {reference * 100:.1f} %" if reference else ""
                after = f"after {_mean_std(minutes, '.1f')} min" if hits else "not reached"
                cells.append(f"{success} % (n={len(group)}); 95 % evaluation success {after} "
                             f"({hits}/{len(group)}){paper_text}")
            out.append(f"| {METHOD_LABELS[method]} | " + " | ".join(cells) + " |")
        out.append("")
        if figure_dir is not None:
            for value in settings:
                curves = {METHOD_LABELS[m]: [_metrics_rows(run) for run in groups[(kind, value)].get(m, [])]
                          for m in METHODS if groups[(kind, value)].get(m)}
                name = f"{kind}_{value:g}{figure_suffix}.png"
                if draw:
                    plot_success_against_time(curves, figure_dir / name, key=SUCCESS_KEY,
                                              title=f"{kind} destination, {label.lower()} {value:g} {unit}")
                out.append(f"![{kind} {value:g}]({figure_dir.name}/{name})")  # the page beside the folder
            out.append("")
    out.append(targets_table(groups))
    return "\n".join(out)


def targets_table(groups: dict) -> str:
    """The issue's targets per setting: >= 99 % final success, and reuse's time to 95 % against the others.

    Each time is given twice: to 95 % periodic-evaluation success (full start box, on the runs' ``eval``
    schedule) and to 95 % training success (every iteration; for scratch, on the curriculum's easier starts).
    Settings where ``reuse`` also ran with ``method.start_from_baseline=true`` get that variant's times too."""
    methods = ("scratch", "pretrained", "reuse")
    lines = ["### Against the targets\n",
             "Minutes of training wall time to 95 % success, as *evaluation / training* success: the median over "
             "seeds (∞: not reached by at least half of the seeds). Evaluation success is measured on the full start "
             "box at each periodic evaluation (`eval.interval` iterations or `eval.interval_seconds` seconds apart, "
             "as the runs were configured); training success every iteration on the training episodes "
             "(for scratch, on the curriculum's easier starts). Then the lowest final success (1000 episodes) of "
             "any seed and the median relabelling time per reuse iteration. Reuse + B = reuse with "
             "`method.start_from_baseline=true` (not the paper's Algorithm 1); '-': not run.\n",
             "| Setting | Scratch | Pre-trained | Reuse | Reuse + B | Reuse < scratch | Reuse < pre-trained | "
             "Lowest final success (scratch / pre-trained / reuse) | Relabelling s / iteration |",
             "|---|---|---|---|---|---|---|---|---|"]
    keys = (SUCCESS_KEY, TRAINING_SUCCESS_KEY)

    def minutes_text(value: float) -> str:
        return "∞" if value == float("inf") else f"{value:.2f}"

    def faster(a: float | None, b: float | None) -> str:
        return "-" if a is None or b is None else ("yes" if a < b else "no")

    for (kind, value), by_method in sorted(groups.items()):
        if not by_method.get("reuse"):
            continue
        minutes = {(m, key): median_minutes_to(by_method[m], 0.95, key) if by_method.get(m) else None
                   for m in (*methods, "reuse_from_baseline") for key in keys}
        text = {m: " / ".join("-" if minutes[m, key] is None else minutes_text(minutes[m, key]) for key in keys)
                for m in (*methods, "reuse_from_baseline")}
        compare = {other: " / ".join(faster(minutes["reuse", key], minutes[other, key]) for key in keys)
                   for other in ("scratch", "pretrained")}
        lowest = " / ".join(f"{min(r['success'] for r in by_method[m]) * 100:.1f} %"
                            if by_method.get(m) else "-" for m in methods)
        costs = [run["relabel_seconds_median_all"] for run in by_method["reuse"]
                 if run["relabel_seconds_median_all"] is not None]
        cost = f"{statistics.median(costs):.1f}" if costs else "-"
        unit = {"uniform": "m/s", "curved": "m"}.get(kind)
        setting = f"{kind} {value:g} {unit}" if unit else kind  # the irregular destination has no speed or radius
        lines.append(
            f"| {setting} | {text['scratch']} | {text['pretrained']} | {text['reuse']} | "
            f"{text['reuse_from_baseline']} | {compare['scratch']} | {compare['pretrained']} | {lowest} | {cost} |"
        )
    if len(lines) == 4:  # no setting with reuse runs: nothing to compare
        return ""
    return "\n".join(lines) + "\n"
