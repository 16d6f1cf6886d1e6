"""What exact resume needs besides the networks: the run's counters, random-number states and the collector's
carried rows.

Everything here is stored as tensors and plain Python values, so checkpoints load with
``torch.load(weights_only=True)`` (see :mod:`agrl.rl.checkpoint`).
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.collectors import Collector

from agrl.envs.guidance import GuidanceEnv


@dataclass
class Counters:
    """Where a run is: checkpoints keep these, and a resumed run goes on from them."""

    iteration: int = 0
    frames: int = 0
    wall_time: float = 0.0  # seconds of training, summed over resumed sessions
    best_success: float = -1.0
    curriculum_scale: float = 1.0  # fraction of the start box used for training episodes
    next_evaluation_time: float = 0.0  # s of training; the wall-clock evaluation schedule (eval.interval_seconds)
    finetune_from: int = 0  # the iteration after which the run's fine-tune began (0: not begun; cfg.finetune)


def seed_everything(seed: int) -> None:
    torch.manual_seed(seed)
    random.seed(seed)
    np.random.seed(seed)


def rng_states(env: GuidanceEnv) -> dict[str, Any]:
    """torch (CPU and CUDA), the env's own stream, Python's and NumPy's generators."""
    name, keys, position, has_gauss, cached_gaussian = np.random.get_state()
    return {
        "torch": torch.get_rng_state(),
        "cuda": torch.cuda.get_rng_state_all() if torch.cuda.is_available() else None,
        "env": env.generator_state(),
        "python": random.getstate(),
        # NumPy's key array as a tensor: a NumPy array would need unpickling to load.
        "numpy": (name, torch.from_numpy(keys.copy()), int(position), int(has_gauss), float(cached_gaussian)),
    }


def restore_rng_states(env: GuidanceEnv, states: dict[str, Any]) -> None:
    torch.set_rng_state(states["torch"])
    if states.get("cuda") is not None and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(states["cuda"])
    env.set_generator_state(states["env"])
    random.setstate(states["python"])
    name, keys, position, has_gauss, cached_gaussian = states["numpy"]
    keys = keys.numpy() if isinstance(keys, torch.Tensor) else keys  # format-1 checkpoints stored the array
    np.random.set_state((name, keys, position, has_gauss, cached_gaussian))


def carried_rows(collector: Collector) -> dict[str, Any]:
    """The rows the collector carries into its next step, as a plain dict of CPU tensors.

    TorchRL 0.14's ``Collector`` keeps them in its private ``_carrier`` and offers no
    public accessor; this is the one place agrl reads a private TorchRL attribute.
    """
    return collector._carrier.exclude("collector").clone().cpu().to_dict()


def carried_rows_from_checkpoint(stored: dict[str, Any] | TensorDictBase) -> TensorDictBase:
    if isinstance(stored, TensorDictBase):  # format-1 checkpoints stored the TensorDict itself
        return stored
    return TensorDict.from_dict(stored, batch_size=stored["step_count"].shape[:1])
