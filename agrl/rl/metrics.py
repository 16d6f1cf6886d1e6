"""Training metrics: per-iteration episode statistics, and where they are written.

One sink: every scalar goes to TensorBoard (``<run>/tensorboard``, TorchRL's ``TensorboardLogger``),
keyed by decisions trained; :func:`agrl.report.read_metrics` reads it back for tables and figures
(``train/iteration`` and ``time/wall_time`` are scalars like the others).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from tensordict import TensorDictBase
from torchrl.record.loggers import TensorboardLogger

from agrl.core.reward import REWARD_PART_KEYS
from agrl.core.termination import Outcome


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
    """TensorBoard scalars (and images), keyed by decisions trained."""

    def __init__(self, run_dir: Path):
        self.tensorboard = TensorboardLogger(exp_name="tensorboard", log_dir=str(run_dir))

    def log_hparams(self, config: dict[str, Any]) -> None:
        self.tensorboard.log_hparams(flatten_config(config))

    def log(self, metrics: dict[str, float], frames: int) -> None:
        """One iteration's scalars (``train/iteration`` and ``time/wall_time`` among them), written to disk
        now: a report or a watcher reads every finished iteration, even of a run still going."""
        for key, value in metrics.items():
            if isinstance(value, int | float) and math.isfinite(value):
                self.tensorboard.log_scalar(key, value, step=frames)
        self.tensorboard.experiment.flush()

    def log_image(self, tag: str, image: np.ndarray, frames: int) -> None:
        """An ``(H, W, 3)`` uint8 picture, e.g. the evaluation's trajectories, on the dashboard's Images tab."""
        self.tensorboard.experiment.add_image(tag, image, global_step=frames, dataformats="HWC")
