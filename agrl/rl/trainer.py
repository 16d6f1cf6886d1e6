"""PPO training loop: Collector -> GAE -> replay buffer (with the optional reuse transform) -> ClipPPOLoss.

Modelled on TorchRL's own PPO script (``sota-implementations/ppo``), plus what a
long experiment needs: periodic evaluation, TensorBoard dashboards, atomic
checkpoints with exact resume, a Ctrl-C that saves, and a guard on non-finite losses.
"""

from __future__ import annotations

import copy
import csv
import json
import logging
import math
import random
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
import tqdm
from omegaconf import OmegaConf
from tensordict import TensorDictBase
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement
from torchrl.objectives import ClipPPOLoss
from torchrl.objectives.value import GAE
from torchrl.record.loggers import TensorboardLogger

from agrl.config import TrainConfig, task_label, to_guidance_parameters
from agrl.core.initial_states import scale_distribution
from agrl.core.termination import Outcome
from agrl.envs.guidance import REWARD_PART_KEYS, GuidanceEnv
from agrl.plots import plot_trajectories
from agrl.rl.checkpoint import (
    CheckpointError,
    load_checkpoint,
    load_module_state,
    resolve_checkpoint_path,
    save_checkpoint,
)
from agrl.rl.evaluation import instruction_latency_ms, run_episodes, summarise
from agrl.rl.models import make_actor, make_critic
from agrl.rl.reuse import PolicyReuseTransform, relabelled_ppo_targets

log = logging.getLogger("agrl.train")


class TrainingDiverged(RuntimeError):
    """A loss became NaN or infinite; the last good checkpoint is kept."""


@dataclass
class Counters:
    iteration: int = 0
    frames: int = 0
    wall_time: float = 0.0  # seconds of training, summed over resumed sessions
    best_success: float = -1.0
    curriculum_scale: float = 1.0  # fraction of the start box used for training episodes


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


