"""Training metrics: per-iteration episode statistics, and where they are written.

Every scalar goes to TensorBoard (``<run>/tensorboard``, TorchRL's ``TensorboardLogger``);
a compact ``metrics.csv`` (one row per iteration, the columns :mod:`agrl.report` reads)
is written beside it.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np
from tensordict import TensorDictBase
from torchrl.record.loggers import TensorboardLogger

from agrl.core.termination import Outcome
from agrl.envs.guidance import REWARD_PART_KEYS

#: The columns of ``metrics.csv`` beyond iteration, frames and wall time.
CSV_COLUMNS = ("train/success_rate", "eval/success_rate", "train/instructions_per_episode", "train/reuse_fraction",
               "train/e")


def flatten_config(config: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Flatten nested dicts to ``a.b.c`` keys with scalar values (TensorBoard hparams take no nesting)."""
    flat = {}
    for key, value in config.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            flat.update(flatten_config(value, f"{name}."))
        elif isinstance(value, int | float | str | bool):
            flat[name] = value
        else:
            flat[name] = str(value)
    return flat


def episode_statistics(data: TensorDictBase) -> dict[str, float]:
    """Outcome rates and per-episode means over the episodes that ended in ``data``.

    The reward's parts (``train/reward_*``, keys of :data:`REWARD_PART_KEYS`) are means per decision over
    every transition of the iteration, so they add up to ``train/reward_per_decision``, the mean of what PPO
    was trained on (finished or not): a user sees which term drives learning.
    """
    reward_parts = {f"train/{key}": float(data["next", key].mean()) for key in REWARD_PART_KEYS}
    reward_parts["train/reward_per_decision"] = float(data["next", "reward"].mean())
    done = data["next", "done"].squeeze(-1)
    finished = int(done.sum())
    if finished == 0:
        return {"train/episodes": 0, **reward_parts}
    outcome = data["next", "outcome"][done]
    return {
        **reward_parts,
        "train/episodes": finished,
        "train/success_rate": float((outcome == Outcome.SUCCESS).float().mean()),
        "train/out_of_airspace_rate": float((outcome == Outcome.OUT_OF_AIRSPACE).float().mean()),
        "train/time_out_rate": float((outcome == Outcome.BUDGET_EXHAUSTED).float().mean()),
        "train/episode_reward": float(data["next", "episode_return"][done].mean()),
        "train/decisions_per_episode": float(data["next", "step_count"][done].float().mean()),
        "train/instructions_per_episode": float(data["next", "instruction_count"][done].float().mean()),
    }


def progress_line(iteration: int, frames: int, wall_time: float, metrics: dict[str, float]) -> str:
    parts = [f"iter {iteration}", f"decisions {frames}", f"wall {wall_time:.0f}s",
             f"train success {metrics.get('train/success_rate', float('nan')):.3f}"]
    if "eval/success_rate" in metrics:
        parts.append(f"eval success {metrics['eval/success_rate']:.3f}")
    parts.append(f"{metrics['time/decisions_per_second']:.0f} dec/s")
    return " | ".join(parts)


class MetricsLog:
    """TensorBoard scalars (and images) plus ``metrics.csv``, both keyed by decisions trained."""

    def __init__(self, run_dir: Path):
        self.tensorboard = TensorboardLogger(exp_name="tensorboard", log_dir=str(run_dir))
        self.csv_path = Path(run_dir) / "metrics.csv"

    def log_hparams(self, config: dict[str, Any]) -> None:
        self.tensorboard.log_hparams(flatten_config(config))

    def log(self, metrics: dict[str, float], iteration: int, frames: int, wall_time: float) -> None:
        for key, value in metrics.items():
            if isinstance(value, int | float) and math.isfinite(value):
                self.tensorboard.log_scalar(key, value, step=frames)
        row = {"iteration": iteration, "frames": frames, "wall_time": round(wall_time, 3)}
        row.update({key: metrics.get(key, "") for key in CSV_COLUMNS})
        new_file = not self.csv_path.exists()
        with self.csv_path.open("a", newline="") as file:
            writer = csv.DictWriter(file, fieldnames=list(row))
            if new_file:
                writer.writeheader()
            writer.writerow(row)

    def log_image(self, tag: str, image: np.ndarray, frames: int) -> None:
        """An ``(H, W, 3)`` uint8 picture, e.g. the evaluation's trajectories, on the dashboard's Images tab."""
        self.tensorboard.experiment.add_image(tag, image, global_step=frames, dataformats="HWC")
