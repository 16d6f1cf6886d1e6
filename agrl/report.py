"""``python -m agrl.report``: the results pages' tables and figures, from small data files extracted from runs.

    python -m agrl.report extract runs/moving docs/results/data/moving    # run folders -> runs/evaluations/curves.csv
    python -m agrl.report table3 docs/results/data/table3_2026-12-03 --independent 777 4242  # tables to standard output
    python -m agrl.report moving docs/results/data/moving --figures docs/results/figures
    python -m agrl.report runs docs/results/data/moving --times 60 120 180 240       # one line per run
    python -m agrl.report summary docs/results/data/switch_finetune --by variant    # mean ± sd over seeds per group
    python -m agrl.report evaluations docs/results/data/zero_shot_2026-12-03     # one line per independent evaluation
    python -m agrl.report bench docs/results/data/bench_2026-12-03/bench.jsonl   # one line per `make bench` JSON line
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

from __future__ import annotations

import argparse
import contextlib
import csv
import fnmatch
import io
import json
import math
import os
import re
import shlex
import shutil
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

# ---------------------------------------------------------------------------------------------- the data files
#: Each data file's columns and their types: ``str``, ``int`` or the number of decimals a float is rounded to
#: (seconds keep 6: TensorBoard's float32 values, rounded any coarser, can land on a table's rounding boundary).
RUN_COLUMNS: dict[str, Any] = {
    "run": str, "task": str, "speed": 1, "radius": 1, "method": str, "reward": str, "switch_cost": 3, "seed": int,
    "overrides": str, "commit": str, "training_seconds": 1, "iterations": int, "decisions_trained": int,
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
#: A runs folder's own result files (outside any run or evaluation) that ``extract`` copies, up to
#: :data:`MAX_COPIED_BYTES` each: benchmark JSON lines and small result tables. Logs, scripts and Hydra's records
#: are raw outputs and stay with the runs.
COPIED_SUFFIXES = (".jsonl", ".json", ".csv")
MAX_COPIED_BYTES = 200_000
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


# ------------------------------------------------------------------------------------------- reading run folders
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


def read_metrics_csv(path: str | Path) -> list[dict[str, float]]:
    """The rows of an older run's ``metrics.csv`` (``iteration``, ``frames``, ``wall_time`` and tags as
    columns), in :func:`read_metrics`' form: an empty cell is an absent tag."""
    with open(path, newline="", encoding="utf-8") as handle:
        return [{key: float(value) for key, value in row.items() if value not in ("", None)}
                for row in csv.DictReader(handle)]


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


def _load_config(folder: Path) -> dict | None:
    for name in (".hydra", "hydra"):
        path = folder / name / "config.yaml"
        if path.is_file():
            config = OmegaConf.load(path)
            try:
                return OmegaConf.to_container(config, resolve=True)
            except Exception:  # an older config whose interpolations no longer resolve: its plain values
                return OmegaConf.to_container(config, resolve=False)
    return None


def _load_overrides(folder: Path) -> str:
    for name in (".hydra", "hydra"):
        path = folder / name / "overrides.yaml"
        if path.is_file():
            return " ".join(str(item) for item in (OmegaConf.to_container(OmegaConf.load(path)) or []))
    return ""


def _median(values: list[float]) -> float | None:
    return statistics.median(values) if values else None


def _evaluation_row(run: str, evaluation: str, final: bool, data: dict, overrides: str) -> dict:
    interval = data.get("success_rate_ci95") or (None, None)
    outcomes = data.get("outcomes") or {}
    return _typed({
        "run": run, "evaluation": evaluation, "final": int(final), "checkpoint": data.get("checkpoint"),
        "task": data.get("task"), "speed": data.get("speed"), "radius": data.get("radius"),
        "seed": data.get("evaluation_seed", data.get("seed")) if final else data.get("seed"),
        "episodes": data.get("episodes"), "success": data.get("success_rate"), "success_low": interval[0],
        "success_high": interval[1], "instructions": data.get("instructions_per_episode"),
        "instructions_successful": data.get("instructions_per_successful_episode"),
        "decisions": data.get("decisions_per_episode"), "ms_per_instruction": data.get("ms_per_instruction"),
        "mean_return": data.get("mean_return"), "out_of_airspace": outcomes.get("out_of_airspace"),
        "budget_exhausted": outcomes.get("budget_exhausted"), "overrides": overrides,
    }, EVALUATION_COLUMNS)


