"""Run folders to the data files' rows: :func:`extract` reads every run and evaluation below a folder (configs,
final and independent evaluations, TensorBoard scalars), :func:`write_data` writes them as a data folder."""

from __future__ import annotations

import csv
import json
import os
import shutil
import statistics
from collections import defaultdict
from pathlib import Path

from omegaconf import OmegaConf

from agrl.config import (  # (importing agrl.config registers the resolver of saved configs)
    LEGACY_ACTIONS,
    upgraded_config,
)
from agrl.report.columns import (
    CURVE_COLUMNS,
    DATA_FILES,
    EVALUATION_COLUMNS,
    RUN_COLUMNS,
    SUCCESS_KEY,
    TRAINING_SUCCESS_KEY,
    TRAINING_THRESHOLD,
    _typed,
    write_csv,
)

#: A runs folder's own result files (outside any run or evaluation) that ``extract`` copies, up to
#: :data:`MAX_COPIED_BYTES` each: benchmark JSON lines and small result tables. Logs, scripts and Hydra's records
#: are raw outputs and stay with the runs.
COPIED_SUFFIXES = (".jsonl", ".json", ".csv")
MAX_COPIED_BYTES = 200_000


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
                values = OmegaConf.to_container(config, resolve=True)
            except Exception:  # an older config whose interpolations no longer resolve: its plain values
                values = OmegaConf.to_container(config, resolve=False)
            return upgraded_config(values) if isinstance(values, dict) else values  # today's keys
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
        actions = config.get("actions", LEGACY_ACTIONS)["name"]  # a config without the group flew maneuvers
    else:  # a run that kept only its final evaluation
        task_name, method_name = final.get("task"), final.get("method")
        speed, radius, label, cost, from_baseline = final.get("speed"), final.get("radius"), final.get("reward"), \
            None, False
        seed, actions = final.get("seed"), None
    method_name = "reuse_from_baseline" if method_name == "reuse" and from_baseline else method_name
    iterations = [row for row in metrics if "time/iteration_seconds" in row]
    relabelled = [row["time/reuse_seconds"] for row in iterations if "time/reuse_seconds" in row]
    first = iterations[0] if iterations else {}
    trained = next(((row["iteration"], row["wall_time"]) for row in metrics
                    if row.get(TRAINING_SUCCESS_KEY, -1.0) >= TRAINING_THRESHOLD), (None, None))
    interval = final.get("success_rate_ci95") or (None, None)
    run = _typed({
        "run": name, "task": task_name, "speed": speed, "radius": radius, "method": method_name, "reward": label,
        "switch_cost": cost, "seed": seed, "actions": actions, "overrides": overrides, "commit": final.get("commit"),
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
