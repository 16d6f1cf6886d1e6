"""``method=reuse``: the paper's policy reuse by destination position prediction (Algorithm 1).

Z trains with PPO from its own flying, and each collected batch passes, on its way into the replay buffer,
through :class:`agrl.rl.reuse.PolicyReuseTransform`: selected episodes are re-flown by the frozen baseline B
towards predicted destination positions, and successful re-flights replace Z's rows (``docs/policy_reuse.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch
from omegaconf import MISSING
from tensordict import TensorDictBase

from agrl.config import MethodConfig, TrainConfig, require, require_baseline
from agrl.rl.methods.from_baseline import FromBaseline
from agrl.rl.ppo import clip_fraction_by_source, make_advantage
from agrl.rl.reuse import PolicyReuseTransform, relabelled_ppo_targets

if TYPE_CHECKING:
    from agrl.rl.trainer import Trainer

#: Relabelled episodes may be longer than the rows they replace: the buffer holds up to this many batches' rows.
STORAGE_BATCHES = 3


@dataclass
class ReuseConfig(MethodConfig):
    """Algorithm 1's knobs (values and reasons: ``conf/method/reuse.yaml``)."""

    initial_selection_factor: float = MISSING  # e at the start (Algorithm 1)
    selection_decay: float = MISSING  # k, subtracted from e per relabelled episode
    candidate_stride: int = MISSING  # consider every n-th step as a termination step t_n
    max_candidates: int = MISSING  # at most this many t_n per episode (evenly spread)
    keep: str = MISSING  # which successful candidate to keep: earliest | latest
    behaviour_log_prob: str = MISSING  # relabelled rows' PPO behaviour log-prob: current (Z's) | baseline (B's)
    start_from_baseline: bool = MISSING  # Z starts from B's weights (reuse + pre-training)
    relabel_unfinished: bool = MISSING  # false: an episode running at a batch's end is searched once, when it ends
    relabel_own_successes: bool = MISSING  # false: episodes Z flew to a success keep Z's rows (not searched)
    equal_update_cost: bool = MISSING  # true: as many minibatches per update as a plain iteration's, over all rows

    def __post_init__(self) -> None:
        require_baseline(self)
        require(0 <= self.initial_selection_factor <= 1, "method.initial_selection_factor",
                self.initial_selection_factor, "[0, 1]")
        require(self.selection_decay >= 0, "method.selection_decay", self.selection_decay, ">= 0")
        require(self.candidate_stride >= 1, "method.candidate_stride", self.candidate_stride, ">= 1")
        require(self.max_candidates >= 1, "method.max_candidates", self.max_candidates, ">= 1")
        require(self.keep in ("earliest", "latest"), "method.keep", self.keep, "earliest or latest")
        require(self.behaviour_log_prob in ("current", "baseline"), "method.behaviour_log_prob",
                self.behaviour_log_prob, "current or baseline")

    def check(self, train: TrainConfig) -> None:
        workers = train.ppo.collector_workers
        require(workers == 1, "ppo.collector_workers", workers,
                "1 with method=reuse (the reuse transform carries episodes of the single collector's envs)")


class PolicyReuse(FromBaseline):
    """Algorithm 1 as a replay-buffer transform, with the PPO targets of relabelled rows and its dashboards."""

    config_class = ReuseConfig
    episode_ids = True  # the transform finds each row's episode by them (agrl.rl.reuse.carry)
    transform: PolicyReuseTransform | None = None

    def starts_from_baseline(self) -> bool:
        return self.config.start_from_baseline  # Algorithm 1 line 1: Z from scratch, unless asked

    def storage_rows(self, frames_per_batch: int) -> int:
        return frames_per_batch * STORAGE_BATCHES

    def buffer_transform(self, trainer: Trainer) -> PolicyReuseTransform:
        method, ppo = self.config, trainer.cfg.ppo
        # For re-played trajectories the critic's values come with the data, on valid rows only (agrl.rl.reuse).
        replay_advantage = make_advantage(trainer.cfg.reward.gamma, ppo.gae_lambda, None, trainer.device)
        actor = trainer.actor if method.behaviour_log_prob == "current" else None

        def ppo_targets(trajectories: TensorDictBase, valid: torch.Tensor) -> TensorDictBase:
            """What PPO needs for relabelled trajectories: a behaviour log-prob and GAE (docs/policy_reuse.md)."""
            return relabelled_ppo_targets(trajectories, valid, critic=trainer.critic, advantage=replay_advantage,
                                          actor=actor)

        self.transform = PolicyReuseTransform(
            baseline_actor=self.baseline_actor, env=trainer.env,
            initial_selection_factor=method.initial_selection_factor, selection_decay=method.selection_decay,
            candidate_stride=method.candidate_stride, max_candidates=method.max_candidates, keep=method.keep,
            ppo_targets=ppo_targets, max_rows=self.storage_rows(trainer.frames_per_batch), seed=trainer.cfg.seed,
            relabel_unfinished=method.relabel_unfinished, relabel_own_successes=method.relabel_own_successes,
            baseline_observation=self.baseline_observation,
        )
        return self.transform

    def buffer_rows(self, rows: TensorDictBase, update_fields: list) -> TensorDictBase:
        return rows  # the transform re-simulates episodes from their full state

    def max_updates(self, frames_per_batch: int, epochs: int, minibatch_size: int) -> int | None:
        """``method.equal_update_cost``: the minibatches of a plain iteration, however many rows were stored."""
        return epochs * math.ceil(frames_per_batch / minibatch_size) if self.config.equal_update_cost else None

    def iteration_metrics(self, trainer: Trainer, fill_seconds: float) -> dict[str, float]:
        return {**self.transform.last_statistics(), "time/reuse_seconds": fill_seconds,
                **clip_fraction_by_source(trainer.actor, trainer.buffer[:], trainer.cfg.ppo.clip_epsilon)}

    def state_dict(self) -> dict:
        return self.transform.state_dict()

    def load_state_dict(self, state: dict) -> None:
        self.transform.load_state_dict(state)