def _run_rows(name: str, config: dict | None, final: dict | None, overrides: str,
              metrics: list[dict[str, float]]) -> tuple[dict, list[dict]]:
    """A run's ``runs.csv`` row and its ``curves.csv`` rows, from its config, final evaluation and metrics."""
    final = final or {}
    if config is not None:
        task, reward, method = config.get("task", {}), config.get("reward", {}), config.get("method", {})
        task_name, method_name = task.get("name"), method.get("name")
        speed = task.get("speed") if task_name in ("uniform", "irregular") else None
        radius = task.get("radius") if task_name == "curved" else None
        label = reward_label(config) if "name" in reward else None
        cost = reward.get("switch_cost") if reward.get("name") == "switch" else None
        from_baseline = bool(method.get("start_from_baseline"))
        seed = config.get("seed")
    else:  # a run that kept only its final evaluation
        task_name, method_name = final.get("task"), final.get("method")
        speed, radius, label, cost, from_baseline = final.get("speed"), final.get("radius"), final.get("reward"), \
            None, False
        seed = final.get("seed")
    method_name = "reuse_from_baseline" if method_name == "reuse" and from_baseline else method_name
    iterations = [row for row in metrics if "time/iteration_seconds" in row]
    relabelled = [row["time/reuse_seconds"] for row in iterations if "time/reuse_seconds" in row]
    first = iterations[0] if iterations else {}
    trained = next(((row["iteration"], row["wall_time"]) for row in metrics
                    if row.get(TRAINING_SUCCESS_KEY, -1.0) >= TRAINING_THRESHOLD), (None, None))
    interval = final.get("success_rate_ci95") or (None, None)
    run = _typed({
        "run": name, "task": task_name, "speed": speed, "radius": radius, "method": method_name, "reward": label,
        "switch_cost": cost, "seed": seed, "overrides": overrides, "commit": final.get("commit"),
        "training_seconds": final.get("training_wall_time_s"), "iterations": final.get("iterations"),
        "decisions_trained": final.get("decisions_trained"), "episodes": final.get("episodes"),
        "success": final.get("success_rate"), "success_low": interval[0], "success_high": interval[1],
        "instructions": final.get("instructions_per_episode"), "decisions": final.get("decisions_per_episode"),
        "ms_per_instruction": final.get("ms_per_instruction"), "evaluation_seed": final.get("evaluation_seed"),
        "iterations_logged": len(iterations), "iteration_seconds_first": first.get("time/iteration_seconds"),
        "iteration_seconds_median": _median([row["time/iteration_seconds"] for row in iterations[1:]]),
        "relabel_seconds_first": first.get("time/reuse_seconds"),
        "relabel_seconds_median": _median([row["time/reuse_seconds"] for row in iterations[1:]
                                           if "time/reuse_seconds" in row]),
        "relabel_seconds_median_all": _median(relabelled),
        "train_95_iteration": trained[0], "train_95_seconds": trained[1],
    }, RUN_COLUMNS)
    curve = [_typed({"run": name, "iteration": row["iteration"], "frames": row["frames"],
                     "seconds": row["wall_time"], "success": row[SUCCESS_KEY],
                     "instructions": row.get("eval/instructions_per_episode"),
                     "train_success": row.get(TRAINING_SUCCESS_KEY)}, CURVE_COLUMNS)
             for row in metrics if SUCCESS_KEY in row]
    return run, curve


def _checkpoint_run(checkpoint: str | None, root_name: str, runs: list[str]) -> str:
    """The run (path below the runs folder named ``root_name``) that ``checkpoint`` was saved in, or ''."""
    if not checkpoint:
        return ""
    path = "/" + checkpoint.replace(os.sep, "/").strip("/")
    if path.endswith(".pt"):
        path = path.rsplit("/", 1)[0]
    if path.endswith("/checkpoints"):
        path = path[: -len("/checkpoints")]
    for run in sorted(runs, key=len, reverse=True):
        if path.endswith("/" + root_name + ("" if run == "." else "/" + run)):
            return run
    return ""


