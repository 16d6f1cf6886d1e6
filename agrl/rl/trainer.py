"""PPO training: Collector -> GAE -> replay buffer (with the method's transform, if any) -> ClipPPOLoss.

Laid out like TorchRL's own PPO script (``sota-implementations/ppo``): setup in small
named steps, then one loop. The training method (scratch, pretrained, policy reuse, or
one registered from outside) plugs in through the hooks of :class:`agrl.rl.methods.Method`;
the trainer names none. What a long experiment needs beyond it lives beside:
the PPO update (:mod:`agrl.rl.ppo`), the curriculum (:mod:`agrl.rl.curriculum`),
metrics and dashboards (:mod:`agrl.rl.metrics`), exact-resume state
(:mod:`agrl.rl.run_state`), checkpoint files (:mod:`agrl.rl.checkpoint`) and the
paper's evaluation (:mod:`agrl.rl.evaluation`).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import json
import logging
import sys
import time
from pathlib import Path
from typing import Any

import torch
import tqdm
from omegaconf import OmegaConf
from tensordict import TensorDictBase
from torchrl.collectors import Collector, MultiSyncCollector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer

from agrl.config import TrainConfig, method_class, task_label, to_guidance_parameters
from agrl.envs.guidance import GuidanceEnv
from agrl.machine import processor_record
from agrl.plots import DRAWN_EPISODES, plot_trajectories, trajectory_image
from agrl.rl.checkpoint import CheckpointError, kept_checkpoint, load_module_state, save_checkpoint
from agrl.rl.curriculum import SharedScaleGuidanceEnv, promoted_scale, shared_scale, start_distribution
from agrl.rl.evaluation import instruction_latency_ms, run_episodes, search_objective, summarise, write_evaluation
from agrl.rl.metrics import MetricsLog, episode_statistics, progress_line
from agrl.rl.models import CategoricalSampler, make_agent
from agrl.rl.ppo import (
    CompiledLoss,
    TrainingDiverged,
    annealed_learning_rate,
    make_advantage,
    make_loss,
    make_optimizer,
    ppo_update,
    update_fields,
)
from agrl.rl.run_state import (
    Counters,
    carried_rows,
    carried_rows_from_checkpoint,
    restore_rng_states,
    rng_states,
    seed_everything,
)
from agrl.rl.stop_signals import PREEMPTED_MARKER, Preempted, StopSignals
from agrl.rl.stopping import budget_spent, target_reached

__all__ = ["Counters", "Trainer", "TrainingDiverged"]

log = logging.getLogger("agrl.train")


class Trainer:
    """One training run in ``run_dir`` (a Hydra run directory)."""

    def __init__(self, cfg: TrainConfig, run_dir: Path, resume_payload: dict | None = None):
        self.cfg = cfg
        self.run_dir = Path(run_dir)
        self.checkpoint_dir = self.run_dir / "checkpoints"
        self._latest_saved_iteration: int | None = None  # see save()
        self.device = torch.device(cfg.device)
        self.frames_per_batch = cfg.ppo.num_envs * cfg.ppo.steps_per_env
        if cfg.threads is not None:
            torch.set_num_threads(cfg.threads)
        seed_everything(cfg.seed)

        self.params = to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, actions=cfg.actions)
        self.env, self.eval_env = self._make_envs()
        self.method = method_class(cfg.method.name)(cfg.method)  # an agrl.rl.methods.Method
        # Z's networks (pretrained: B's), which checkpoints record; in a copy, so the caller's config stays as given.
        self.cfg = cfg = dataclasses.replace(cfg, agent=self.method.agent_config(cfg))
        self.actor, self.critic = make_agent(cfg.agent, self.params, self.device)
        self.method.start(self)
        self._make_ppo()
        self.buffer = self._make_buffer()
        self.counters = self._initial_counters()
        if resume_payload is not None:
            self._restore(resume_payload)
        self.env.set_initial_state_distribution(start_distribution(self.params, self.counters.curriculum_scale))
        # The workers' envs (ppo.collector_workers > 1) read the curriculum scale from here (agrl.rl.curriculum).
        self.worker_scale = shared_scale(self.counters.curriculum_scale) if cfg.ppo.collector_workers > 1 else None
        self.collector = self._make_collector()
        if resume_payload is not None:
            restore_rng_states(self.env, resume_payload["rng"])  # building the collector may run the policy
        self.metrics = MetricsLog(self.run_dir)
        self._snapshot: dict | None = None

    # ------------------------------------------------------------------ setup steps
    @property
    def eval_seed(self) -> int:
        return self.cfg.seed + 1_000_003  # a fixed evaluation set, disjoint from the training stream

    @property
    def confirm_seed(self) -> int:
        return self.cfg.seed + 2_000_003  # the stop's confirmation set, another fixed set

    def _make_envs(self) -> tuple[GuidanceEnv, GuidanceEnv]:
        observation = self.cfg.agent.observation
        train = GuidanceEnv(self.params, num_envs=self.cfg.ppo.num_envs, device=self.device, seed=self.cfg.seed,
                            observation=observation)
        periodic = GuidanceEnv(self.params, num_envs=self.cfg.eval.periodic_episodes, device=self.device,
                               seed=self.eval_seed, observation=observation)
        return train, periodic

    def _make_collector(self) -> Collector | MultiSyncCollector:
        """The actor collects as a :class:`CategoricalSampler`; one Collector numbers episodes if the method reads them.
        ``ppo.collector_workers=1``: one Collector stepping ``self.env`` here (exact resume carries its rows).
        N > 1: TorchRL's MultiSyncCollector, N processes of ``num_envs / N`` envs each, batches concatenated along
        the env dimension; the actor's weights and the curriculum's scale (``self.worker_scale``, shared memory)
        go to the workers before each batch. The config keeps N > 1 from what needs ``self.env`` to collect
        (resume, policy reuse, finetune)."""
        workers, policy, ids = self.cfg.ppo.collector_workers, CategoricalSampler(self.actor), self.method.episode_ids
        if workers == 1:
            return Collector(self.env, policy, frames_per_batch=self.frames_per_batch, total_frames=-1,
                             device=self.device, auto_register_policy_transforms=False, track_traj_ids=ids)
        per_worker = self.cfg.ppo.num_envs // workers
        make_envs = [functools.partial(SharedScaleGuidanceEnv, self.params, num_envs=per_worker, device=self.device,
                                       seed=None, observation=self.cfg.agent.observation)  # seeded below
                     for _ in range(workers)]
        # The scale goes as an env kwarg: TorchRL cloudpickles the env factory (a copy of any tensor in it) but
        # hands create_env_kwargs to the process itself, which torch.multiprocessing pickles as shared storage.
        collector = MultiSyncCollector(
            make_envs, policy, create_env_kwargs=[{"scale": self.worker_scale}] * workers,
            frames_per_batch=self.frames_per_batch, total_frames=-1, device=self.device, cat_results=0,
            update_at_each_batch=True, use_buffers=True,
            num_threads=torch.get_num_threads(),  # this process's threads: the PPO update
            auto_register_policy_transforms=False)
        # Each worker's env generator (distinct seeds from `seed`) and its torch generator, which samples the
        # actor's actions there: without it a worker run is not reproducible.
        collector.set_seed(self.cfg.seed)
        return collector

    def _make_ppo(self) -> None:
        ppo, gamma = self.cfg.ppo, self.cfg.reward.gamma
        self.advantage = make_advantage(gamma, ppo.gae_lambda, self.critic, self.device)
        self.loss = make_loss(self.actor, self.critic, ppo.clip_epsilon, ppo.entropy_coeff, ppo.critic_coeff,
                              ppo.compiled_entropy_draw)
        self.optimizer = make_optimizer(self.loss, ppo.learning_rate)
        self.update_loss = CompiledLoss(self.loss) if ppo.compile_loss else self.loss  # what the update calls

    def _make_buffer(self) -> TensorDictReplayBuffer:
        """The rows of one update, through the method's transform (policy reuse rewrites and adds rows there); the
        update reads them all at once and slices its minibatches itself (agrl.rl.ppo.minibatches)."""
        storage = LazyTensorStorage(self.method.storage_rows(self.frames_per_batch), device=self.device)
        return TensorDictReplayBuffer(storage=storage, transform=self.method.buffer_transform(self))

    def _initial_counters(self) -> Counters:
        curriculum = self.cfg.curriculum
        on = curriculum.enabled and self.cfg.method.use_curriculum
        return Counters(curriculum_scale=curriculum.initial_scale if on else 1.0)

    # ------------------------------------------------------------------ checkpoints
    @functools.cached_property
    def _config_record(self) -> dict[str, Any]:
        """The resolved config and the processor path, as checkpoints keep them; built once (neither changes during a
        run, and building them costs about as much as the rest of a snapshot, which every iteration takes)."""
        config = OmegaConf.structured(self.cfg)
        return {"config": OmegaConf.to_container(config, resolve=True),
                "config_yaml": OmegaConf.to_yaml(config, resolve=True), "machine": processor_record()}

    def _state(self) -> dict[str, Any]:
        """Everything exact resume needs, as tensors and plain data (the file loads with weights_only=True)."""
        return {
            "actor": copy.deepcopy(self.actor.state_dict()),
            "critic": copy.deepcopy(self.critic.state_dict()),
            "optimizer": copy.deepcopy(self.optimizer.state_dict()),
            "counters": vars(self.counters).copy(),
            "carrier": carried_rows(self.collector) if isinstance(self.collector, Collector) else None,
            "method_state": self.method.state_dict(),
            "rng": rng_states(self.env),
            **self._config_record,
            "run_dir": str(self.run_dir),
        }

    def _restore(self, payload: dict[str, Any]) -> None:
        path = Path(payload.get("_path", "checkpoint"))
        load_module_state(self.actor, payload["actor"], path, "actor")
        load_module_state(self.critic, payload["critic"], path, "critic")
        self.optimizer.load_state_dict(payload["optimizer"])
        self.counters = Counters(**payload["counters"])
        carrier = carried_rows_from_checkpoint(payload["carrier"])
        if tuple(carrier.batch_size) != tuple(self.env.batch_size):
            raise CheckpointError(
                f"{path}: checkpoint has {carrier.batch_size[0]} environments, this run has {self.env.batch_size[0]}"
            )
        self.env.restore_on_next_reset(carrier)
        state = payload.get("method_state", payload.get("reuse"))  # "reuse": checkpoints written before methods
        if state is not None:
            self.method.load_state_dict(state)
        if self.counters.finetune_from:
            self._set_switch_cost(self.cfg.finetune.switch_cost)

    def save(self, name: str, state: dict[str, Any] | None = None) -> Path:
        """Write checkpoint ``name``; ``latest`` keeps the one it replaces (``latest.previous.pt``), which a
        resume reads if ``latest.pt`` was damaged after it was written."""
        state = state or self._state()
        path = self.checkpoint_dir / f"{name}.pt"
        if name == "latest":
            # The same iteration again (the end of a run whose last iteration was saved already) would make the
            # kept previous checkpoint a copy of this one.
            if state["counters"]["iteration"] == self._latest_saved_iteration and path.is_file():
                return path
            self._latest_saved_iteration = state["counters"]["iteration"]
        return save_checkpoint(state, path, keep_previous=name == "latest")

    # ------------------------------------------------------------------ one iteration's parts
    def _advance_curriculum(self, metrics: dict[str, float]) -> None:
        curriculum = self.cfg.curriculum
        scale = promoted_scale(self.counters.curriculum_scale, metrics.get("train/success_rate"),
                               curriculum.scale_step, curriculum.promotion_success)
        if scale != self.counters.curriculum_scale:
            self.counters.curriculum_scale = scale
            self.env.set_initial_state_distribution(start_distribution(self.params, scale))
            if self.worker_scale is not None:
                self.worker_scale.fill_(scale)  # the workers' next resets: collection waits for the next batch
            log.info("curriculum: training starts now use %.0f %% of the start box", 100 * scale)
        metrics["train/curriculum_scale"] = self.counters.curriculum_scale

    def _set_learning_rate(self) -> float:
        ppo, finetune = self.cfg.ppo, self.cfg.finetune
        rate = finetune.learning_rate if self.counters.finetune_from and finetune.learning_rate else ppo.learning_rate
        if ppo.anneal_lr:  # the rate in force (the fine-tune's, once it has begun), decayed with the frame budget
            rate = annealed_learning_rate(rate, self.counters.frames, ppo.total_frames)
        for group in self.optimizer.param_groups:
            group["lr"] = rate
        return rate

    def learn(self, data: TensorDictBase) -> tuple[TensorDictBase, dict[str, float], float]:
        """One PPO update from a collected batch: GAE, the replay buffer (through the method's transform, if it
        has one), then epochs of minibatches of its rows. Returns the batch with its advantages, the mean loss
        terms and the seconds spent filling the buffer (the relabelling, for policy reuse)."""
        with torch.no_grad():
            data = self.advantage(data)
        self.buffer.empty()
        fill_start = time.perf_counter()
        self.buffer.extend(self.method.buffer_rows(data.reshape(-1), update_fields(self.loss)))
        fill_time = time.perf_counter() - fill_start
        ppo = self.cfg.ppo
        max_updates = self.method.max_updates(self.frames_per_batch, ppo.epochs, ppo.minibatch_size)
        try:
            losses = ppo_update(self.update_loss, self.optimizer, self.buffer[:], ppo.minibatch_size, ppo.epochs,
                                ppo.max_grad_norm, where=f"at iteration {self.counters.iteration + 1}",
                                max_updates=max_updates, target_kl=ppo.target_kl)
        except TrainingDiverged as error:
            kept = kept_checkpoint(self.checkpoint_dir, self.cfg.checkpoint_interval)
            raise TrainingDiverged(f"{error}; {kept}") from None
        return data, losses, fill_time

    def _evaluation_due(self, metrics: dict[str, float]) -> bool:
        """Whether a periodic evaluation follows this iteration (``metrics``: its training statistics)."""
        schedule = self.cfg.eval
        if self.counters.finetune_from:
            return False  # they serve the stop, which has fired; the final evaluation reads the fine-tuned agent
        if schedule.min_train_success and not self._could_stop(metrics):
            return False  # the schedule resumes from here: no evaluation is owed for the skipped ones
        if schedule.interval_seconds:
            if self.counters.wall_time < self.counters.next_evaluation_time:
                return False
            while self.counters.next_evaluation_time <= self.counters.wall_time:
                self.counters.next_evaluation_time += schedule.interval_seconds
            return True
        return bool(schedule.interval) and self.counters.iteration % schedule.interval == 0

    def _could_stop(self, metrics: dict[str, float]) -> bool:
        """``eval.min_train_success``: the curriculum has reached the full start box and this iteration's training
        success is at that value or above (the iteration that reaches the full box counts with its own success)."""
        success = metrics.get("train/success_rate")
        return (self.counters.curriculum_scale >= 1.0 and success is not None
                and success >= self.cfg.eval.min_train_success)

    def evaluate(self, episodes: int | None = None, trajectories: int = 0,
                 seed: int | None = None) -> tuple[dict[str, Any], Any]:
        """``episodes`` deterministic episodes (default: the periodic set's size) drawn from ``seed`` (default:
        :attr:`eval_seed`): the same episodes at every call; the first ``trajectories`` keep their paths."""
        env = self.eval_env
        if episodes is not None and episodes != env.batch_size[0]:
            env = GuidanceEnv(self.params, num_envs=episodes, device=self.device, seed=self.eval_seed,
                              observation=self.cfg.agent.observation)
        env.set_seed(self.eval_seed if seed is None else seed)
        records = run_episodes(env, self.actor, trajectories=trajectories)
        return summarise(records), records

    def _periodic_evaluation(self) -> dict[str, float]:
        """The fixed periodic episode set; its first episodes' trajectories also go to the dashboard's Images."""
        picture = self.cfg.eval.trajectory_image
        evaluation, records = self.evaluate(trajectories=DRAWN_EPISODES if picture else 0)
        if picture:
            title = f"{task_label(self.cfg.task)}, {self.cfg.method.name}: {self.counters.frames:,} decisions trained"
            image = trajectory_image(records, self.params.simulation.airspace, title=title)
            self.metrics.log_image("eval/trajectories", image, self.counters.frames)
        return {f"eval/{key}": evaluation[key]
                for key in ("success_rate", "instructions_per_episode", "decisions_per_episode", "mean_return")}

    def _finished(self) -> str | None:
        return budget_spent(self.cfg, self.counters)  # a subclass may stop on its own rule (benchmarks/bench_race.py)

    # ------------------------------------------------------------------ the loop
    def train(self) -> dict[str, Any]:
        """Run until the frame or time budget (or the target success) is reached; return the final evaluation."""
        cfg = self.cfg
        self.run_dir.mkdir(parents=True, exist_ok=True)
        if self.counters.iteration == 0:
            self.metrics.log_hparams(OmegaConf.to_container(OmegaConf.structured(cfg), resolve=True))
            if cfg.eval.interval or cfg.eval.interval_seconds:
                # Where the run starts from (for pretrained and reuse: the baseline's zero-shot success on this task).
                self._log(self._periodic_evaluation())
        show_progress = cfg.progress and sys.stderr.isatty()
        bar = tqdm.tqdm(total=cfg.ppo.total_frames, initial=self.counters.frames, unit="dec", dynamic_ncols=True,
                        disable=not show_progress)
        start, wall_offset = time.perf_counter(), self.counters.wall_time
        self._snapshot = self._state()
        reason = self._finished()
        try:
            with StopSignals() as stop:
                reason = self._loop(bar, start, wall_offset, show_progress, reason, stop)
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

    def _loop(self, bar: tqdm.tqdm, start: float, wall_offset: float, show_progress: bool, reason: str | None,
              stop: StopSignals) -> str:
        """Iterate until ``reason`` says why to stop; a stop signal saves ``latest`` and raises
        :class:`Preempted` after the iteration it arrived in (the state is whole only between iterations)."""
        batches = iter(self.collector)
        while reason is None:
            iteration_start = time.perf_counter()
            data = next(batches)
            collect_time = time.perf_counter() - iteration_start
            learning_rate = self._set_learning_rate()
            data, losses, fill_time = self.learn(data)

            self.counters.iteration += 1
            self.counters.frames += data.numel()
            self.counters.wall_time = wall_offset + time.perf_counter() - start
            iteration_time = time.perf_counter() - iteration_start
            metrics = {**episode_statistics(data), **{f"loss/{k}": v for k, v in losses.items()},
                       "train/learning_rate": learning_rate, "train/iteration": self.counters.iteration,
                       "time/decisions_per_second": data.numel() / iteration_time,
                       "time/collection_decisions_per_second": data.numel() / max(collect_time, 1e-9),
                       "time/iteration_seconds": iteration_time, "time/wall_time": self.counters.wall_time}
            self._advance_curriculum(metrics)
            metrics.update(self.method.iteration_metrics(self, fill_time))
            if self._evaluation_due(metrics):
                metrics.update(self._periodic_evaluation())
                metrics.update(self._confirmation(metrics))
                reason = target_reached(self.cfg, metrics)
                if reason and self.cfg.finetune.iterations:  # before the snapshot: a resume finds the phase begun
                    self.counters.finetune_from = self.counters.iteration
                    self._set_switch_cost(self.cfg.finetune.switch_cost)
                    log.info("%s: fine-tuning for %d iterations at switch cost %s", reason,
                             self.cfg.finetune.iterations, self.cfg.finetune.switch_cost)
                    reason = None
            new_best = self._count_best(metrics)  # before the snapshot, which records the best success
            self._snapshot = self._state()
            self._log(metrics)
            self._checkpoint(new_best)
            bar.update(data.numel())
            bar.set_postfix(success=f"{metrics.get('train/success_rate', float('nan')):.3f}",
                            dps=f"{metrics['time/decisions_per_second']:.0f}")
            if not show_progress and ("eval/success_rate" in metrics or self.counters.iteration == 1):
                log.info(progress_line(self.counters.iteration, self.counters.frames, self.counters.wall_time,
                                       metrics))
            reason = self._finished() or reason
            if stop.received:
                path = self.save("latest", self._snapshot)
                (self.checkpoint_dir / PREEMPTED_MARKER).write_text(json.dumps(
                    {"signal": stop.received, "iteration": self.counters.iteration}))
                preempted = Preempted(stop.received, str(path), str(self.run_dir))
                log.warning("%s", preempted)
                stop.forward()  # under submitit: its requeue, which exits
                raise preempted
        return reason

    def _count_best(self, metrics: dict[str, float]) -> bool:
        """Whether this iteration's periodic evaluation is the best so far (``counters.best_success`` follows)."""
        success = metrics.get("eval/success_rate")
        if success is None or success <= self.counters.best_success:
            return False
        self.counters.best_success = success
        return True

    def _checkpoint(self, new_best: bool) -> None:
        """``best`` on a new best periodic evaluation, ``latest`` every ``checkpoint_interval`` iterations."""
        if new_best:
            self.save("best", self._snapshot)
        if self.counters.iteration % self.cfg.checkpoint_interval == 0:
            self.save("latest", self._snapshot)

    def _confirmation(self, metrics: dict[str, float]) -> dict[str, float]:
        """Once a periodic evaluation reaches ``target_success``, ``eval.confirm_episodes`` other episodes (a fixed
        set of their own) must reach it too before the run stops: a few hundred periodic episodes reach a target
        near 100 % by luck often enough that a run stopped on them alone scores below it on its final evaluation."""
        target, episodes = self.cfg.target_success, self.cfg.eval.confirm_episodes
        if not (target and episodes and metrics["eval/success_rate"] >= target):
            return {}
        summary, _ = self.evaluate(episodes, seed=self.confirm_seed)
        return {"eval/confirm_success_rate": summary["success_rate"]}

    def _set_switch_cost(self, switch_cost: float) -> None:
        """The training env's (and so the reuse relabelling's) price per instruction, and the evaluations'."""
        self.params = self.params.with_switch_cost(switch_cost)
        for env in (self.env, self.eval_env):
            env.set_switch_cost(switch_cost)

    def _log(self, metrics: dict[str, float]) -> None:
        # Every logged step carries its iteration and wall time (the initial evaluation's too): agrl.report's rows.
        where = {"train/iteration": self.counters.iteration, "time/wall_time": self.counters.wall_time}
        self.metrics.log({**where, **metrics}, self.counters.frames)

    def final_evaluation(self) -> dict[str, Any]:
        """The paper's evaluation (``eval.episodes`` deterministic episodes) -> ``eval/eval.json``."""
        summary, records = self.evaluate(self.cfg.eval.episodes, trajectories=DRAWN_EPISODES)
        summary["ms_per_instruction"] = instruction_latency_ms(self.eval_env, self.actor)
        summary.update({
            "task": self.cfg.task.name, "method": self.cfg.method.name, "reward": self.cfg.reward.name,
            "seed": self.cfg.seed, "evaluation_seed": self.eval_seed, "iterations": self.counters.iteration,
            "decisions_trained": self.counters.frames, "training_wall_time_s": round(self.counters.wall_time, 1),
            "machine": processor_record(),  # a run repeats bit for bit on the same processor path and threads only
        })
        search = self.cfg.search
        summary["search_objective"] = search_objective(summary, search.success, search.max_instructions,
                                                       search.penalty_seconds)
        write_evaluation(self.run_dir / "eval", summary, records)
        title = f"{task_label(self.cfg.task)}, {self.cfg.method.name}: {DRAWN_EPISODES} evaluation episodes"
        plot_trajectories(records, self.run_dir / "eval" / "trajectories.png", self.params.simulation.airspace,
                          title=title)
        return summary