class Trainer:
    """One training run in ``run_dir`` (a Hydra run directory)."""

    def __init__(self, cfg: TrainConfig, run_dir: Path, resume_payload: dict | None = None):
        self.cfg = cfg
        self.run_dir = Path(run_dir)
        self.checkpoint_dir = self.run_dir / "checkpoints"
        self.device = torch.device(cfg.device)
        ppo = cfg.ppo
        self.frames_per_batch = ppo.num_envs * ppo.steps_per_env
        torch.manual_seed(cfg.seed)
        random.seed(cfg.seed)
        np.random.seed(cfg.seed)

        self.params = to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation)
        self.env = GuidanceEnv(self.params, num_envs=ppo.num_envs, device=self.device, seed=cfg.seed)
        self.eval_env = GuidanceEnv(
            self.params, num_envs=cfg.eval.periodic_episodes, device=self.device, seed=self.eval_seed
        )
        self.actor = make_actor(cfg.agent.actor_hidden, cfg.agent.activation, self.device)
        self.critic = make_critic(cfg.agent.critic_hidden, cfg.agent.activation, self.device)
        self.baseline_actor = None
        if cfg.method.name in ("pretrained", "reuse"):
            self._load_baseline(cfg.method.baseline)

        self.advantage = GAE(
            gamma=cfg.reward.gamma, lmbda=ppo.gae_lambda, value_network=self.critic, average_gae=False,
            device=self.device,
        )
        # For re-played trajectories the critic's values are computed on their valid rows only (agrl.rl.reuse).
        self.replay_advantage = GAE(gamma=cfg.reward.gamma, lmbda=ppo.gae_lambda, value_network=None,
                                    average_gae=False, device=self.device)
        self.loss = ClipPPOLoss(
            self.actor, self.critic, clip_epsilon=ppo.clip_epsilon, entropy_coeff=ppo.entropy_coeff,
            critic_coeff=ppo.critic_coeff, normalize_advantage=True, loss_critic_type="smooth_l1",
        )
        self.optimizer = torch.optim.Adam(self.loss.parameters(), lr=ppo.learning_rate, eps=1e-5)
        self.reuse = self._make_reuse_transform() if cfg.method.name == "reuse" else None
        self.buffer = TensorDictReplayBuffer(
            storage=LazyTensorStorage(self._storage_size(), device=self.device),
            sampler=SamplerWithoutReplacement(),
            batch_size=ppo.minibatch_size,
            transform=self.reuse,
        )
        self.counters = Counters()
        if cfg.curriculum.enabled and cfg.method.use_curriculum:
            self.counters.curriculum_scale = cfg.curriculum.initial_scale
        if resume_payload is not None:
            self._restore(resume_payload)
        self._apply_curriculum()
        self.collector = Collector(
            self.env, self.actor, frames_per_batch=self.frames_per_batch, total_frames=-1,
            device=self.device, auto_register_policy_transforms=False,
        )
        if resume_payload is not None:
            # Building the collector may run the policy once: restore the RNGs afterwards.
            self._restore_rng(resume_payload["rng"])
        self.logger = TensorboardLogger(exp_name="tensorboard", log_dir=str(self.run_dir))
        self._snapshot: dict | None = None
        self._metrics_file = self.run_dir / "metrics.csv"

    # ------------------------------------------------------------------ setup helpers
    @property
    def eval_seed(self) -> int:
        return self.cfg.seed + 1_000_003  # a fixed evaluation set, disjoint from the training stream

    def _storage_size(self) -> int:
        # Relabelled episodes may be longer than the rows they replace (bounded in agrl.rl.reuse).
        return self.frames_per_batch * (3 if self.cfg.method.name == "reuse" else 1)

    def _load_baseline(self, reference: str) -> None:
        path = resolve_checkpoint_path(reference)
        payload = load_checkpoint(path, required=("actor", "critic"))
        if self.cfg.method.name == "pretrained" or self.cfg.method.start_from_baseline:
            load_module_state(self.actor, payload["actor"], path, "actor")
            load_module_state(self.critic, payload["critic"], path, "critic")
        baseline_cfg = payload.get("config", {}).get("agent", {})
        actor = make_actor(
            baseline_cfg.get("actor_hidden", self.cfg.agent.actor_hidden),
            baseline_cfg.get("activation", self.cfg.agent.activation), self.device,
        )
        load_module_state(actor, payload["actor"], path, "baseline actor")
        self.baseline_actor = actor.eval().requires_grad_(False)
        self.baseline_path = path

    def _make_reuse_transform(self) -> PolicyReuseTransform:
        method = self.cfg.method
        return PolicyReuseTransform(
            baseline_actor=self.baseline_actor,
            env=self.env,
            initial_selection_factor=method.initial_selection_factor,
            selection_decay=method.selection_decay,
            candidate_stride=method.candidate_stride,
            max_candidates=method.max_candidates,
            keep=method.keep,
            ppo_targets=self._ppo_targets,
            max_rows=self._storage_size(),
            seed=self.cfg.seed,
        )

    def _ppo_targets(self, trajectories: TensorDictBase, valid: torch.Tensor) -> TensorDictBase:
        """What PPO needs for relabelled trajectories: a behaviour log-prob and GAE (see docs/policy_reuse.md)."""
        actor = self.actor if self.cfg.method.behaviour_log_prob == "current" else None
        return relabelled_ppo_targets(trajectories, valid, critic=self.critic, advantage=self.replay_advantage,
                                      actor=actor)

    def _apply_curriculum(self) -> None:
        scale = min(1.0, self.counters.curriculum_scale)
        start = tuple(self.params.destination.start[:3])
        distribution = scale_distribution(self.params.initial_state, scale, start,
                                          success_distance=self.params.simulation.tolerance.distance)
        self.env.set_initial_state_distribution(distribution)

    def _advance_curriculum(self, metrics: dict[str, float]) -> None:
        scale = self.counters.curriculum_scale
        if scale < 1.0 and metrics.get("train/success_rate", 0.0) >= self.cfg.curriculum.promotion_success:
            self.counters.curriculum_scale = min(1.0, round(scale + self.cfg.curriculum.scale_step, 6))
            self._apply_curriculum()
            log.info("curriculum: training starts now use %.0f %% of the start box",
                     100 * self.counters.curriculum_scale)
        metrics["train/curriculum_scale"] = self.counters.curriculum_scale

    # ------------------------------------------------------------------ checkpoints
    def _state(self) -> dict[str, Any]:
        return {
            "actor": copy.deepcopy(self.actor.state_dict()),
            "critic": copy.deepcopy(self.critic.state_dict()),
            "optimizer": copy.deepcopy(self.optimizer.state_dict()),
            "counters": vars(self.counters).copy(),
            # The rows the collector carries into its next step (torchrl 0.14's Collector
            # keeps them in ``_carrier``); restored through the env on resume.
            "carrier": self.collector._carrier.exclude("collector").clone().cpu(),
            "reuse": self.reuse.state_dict() if self.reuse is not None else None,
            "rng": {
                "torch": torch.get_rng_state(),
                "cuda": torch.cuda.get_rng_state_all() if torch.cuda.is_available() else None,
                "env": self.env._generator.get_state(),
                "python": random.getstate(),
                "numpy": np.random.get_state(),
            },
            "config": OmegaConf.to_container(OmegaConf.structured(self.cfg), resolve=True),
            "config_yaml": OmegaConf.to_yaml(OmegaConf.structured(self.cfg), resolve=True),
            "run_dir": str(self.run_dir),
        }

    def _restore(self, payload: dict[str, Any]) -> None:
        path = Path(payload.get("_path", "checkpoint"))
        load_module_state(self.actor, payload["actor"], path, "actor")
        load_module_state(self.critic, payload["critic"], path, "critic")
        self.optimizer.load_state_dict(payload["optimizer"])
        self.counters = Counters(**payload["counters"])
        carrier = payload["carrier"]
        if tuple(carrier.batch_size) != tuple(self.env.batch_size):
            raise CheckpointError(
                f"{path}: checkpoint has {carrier.batch_size[0]} environments, this run has {self.env.batch_size[0]}"
            )
        self.env.restore_on_next_reset(carrier)
        if self.reuse is not None and payload.get("reuse") is not None:
            self.reuse.load_state_dict(payload["reuse"])

    def _restore_rng(self, rng: dict[str, Any]) -> None:
        torch.set_rng_state(rng["torch"])
        if rng.get("cuda") is not None and torch.cuda.is_available():
            torch.cuda.set_rng_state_all(rng["cuda"])
        self.env._generator.set_state(rng["env"])
        random.setstate(rng["python"])
        np.random.set_state(rng["numpy"])

    def save(self, name: str, state: dict[str, Any] | None = None) -> Path:
        return save_checkpoint(state or self._state(), self.checkpoint_dir / f"{name}.pt")

    # ------------------------------------------------------------------ training
    def _update(self) -> dict[str, float]:
        """PPO epochs over the buffer; returns mean loss terms."""
        totals: dict[str, float] = {}
        updates = 0
        for _ in range(self.cfg.ppo.epochs):
            for batch in self.buffer:
                losses = self.loss(batch)
                total = losses["loss_objective"] + losses["loss_critic"] + losses["loss_entropy"]
                if not torch.isfinite(total):
                    raise TrainingDiverged(
                        f"non-finite loss ({total.item()}) at iteration {self.counters.iteration + 1}, "
                        f"update {updates + 1}; last good checkpoint kept in {self.checkpoint_dir}"
                    )
                self.optimizer.zero_grad(set_to_none=True)
                total.backward()
                gradient_norm = torch.nn.utils.clip_grad_norm_(self.loss.parameters(), self.cfg.ppo.max_grad_norm)
                if not torch.isfinite(gradient_norm):
                    raise TrainingDiverged(
                        f"non-finite gradient at iteration {self.counters.iteration + 1}, update {updates + 1}; "
                        f"last good checkpoint kept in {self.checkpoint_dir}"
                    )
                self.optimizer.step()
                updates += 1
                for key in ("loss_objective", "loss_critic", "loss_entropy", "entropy", "kl_approx",
                            "clip_fraction", "explained_variance"):
                    if key in losses.keys():
                        totals[key] = totals.get(key, 0.0) + float(losses[key].detach().float().mean())
        return {key: value / max(updates, 1) for key, value in totals.items()}

    @torch.no_grad()
    def _clip_fraction_by_source(self) -> dict[str, float]:
        """Fraction of rows whose probability ratio is outside the clip range, per data source."""
        data = self.buffer[:]
        if "relabelled" not in data.keys():
            return {}
        ratio = (self.actor.get_dist(data).log_prob(data["action"]) - data["action_log_prob"]).exp()
        clipped = (ratio - 1).abs() > self.cfg.ppo.clip_epsilon
        relabelled = data["relabelled"]
        result = {}
        for name, mask in (("own", ~relabelled), ("relabelled", relabelled)):
            if bool(mask.any()):
                result[f"loss/clip_fraction_{name}"] = float(clipped[mask].float().mean())
        return result

    @staticmethod
    def episode_statistics(data: TensorDictBase) -> dict[str, float]:
        """Outcome rates and per-episode means over the episodes that ended in ``data``.

        The reward's parts (``train/reward_*``, keys of :data:`REWARD_PART_KEYS`) are means per decision over
        every transition of the iteration, so they add up to ``train/reward_per_decision``, the mean of what PPO
        was trained on (finished or not).
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

    def evaluate(self, episodes: int | None = None, record_trajectories: bool = False) -> tuple[dict[str, Any], Any]:
        env = self.eval_env
        if episodes is not None and episodes != env.batch_size[0]:
            env = GuidanceEnv(self.params, num_envs=episodes, device=self.device, seed=self.eval_seed)
        env.set_seed(self.eval_seed)  # the same evaluation episodes every time
        records = run_episodes(env, self.actor, record_trajectories=record_trajectories)
        return summarise(records), records

    def _finished(self, wall_time: float) -> str | None:
        ppo = self.cfg.ppo
        if self.counters.frames >= ppo.total_frames:
            return f"reached ppo.total_frames={ppo.total_frames}"
        if ppo.max_minutes and wall_time >= 60 * ppo.max_minutes:
            return f"reached ppo.max_minutes={ppo.max_minutes}"
        return None

    def train(self) -> dict[str, Any]:
        """Run until the frame or time budget (or the target success) is reached; return the final evaluation."""
        cfg = self.cfg
        self.run_dir.mkdir(parents=True, exist_ok=True)
        if self.counters.iteration == 0:
            self.logger.log_hparams(flatten_config(OmegaConf.to_container(OmegaConf.structured(cfg), resolve=True)))
        show_progress = cfg.progress and sys.stderr.isatty()
        bar = tqdm.tqdm(total=cfg.ppo.total_frames, initial=self.counters.frames, unit="dec", disable=not show_progress,
                        dynamic_ncols=True)
        start = time.perf_counter()
        wall_offset = self.counters.wall_time
        self._snapshot = self._state()
        if self.counters.iteration == 0 and cfg.eval.interval:
            # Where the run starts from (for pretrained and reuse: the baseline's zero-shot success on this task).
            evaluation, _ = self.evaluate()
            self._log({"eval/success_rate": evaluation["success_rate"],
                       "eval/instructions_per_episode": evaluation["instructions_per_episode"]})
        reason = self._finished(wall_offset)
        try:
            iterator = iter(self.collector)
            while reason is None:
                iteration_start = time.perf_counter()
                data = next(iterator)
                collect_time = time.perf_counter() - iteration_start
                with torch.no_grad():
                    data = self.advantage(data)
                self.buffer.empty()
                reuse_start = time.perf_counter()
                self.buffer.extend(data.reshape(-1))
                reuse_time = time.perf_counter() - reuse_start
                losses = self._update()
                self.counters.iteration += 1
                self.counters.frames += data.numel()
                self.counters.wall_time = wall_offset + time.perf_counter() - start
                metrics = {**self.episode_statistics(data), **{f"loss/{k}": v for k, v in losses.items()}}
                metrics.update(self._clip_fraction_by_source())
                self._advance_curriculum(metrics)
                if self.reuse is not None:
                    metrics.update(self.reuse.last_statistics())
                    metrics["time/reuse_seconds"] = reuse_time
                iteration_time = time.perf_counter() - iteration_start
                metrics.update({
                    "time/decisions_per_second": data.numel() / iteration_time,
                    "time/collection_decisions_per_second": data.numel() / max(collect_time, 1e-9),
                    "time/iteration_seconds": iteration_time,
                    "time/wall_time": self.counters.wall_time,
                    "train/iteration": self.counters.iteration,
                })
                evaluation = None
                if cfg.eval.interval and self.counters.iteration % cfg.eval.interval == 0:
                    evaluation, _ = self.evaluate()
                    metrics.update({
                        "eval/success_rate": evaluation["success_rate"],
                        "eval/instructions_per_episode": evaluation["instructions_per_episode"],
                        "eval/decisions_per_episode": evaluation["decisions_per_episode"],
                        "eval/mean_return": evaluation["mean_return"],
                    })
                self._snapshot = self._state()
                self._log(metrics)
                if evaluation is not None and evaluation["success_rate"] > self.counters.best_success:
                    self.counters.best_success = evaluation["success_rate"]
                    self._snapshot = self._state()
                    self.save("best", self._snapshot)
                if self.counters.iteration % cfg.checkpoint_interval == 0:
                    self.save("latest", self._snapshot)
                bar.update(data.numel())
                bar.set_postfix(success=f"{metrics.get('train/success_rate', float('nan')):.3f}",
                                dps=f"{metrics['time/decisions_per_second']:.0f}")
                if not show_progress and (evaluation is not None or self.counters.iteration == 1):
                    log.info(self._progress_line(metrics))
                reason = self._finished(self.counters.wall_time)
                if evaluation is not None and cfg.target_success and evaluation["success_rate"] >= cfg.target_success:
                    reason = f"periodic evaluation reached target_success={cfg.target_success}"
        except KeyboardInterrupt:
            bar.close()
            path = self.save("latest", self._snapshot)
            log.warning("interrupted: saved the last completed iteration to %s (resume with resume=%s)",
                        path, self.run_dir)
            raise
        finally:
            bar.close()
            self.collector.shutdown()
        self.save("latest", self._snapshot)
        log.info("training stopped: %s", reason)
        return self.final_evaluation()

    def _progress_line(self, metrics: dict[str, float]) -> str:
        parts = [f"iter {self.counters.iteration}", f"decisions {self.counters.frames}",
                 f"wall {self.counters.wall_time:.0f}s",
                 f"train success {metrics.get('train/success_rate', float('nan')):.3f}"]
        if "eval/success_rate" in metrics:
            parts.append(f"eval success {metrics['eval/success_rate']:.3f}")
        parts.append(f"{metrics['time/decisions_per_second']:.0f} dec/s")
        return " | ".join(parts)

    def _log(self, metrics: dict[str, float]) -> None:
        for key, value in metrics.items():
            if isinstance(value, int | float) and math.isfinite(value):
                self.logger.log_scalar(key, value, step=self.counters.frames)
        row = {"iteration": self.counters.iteration, "frames": self.counters.frames,
               "wall_time": round(self.counters.wall_time, 3)}
        for key in ("train/success_rate", "eval/success_rate", "train/instructions_per_episode",
                    "train/reuse_fraction", "train/e"):
            row[key] = metrics.get(key, "")
        new_file = not self._metrics_file.exists()
        with self._metrics_file.open("a", newline="") as file:
            writer = csv.DictWriter(file, fieldnames=list(row))
            if new_file:
                writer.writeheader()
            writer.writerow(row)

    def final_evaluation(self) -> dict[str, Any]:
        """The paper's evaluation (``eval.episodes`` deterministic episodes) -> ``eval/eval.json``."""
        summary, records = self.evaluate(self.cfg.eval.episodes, record_trajectories=True)
        summary["ms_per_instruction"] = instruction_latency_ms(self.eval_env, self.actor)
        summary.update({
            "task": self.cfg.task.name, "method": self.cfg.method.name, "reward": self.cfg.reward.name,
            "seed": self.cfg.seed, "evaluation_seed": self.eval_seed, "iterations": self.counters.iteration,
            "decisions_trained": self.counters.frames, "training_wall_time_s": round(self.counters.wall_time, 1),
        })
        write_evaluation(self.run_dir / "eval", summary, records)
        plot_trajectories(records, self.run_dir / "eval" / "trajectories.png", self.params.simulation.airspace,
                          title=f"{task_label(self.cfg.task)}, {self.cfg.method.name}: 10 evaluation episodes")
        return summary


def write_evaluation(directory: Path, summary: dict[str, Any], records) -> None:
    """``eval.json`` (summary) and ``episodes.csv`` (one row per episode)."""
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "eval.json").write_text(json.dumps(summary, indent=2) + "\n")
    with (directory / "episodes.csv").open("w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["episode", "x0_m", "y0_m", "z0_m", "outcome", "decisions", "instructions", "return",
                         "final_distance_m"])
        for index in range(records.outcome.numel()):
            x0, y0, z0 = records.initial_aircraft_state[index, :3].tolist()
            writer.writerow([index, round(x0, 1), round(y0, 1), round(z0, 1),
                             Outcome(int(records.outcome[index])).name.lower(), int(records.decisions[index]),
                             int(records.instructions[index]), round(float(records.episode_return[index]), 4),
                             round(float(records.final_distance[index]), 1)])