def extract(root: str | Path) -> dict[str, list]:
    """Every run and evaluation below ``root``, as the rows of the data files: ``{"runs.csv": [...],
    "evaluations.csv": [...], "curves.csv": [...], "files": [paths of the folder's own result files]}``.
    Rows are sorted and rounded as the files keep them, so tables made from them equal tables made from the
    files."""
    root = Path(root)
    runs, evaluations, curves, files = [], [], [], []
    run_names: list[str] = []
    standalone: list[tuple[str, dict, str]] = []  # evaluations outside any run: (folder, eval.json, overrides)
    taken: set[Path] = set()  # run and evaluation folders: their files are not the folder's own
    for folder, subfolders, names in os.walk(root):
        folder_path = Path(folder)
        subfolders[:] = sorted(name for name in subfolders if name not in ("tensorboard", "checkpoints"))
        if folder_path.name in (".hydra", "hydra") or (folder_path.name == "eval" and folder_path.parent in taken):
            continue  # Hydra's own files; a run's final evaluation (read with the run)
        relative = folder_path.relative_to(root).as_posix()
        config = _load_config(folder_path)
        final_file = next((path for path in (folder_path / "eval" / "eval.json", folder_path / "eval.json")
                           if path.is_file()), None)
        final = json.loads(final_file.read_text()) if final_file else None
        is_run = (config is not None and "ppo" in config) or (folder_path / "eval" / "eval.json").is_file() or (
            config is None and final is not None and "training_wall_time_s" in final)
        if is_run:
            metrics = read_metrics(folder_path)
            if not metrics and (folder_path / "metrics.csv").is_file():
                metrics = read_metrics_csv(folder_path / "metrics.csv")
            overrides = _load_overrides(folder_path)
            run, curve = _run_rows(relative, config, final, overrides, metrics)
            runs.append(run)
            curves += curve
            run_names.append(relative)
            if final is not None:
                evaluation = final_file.parent.relative_to(root).as_posix()
                evaluations.append(_evaluation_row(relative, evaluation, True, final, ""))
            taken.add(folder_path)
        elif "eval.json" in names:
            data = json.loads((folder_path / "eval.json").read_text())
            owner = next((above for above in folder_path.parents if above in taken), None)  # a run it lies in
            if owner is not None:
                evaluations.append(_evaluation_row(owner.relative_to(root).as_posix(), relative, False, data,
                                                   _load_overrides(folder_path)))
            else:
                standalone.append((relative, data, _load_overrides(folder_path)))
            taken.add(folder_path)
        else:
            for name in sorted(names):
                path = folder_path / name
                if path.suffix in COPIED_SUFFIXES and path.stat().st_size <= MAX_COPIED_BYTES and \
                        not any(above in taken for above in path.parents):
                    files.append(path.relative_to(root).as_posix())
    root_name = root.resolve().name
    for relative, data, overrides in standalone:
        checkpoint = data.get("checkpoint") or next(
            (item.split("=", 1)[1] for item in overrides.split() if item.startswith("checkpoint=")), None)
        owner = _checkpoint_run(checkpoint, root_name, run_names)
        evaluations.append(_evaluation_row(owner, relative, False, data, overrides))
    runs.sort(key=lambda row: row["run"])
    evaluations.sort(key=lambda row: (row["run"] or "", row["evaluation"]))
    curves.sort(key=lambda row: (row["run"], row["frames"] or 0))
    return {"runs.csv": runs, "evaluations.csv": evaluations, "curves.csv": curves, "files": sorted(files)}


