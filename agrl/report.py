"""``python -m agrl.report``: turn finished runs into the paper's tables and figures.

    python -m agrl.report table3 runs/table3 > table3.md              # the tables go to standard output
    python -m agrl.report table3 runs/table3 --independent eval_777   # + each run's <run>/eval_777/eval.json
    python -m agrl.report moving runs/moving --figures docs/results/figures
    python -m agrl.report runs runs/moving --times 60 120 180 240       # one line per run: its curve and costs

Each run directory is found by its ``eval/eval.json``; its ``.hydra/config.yaml`` says which task, method,
reward and seed it was, and its TensorBoard scalars (``tensorboard/events.out.tfevents.*``, the one metrics sink
of :mod:`agrl.rl.metrics`) give the training curve (success against wall time).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf

import agrl.config  # noqa: F401  (registers the resolver used in saved configs)
from agrl.cli import writable_folder
from agrl.config import ConfigError
from agrl.plots import plot_success_against_time

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


def method_of(run: dict) -> str:
    """The method's report name: ``reuse`` with ``start_from_baseline`` is told apart from the paper's."""
    method = run["config"]["method"]
    return "reuse_from_baseline" if method.get("start_from_baseline") else method["name"]


def read_metrics(run_dir: str | Path) -> list[dict[str, float]]:
    """A run's TensorBoard scalars as rows, one per logged step (decisions trained), oldest first.

    Each row has ``iteration``, ``frames`` and ``wall_time`` (s) and every tag logged at that step; a tag not
    logged there (e.g. ``eval/success_rate`` between evaluations) is absent. A step logged twice (a run resumed
    from an earlier checkpoint repeats iterations) keeps its last value. Runs made before every step carried
    ``train/iteration`` and ``time/wall_time`` lacked them only at step 0, the initial evaluation.
    """
    from tensorboard.backend.event_processing.event_accumulator import SCALARS, EventAccumulator

    folder = Path(run_dir) / "tensorboard"
    if not any(folder.glob("events.out.tfevents.*")):
        return []
    accumulator = EventAccumulator(str(folder), size_guidance={SCALARS: 0})  # 0 = keep every event
    accumulator.Reload()
    steps: dict[int, dict[str, float]] = defaultdict(dict)
    for tag in accumulator.Tags()["scalars"]:
        for event in accumulator.Scalars(tag):
            steps[event.step][tag] = event.value
    return [{"iteration": values.get("train/iteration", 0.0), "frames": float(step),
             "wall_time": values.get("time/wall_time", 0.0), **values} for step, values in sorted(steps.items())]


def find_runs(root: Path) -> list[dict[str, Any]]:
    """Every finished run below ``root``: its config, evaluation and metrics (:func:`read_metrics`)."""
    runs = []
    for evaluation in sorted(root.rglob("eval/eval.json")):
        run_dir = evaluation.parent.parent
        config_file = run_dir / ".hydra" / "config.yaml"
        if not config_file.is_file():
            continue
        config = OmegaConf.to_container(OmegaConf.load(config_file), resolve=True)
        runs.append({"dir": run_dir, "config": config, "eval": json.loads(evaluation.read_text()),
                     "metrics": read_metrics(run_dir)})
    return runs


#: Success measured by the periodic deterministic evaluation over the full start box. Training success is not
#: comparable across methods: with the curriculum, scratch runs train on easier (closer) starts first.
SUCCESS_KEY = "eval/success_rate"
TRAINING_SUCCESS_KEY = "train/success_rate"


def time_to_reach(metrics: list[dict[str, float]], threshold: float,
                  key: str = SUCCESS_KEY) -> tuple[int, float] | None:
    """(iteration, wall seconds) of the first row of ``metrics`` whose ``key`` reaches ``threshold``, or None."""
    for row in metrics:
        value = row.get(key)
        if value is not None and value >= threshold:
            return int(row["iteration"]), float(row["wall_time"])
    return None


def run_time_to_reach(run: dict, threshold: float, key: str = SUCCESS_KEY) -> tuple[int, float] | None:
    """Like :func:`time_to_reach` for one found run; for evaluation success, the final 1000-episode evaluation
    counts as the last point (at the training's end), so a run whose last periodic evaluation came before
    the target but whose final policy meets it is not reported as never reaching it."""
    hit = time_to_reach(run["metrics"], threshold, key)
    final = run["eval"]
    if hit is None and key == SUCCESS_KEY and final.get("success_rate", 0.0) >= threshold \
            and "training_wall_time_s" in final:
        return int(final.get("iterations", 0)), float(final["training_wall_time_s"])
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


def reward_label(config: dict) -> str:
    """A run's Table 3 row: the reward variant; for ``switch`` (not in the paper) its cost per instruction, and
    which shaping term it goes without if one is switched off."""
    reward = config["reward"]
    if reward["name"] != "switch":
        return reward["name"]
    dropped = [term for term, key in (("continuous-action", "use_continuous_action"), ("position", "use_position"))
               if not reward.get(key, True)]
    without = "".join(f", no {term} term" for term in dropped)
    return f"switch (k = {float(reward.get('switch_cost', 0.0)):g}{without})"


def independent_evaluation(run: dict, folder: str) -> dict | None:
    """The ``eval.json`` that ``python -m agrl.evaluate`` wrote to ``<run>/<folder>`` (episodes no training or
    stop of the run used), or None."""
    path = Path(run["dir"]) / folder / "eval.json"
    return json.loads(path.read_text()) if path.is_file() else None


def table3(runs: list[dict[str, Any]], independent: tuple[str, ...] = ()) -> str:
    """The paper's Table 3 (mean ± standard deviation over seeds) from the fixed-destination runs among ``runs``,
    one row per reward variant and method: the paper's four in its order, then ``switch`` rows by cost, then those
    of runs that started from a baseline (a fine-tune, ``+experiment=switch_finetune``). ``independent`` names
    evaluation folders inside each run (see :func:`independent_evaluation`); each adds a column of success and
    instructions on those episodes."""
    groups: dict[str, list] = defaultdict(list)
    order: dict[str, tuple] = {}  # rows: the paper's in its order, then by method, switch cost and name
    for run in runs:
        if run["config"]["task"]["name"] != "fixed":
            continue  # Table 3 is the fixed destination (main() says how many runs were left out)
        method = method_of(run)
        label = reward_label(run["config"]) + ("" if method == "scratch" else f", {METHOD_LABELS[method].lower()}")
        groups[label].append(run)
        paper_row = list(PAPER_TABLE3).index(label) if label in PAPER_TABLE3 else len(PAPER_TABLE3)
        reward = run["config"]["reward"]
        cost = float(reward.get("switch_cost", 0.0)) if reward["name"] == "switch" else 0.0
        order[label] = (paper_row, METHODS.index(method), cost, label)
    extra = "".join(f" {folder}: success, instructions |" for folder in independent)
    lines = [
        "| Reward | Seeds | Success rate | Instructions / episode | ms / instruction | Iterations to 95 % eval | "
        "Minutes to 95 % eval | Iterations to 99 % eval | Minutes to 99 % eval |" + extra
        + " Paper: success, instructions, ms |",
        "|---|---|---|---|---|---|---|---|---|" + "---|" * len(independent) + "---|",
    ]
    for name in sorted(groups, key=order.get):
        group = groups[name]
        success = [run["eval"]["success_rate"] * 100 for run in group]
        instructions = [run["eval"]["instructions_per_episode"] for run in group]
        latency = [run["eval"]["ms_per_instruction"] for run in group]
        it95, min95, n95 = _reached(group, 0.95)
        it99, min99, n99 = _reached(group, 0.99)
        cells = []
        for folder in independent:
            found = [evaluation for run in group if (evaluation := independent_evaluation(run, folder))]
            cells.append(
                f"{_mean_std([e['success_rate'] * 100 for e in found], '.2f')} %, "
                f"{_mean_std([e['instructions_per_episode'] for e in found], '.2f')} ({len(found)}/{len(group)})"
                if found else "-")
        paper = PAPER_TABLE3.get(name)
        lines.append(
            f"| {name} | {len(group)} | {_mean_std(success, '.1f')} % | {_mean_std(instructions, '.2f')} | "
            f"{_mean_std(latency, '.2f')} | {_mean_std(it95, '.0f')} ({n95}/{len(group)}) | "
            f"{_mean_std(min95, '.1f')} | "
            f"{_mean_std(it99, '.0f')} ({n99}/{len(group)}) | {_mean_std(min99, '.1f')} | "
            + "".join(f"{cell} | " for cell in cells)
            + (f"{paper[0] * 100:.1f} %, {paper[1]}, {paper[2]} ms |" if paper else "not in the paper |")
        )
    return "\n".join(lines)


def _setting(run: dict) -> tuple[str, float]:
    task = run["config"]["task"]
    if task["name"] == "uniform":
        return "uniform", float(task["speed"])
    if task["name"] == "curved":
        return "curved", float(task["radius"])
    return task["name"], 0.0


def moving_tables(runs: list[dict[str, Any]], figure_dir: Path | None, figure_suffix: str = "") -> str:
    groups: dict[tuple, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for run in runs:
        groups[_setting(run)][method_of(run)].append(run)
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
                success = _mean_std([run["eval"]["success_rate"] * 100 for run in group], ".1f")
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
                curves = {METHOD_LABELS[m]: [run["metrics"] for run in groups[(kind, value)].get(m, [])]
                          for m in METHODS if groups[(kind, value)].get(m)}
                name = f"{kind}_{value:g}{figure_suffix}.png"
                plot_success_against_time(curves, figure_dir / name, key=SUCCESS_KEY,
                                          title=f"{kind} destination, {label.lower()} {value:g} {unit}")
                out.append(f"![{kind} {value:g}]({figure_dir.name}/{name})")  # the page beside the folder
            out.append("")
    out.append(targets_table(groups))
    return "\n".join(out)


def median_minutes_to(runs: list[dict], threshold: float, key: str = SUCCESS_KEY) -> float:
    """Median over runs of the wall minutes until ``key`` (evaluation success by default) reaches ``threshold``;
    a run that never got there counts as infinitely slow (so the median is infinite when half the runs missed)."""
    hits = [run_time_to_reach(run, threshold, key) for run in runs]
    return statistics.median([hit[1] / 60 if hit else float("inf") for hit in hits])


def median_scalar(run_dir: Path, tag: str) -> float | None:
    """Median of a TensorBoard scalar over a run (e.g. ``time/reuse_seconds``), or None if it was not logged."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    values = []
    for events in (run_dir / "tensorboard").rglob("events.out.tfevents.*"):
        accumulator = EventAccumulator(str(events), size_guidance={"scalars": 0})
        accumulator.Reload()
        if tag in accumulator.Tags().get("scalars", []):
            values += [event.value for event in accumulator.Scalars(tag)]
    return statistics.median(values) if values else None


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
        lowest = " / ".join(f"{min(r['eval']['success_rate'] for r in by_method[m]) * 100:.1f} %"
                            if by_method.get(m) else "-" for m in methods)
        costs = [median_scalar(run["dir"], "time/reuse_seconds") for run in by_method["reuse"]]
        costs = [c for c in costs if c is not None]
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


def runs_table(runs: list[dict[str, Any]], root: Path, times: list[float]) -> str:
    """One line per run: its first periodic evaluation, its best evaluation by each of ``times`` (training
    seconds), the training seconds of the first evaluation at or above 95 %, the final evaluation, and the
    iterations' cost (median over all iterations but the first, then the first; relabelling in brackets)."""

    def cell(value: float | None, fmt: str = "{:.1f}") -> str:
        return "-" if value is None else fmt.format(value)

    lines = ["| run | evaluation before training | best evaluation by " + " / ".join(f"{t:g}" for t in times)
             + " s | s to 95 % | final success (episodes) | instructions | iterations "
             "| median s / iteration (relabelling) | first iteration s (relabelling) |",
             "|---|---:|---|---:|---:|---:|---:|---:|---:|"]
    for run in sorted(runs, key=lambda run: str(run["dir"])):
        rows = run["metrics"]
        evaluations = [(row["wall_time"], row[SUCCESS_KEY]) for row in rows if SUCCESS_KEY in row]
        iterations = [row for row in rows if "time/iteration_seconds" in row]
        reached = time_to_reach(rows, 0.95)  # (iteration, wall seconds) or None
        reached_seconds = None if reached is None else reached[1]
        best = [max((success for seconds, success in evaluations if seconds <= limit), default=None)
                for limit in times]
        later = [row["time/iteration_seconds"] for row in iterations[1:]]
        # Only reuse runs log a relabelling time; the other methods get "-", not a median of zeros.
        relabel = [row["time/reuse_seconds"] for row in iterations[1:] if "time/reuse_seconds" in row]
        first = iterations[0] if iterations else {}
        start = evaluations[0][1] * 100 if evaluations else None
        best_text = " / ".join(cell(None if value is None else value * 100, "{:.0f}") for value in best)
        final = run["eval"]
        episodes = f" ({final['episodes']})" if "episodes" in final else ""
        lines.append(
            f"| {Path(run['dir']).relative_to(root)} | {cell(start, '{:.1f} %')} | {best_text} % "
            f"| {cell(reached_seconds, '{:.0f}')} | {final['success_rate'] * 100:.1f} %{episodes} "
            f"| {final['instructions_per_episode']:.1f} "
            f"| {len(iterations)} | {cell(statistics.median(later) if later else None, '{:.2f}')} "
            f"({cell(statistics.median(relabel) if relabel else None, '{:.2f}')}) "
            f"| {cell(first.get('time/iteration_seconds'))} ({cell(first.get('time/reuse_seconds'))}) |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m agrl.report", description=__doc__.splitlines()[0])
    parser.add_argument("kind", choices=("table3", "moving", "runs"))
    parser.add_argument("root", type=Path, help="a folder containing finished runs (e.g. a multirun sweep dir)")
    parser.add_argument("--figures", type=Path, help="folder for success-against-time figures (moving)")
    parser.add_argument("--figure-suffix", default="", help="appended to figure names, e.g. _8min (moving)")
    parser.add_argument("--times", type=float, nargs="+", default=[60, 120, 180],
                        help="training seconds at which to give each run's best evaluation so far (runs)")
    parser.add_argument("--independent", nargs="+", default=[], metavar="FOLDER",
                        help="evaluation folders inside each run (python -m agrl.evaluate ... hydra.run.dir=<run>/"
                             "FOLDER), one column each of success and instructions (table3)")
    args = parser.parse_args(argv)
    if not args.root.is_dir():
        parser.error(f"{args.root}: no such folder; allowed: a folder containing finished runs")
    if any(seconds <= 0 for seconds in args.times):
        parser.error(f"--times {' '.join(f'{seconds:g}' for seconds in args.times)} is not allowed: seconds > 0")
    try:
        if args.figures is not None:
            writable_folder(args.figures / "figure.png")  # before the tables, not after them
    except ConfigError as error:
        print(f"agrl.report: error: --figures: {error}", file=sys.stderr)
        return 2
    runs = find_runs(args.root)
    if not runs:
        print(f"agrl.report: error: no finished runs (eval/eval.json) below {args.root}", file=sys.stderr)
        return 2
    if args.kind == "table3":
        others = sum(run["config"]["task"]["name"] != "fixed" for run in runs)
        if others == len(runs):
            print(f"agrl.report: error: no finished fixed-destination runs below {args.root} (Table 3 is the fixed "
                  "destination)", file=sys.stderr)
            return 2
        if others:
            print(f"agrl.report: {others} run{'s' if others > 1 else ''} of other tasks left out: Table 3 is the "
                  "fixed destination", file=sys.stderr)
        print(table3(runs, tuple(args.independent)))
    elif args.kind == "moving":
        print(moving_tables(runs, args.figures, args.figure_suffix))
    else:
        print(runs_table(runs, args.root, args.times))
    return 0


if __name__ == "__main__":
    sys.exit(main())