def write_data(root: str | Path, data: dict[str, list], folder: str | Path) -> None:
    """Write :func:`extract`'s rows of ``root`` into ``folder`` as CSVs, and copy its own result files there."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, columns in DATA_FILES.items():
        write_csv(folder / name, data[name], columns)
    for relative in data["files"]:
        target = folder / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(Path(root) / relative, target)


def data_folder_above(path: str | Path) -> Path | None:
    """The data folder (with ``runs.csv``) that ``path`` is or lies below (the path need not exist), or None."""
    path = Path(path).absolute()
    return next((folder for folder in (path, *path.parents) if (folder / "runs.csv").is_file()), None)


def load_data(folder: str | Path) -> dict[str, list]:
    """A data folder's rows (:func:`extract`'s form). A path below a data folder (``data/switch_finetune/
    position_2026-12-03``) is that folder's runs and evaluations below it, named from there on, as from the same
    path among the runs; a folder of runs (no ``runs.csv`` in or above it) is extracted in memory."""
    above = data_folder_above(folder)
    if above is None:
        return extract(folder)
    data: dict[str, list] = {"files": []}
    for name, columns in DATA_FILES.items():
        data[name] = read_csv(above / name, columns) if (above / name).is_file() else []
    prefix = Path(folder).absolute().relative_to(above).as_posix()
    if prefix == ".":
        return data

    def below(name: str | None) -> str | None:
        """``name`` relative to the prefix, or None if it is not below it."""
        if name is None or not (name == prefix or name.startswith(prefix + "/")):
            return None
        return name[len(prefix) + 1:] or "."

    for name in ("runs.csv", "curves.csv"):
        data[name] = [{**row, "run": below(row["run"])} for row in data[name] if below(row["run"]) is not None]
    data["evaluations.csv"] = [{**row, "run": below(row["run"]), "evaluation": below(row["evaluation"])}
                               for row in data["evaluations.csv"] if below(row["evaluation"]) is not None]
    return data


def assemble_runs(data: dict[str, list], patterns: tuple[str, ...] = ()) -> list[dict]:
    """The runs of ``data`` (those whose path matches one of ``patterns``, if any), each its ``runs.csv`` row with
    ``curve`` (its periodic evaluations, oldest first) and ``evaluations`` (its independent ones, by folder)."""
    curves: dict[str, list] = defaultdict(list)
    for row in data["curves.csv"]:
        curves[row["run"]].append(row)
    independent: dict[str, list] = defaultdict(list)
    for row in data["evaluations.csv"]:
        if not row["final"] and row["run"]:
            independent[row["run"]].append(row)
    return [{**row, "curve": curves[row["run"]], "evaluations": independent[row["run"]]}
            for row in data["runs.csv"] if not patterns or any(fnmatch.fnmatchcase(row["run"], pattern)
                                                                for pattern in patterns)]


def finished(runs: list[dict]) -> list[dict]:
    """The runs with a final evaluation (the tables' input)."""
    return [run for run in runs if run["success"] is not None]


# ------------------------------------------------------------------------------------------------------ measures
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


# -------------------------------------------------------------------------------------------------------- tables
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


def _cell(value: float | None, fmt: str = "{:.1f}") -> str:
    return "-" if value is None else fmt.format(value)


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
#: others (timing repeats, calls per timing, load) say how, and stay in the JSON lines.
BENCH_SETTING_FIELDS = ("device", "trainer", "guide", "batch", "compiled", "candidates", "z")
#: Fields shown as their own columns when a line has them: the comparisons a reader looks for.
BENCH_COMPARISONS = {"speedup_vs_reference": "× the reference", "collection_s": "collection s",
                     "update_s": "update s", "first_call_seconds": "first call s"}


def _bench_value(value: Any) -> str:
    if isinstance(value, bool):
        return json.dumps(value)
    if isinstance(value, (int, float)):
        return f"{value:,.0f}" if abs(value) >= 1000 else format(value, ".4g")
    return "-" if value is None else str(value)


def _bench_setting(value: Any) -> str:
    return json.dumps(value) if isinstance(value, bool) else str(value)


def bench_table(paths: list[Path]) -> str:
    """One line per measurement in ``make bench``'s JSON lines (other lines, e.g. library logging, are skipped):
    its name, what was measured (:data:`BENCH_SETTING_FIELDS`), value, unit and :data:`BENCH_COMPARISONS`. The
    ``machine`` lines are left out: the page says which machine it was."""
    lines = ["| name | setting | value | unit | " + " | ".join(BENCH_COMPARISONS.values()) + " |",
             "|---|---|---:|---|" + "---:|" * len(BENCH_COMPARISONS)]
    for path in paths:
        for text in path.read_text(encoding="utf-8").splitlines():
            try:
                record = json.loads(text)
            except json.JSONDecodeError:
                continue
            if not isinstance(record, dict) or record.get("name") == "machine":
                continue
            setting = ", ".join(f"{key}={_bench_setting(record[key])}" for key in BENCH_SETTING_FIELDS
                                if key in record) or "-"
            comparisons = " | ".join(_bench_value(record.get(key)) for key in BENCH_COMPARISONS)
            lines.append(f"| {record.get('name', '-')} | {setting.replace('|', '/')} | "
                         f"{_bench_value(record.get('value'))} | {record.get('unit', '-')} | {comparisons} |")
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------------------- pages
BLOCK_START = re.compile(r"^<!-- report: (?P<command>.*?) -->\s*$")
BLOCK_END = "<!-- /report -->"
DEFAULT_PAGES = ("docs/results", "docs/benchmarks.md")
IMAGE_LINK = re.compile(r"!\[[^\]]*\]\((?P<path>[^)\s]+)\)")


def page_files(targets: list[str]) -> list[Path]:
    """The markdown files ``targets`` name (a folder: its ``*.md``, not below), sorted within each folder."""
    files = []
    for target in targets:
        path = Path(target)
        if path.is_dir():
            files += sorted(path.glob("*.md"))
        elif path.is_file():
            files.append(path)
        else:
            raise ReportError(f"{target}: no such file or folder; allowed: markdown pages or folders of them")
    return files


def run_block(command: str, draw: bool) -> tuple[int, str, str]:
    """Run ``python -m agrl.report <command>`` in this process: (exit code, standard output, standard error)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            arguments = shlex.split(command)
            if arguments and arguments[0] == "pages":
                raise ReportError("pages: a block cannot run pages")
            code = main(arguments, draw=draw)
        except SystemExit as exited:  # argparse's errors
            code = exited.code if isinstance(exited.code, int) else 2
        except (ReportError, ValueError) as error:
            print(f"agrl.report: error: {error}", file=sys.stderr)
            code = 2
    return code, out.getvalue(), err.getvalue()


def update_pages(files: list[Path], check: bool) -> tuple[list[str], list[str]]:
    """Rerun every report block of ``files``; write the changed pages unless ``check``. Returns (one line per
    out-of-date block, one line per failed block), each naming the file and line."""
    stale, failed = [], []
    for path in files:
        lines = path.read_text(encoding="utf-8").split("\n")
        result: list[str] = []
        index = 0
        while index < len(lines):
            line = lines[index]
            result.append(line)
            match = BLOCK_START.match(line)
            index += 1
            if match is None:
                continue
            start = index
            end = next((number for number in range(start, len(lines)) if lines[number].strip() == BLOCK_END), None)
            where = f"{path}:{start}"
            if end is None:
                failed.append(f"{where}: report block without its closing {BLOCK_END}")
                continue
            body = lines[start:end]
            code, output, errors = run_block(match["command"], draw=not check)
            if code != 0:
                message = (errors.strip().splitlines() or [f"exit code {code}"])[-1]
                failed.append(f"{where}: report block `{match['command']}` failed: {message}")
                result += body
            else:
                new_body = output.rstrip("\n").split("\n")
                missing = [link["path"] for link in IMAGE_LINK.finditer(output)
                           if not (path.parent / link["path"]).is_file()]
                if new_body != body or missing:
                    what = f"figures missing: {', '.join(missing)}" if new_body == body else "text differs"
                    stale.append(f"{where}: report block `{match['command']}` is out of date ({what})")
                result += new_body
            result.append(lines[end])
            index = end + 1
        if not check:
            text = "\n".join(result)
            if text != path.read_text(encoding="utf-8"):
                path.write_text(text, encoding="utf-8")
    return stale, failed


# ---------------------------------------------------------------------------------------------------------- main
def _matches(evaluation: dict, patterns: list[str]) -> bool:
    """Whether an evaluation's folder or run matches one of ``patterns`` (all do when there are none)."""
    return not patterns or any(fnmatch.fnmatchcase(evaluation["evaluation"], pattern) or
                               fnmatch.fnmatchcase(evaluation["run"] or "", pattern) for pattern in patterns)


TABLES = ("table3", "moving", "runs", "summary", "evaluations")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m agrl.report", description=__doc__.splitlines()[0])
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


def main(argv: list[str] | None = None, draw: bool = True) -> int:
    """The command line; ``draw=False`` links figures without drawing them (``pages --check``)."""
    parser = _parser()
    args = parser.parse_args(argv)
    try:
        if args.kind == "pages":
            stale, failed = update_pages(page_files(args.targets), args.check)
            for line in failed:
                print(f"agrl.report: error: {line}", file=sys.stderr)
            if args.check:
                for line in stale:
                    print(line, file=sys.stderr)
            return 2 if failed else (1 if args.check and stale else 0)
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


if __name__ == "__main__":
    sys.exit(main())
