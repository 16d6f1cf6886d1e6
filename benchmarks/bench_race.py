"""``python -m benchmarks.bench_race``: stable-baselines3 PPO and agrl's trainer learn one task in the same wall time.

Each trainer trains for ``--budget-seconds`` of its own training clock, one after the other in this process
(``torch._dynamo.reset()`` in between, so each pays its own ``torch.compile``). The clock starts before the
trainer is built (env, networks, collector) and stops only while an evaluation runs: every
``--eval-every`` seconds of training, and once at the start and the end, the policy flies the SAME fixed
evaluation set, ``--eval-episodes`` deterministic (argmax) episodes of the task from the full start box
(:func:`agrl.rl.evaluation.run_episodes` on a :class:`agrl.envs.GuidanceEnv` reseeded to the same seed each time,
the machinery of agrl's periodic evaluation). stable-baselines3's policy flies it through a thin adapter
(``policy.predict(observation, deterministic=True)``), agrl's actor directly. A trainer stops at the end of
its budget, or (unless ``--full-budget``) once an evaluation reaches the last ``--targets`` success rate.

agrl's side is :class:`agrl.rl.trainer.Trainer`, the one ``python -m agrl.train`` runs, with the project's
defaults (``conf/``: curriculum on, 512 envs x 64 decisions, ...) plus ``--agrl-override`` Hydra overrides; only
its stopping rule and its periodic evaluation are the race's. stable-baselines3 (the ``bench`` extra) trains
``PPO("MlpPolicy", env)`` on ``--sb3-num-envs`` gym envs and, for ``--sb3-geometry sb3`` (the default), every
other setting at stable-baselines3's own PPO defaults (2048 steps per env per rollout,
minibatch 64, 10 epochs, learning rate 3e-4, gamma 0.99, GAE lambda 0.95, clip 0.2, no entropy bonus, value
coefficient 0.5, gradient norm 0.5, 64-64 tanh networks): what a user writes. The envs are
``make_vec_env("agrl/Guidance-v0", n_envs)`` (``--sb3-env single``: one Python-float env per row, the faster form
for a few rows) or the batched gym vector env (``--sb3-env vector``: :mod:`agrl.envs.gym_vector`, same-step
autoreset, through :func:`benchmarks.bench_peer.make_sb3_vector_env`; the default with ``--sb3-geometry agrl``).
``--sb3-geometry agrl`` takes
agrl's composed config instead (``ppo.num_envs`` rows, ``ppo.steps_per_env``, minibatch, epochs, learning
rate, reward gamma, GAE lambda, clip, entropy and value coefficients, gradient norm, network sizes and
activation), the geometry of ``python -m benchmarks.bench_peer``, with no curriculum.

Prints JSON lines: ``race_evaluation`` (one per evaluation), ``race_result`` per trainer (training seconds and
decisions to first reach each target, decisions/s, final and best success) and ``race_summary``
(stable-baselines3's seconds to each target over agrl's).

Example (the run in docs/benchmarks.md, "Not in `make bench`"; about 25 minutes on a quiet 2-core machine)::

    python -m benchmarks.bench_race --budget-seconds 1250 --eval-every 20 --threads 1
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks import torchrl_logs_to_stderr

TRAINERS = ("agrl", "stable-baselines3")
EVALUATION_SEED_OFFSET = 1_000_003  # as agrl's Trainer: an evaluation set disjoint from the training stream


class TrainingClock:
    """Seconds of training: runs from :meth:`start` and stands still inside :meth:`paused`."""

    def __init__(self):
        self._started: float | None = None
        self._paused_total = 0.0

    def start(self) -> None:
        self._started, self._paused_total = time.perf_counter(), 0.0

    @property
    def seconds(self) -> float:
        return time.perf_counter() - self._started - self._paused_total

    @contextlib.contextmanager
    def paused(self):
        begin = time.perf_counter()
        try:
            yield
        finally:
            self._paused_total += time.perf_counter() - begin


class Sb3Actor:
    """stable-baselines3's policy as a TensorDict actor for :func:`agrl.rl.evaluation.run_episodes`."""

    def __init__(self, model):
        self.model = model

    def __call__(self, td):
        import torch

        actions, _ = self.model.predict(td["observation"].cpu().numpy(), deterministic=True)
        td["action"] = torch.as_tensor(np.asarray(actions, dtype=np.int64), device=td.device).reshape(td.batch_size)
        return td


class RaceEvaluation:
    """The fixed evaluation set both trainers fly, and the log of each trainer's evaluations."""

    def __init__(self, params, episodes: int, seed: int, clock: TrainingClock, targets: Sequence[float],
                 emit: Callable[[dict], None]):
        from agrl.envs.guidance import GuidanceEnv

        self.env = GuidanceEnv(params, num_envs=episodes, device="cpu", seed=seed)
        self.seed, self.clock, self.targets, self.emit = seed, clock, tuple(targets), emit
        self.history: list[dict] = []

    def __call__(self, trainer: str, actor, decisions: int, final: bool = False) -> dict:
        """Fly the evaluation set (the training clock stands still meanwhile); one ``race_evaluation`` line."""
        from agrl.rl.evaluation import run_episodes, summarise

        training_seconds = self.clock.seconds  # before the pause: the evaluation's own time is not training
        with self.clock.paused():
            begin = time.perf_counter()
            self.env.set_seed(self.seed)  # the same episodes every time, for both trainers
            summary = summarise(run_episodes(self.env, actor))
            record = {"name": "race_evaluation", "trainer": trainer, "value": summary["success_rate"],
                      "unit": "success rate", "training_seconds": round(training_seconds, 2),
                      "decisions": int(decisions), "success_rate": summary["success_rate"],
                      "decisions_per_episode": summary["decisions_per_episode"],
                      "instructions_per_episode": summary["instructions_per_episode"], "final": final,
                      "evaluation_seconds": round(time.perf_counter() - begin, 2)}
        self.history.append(record)
        self.emit(record)
        return record

    def reached_last_target(self, trainer: str) -> bool:
        return any(r["trainer"] == trainer and r["success_rate"] >= self.targets[-1] for r in self.history)

    def result(self, trainer: str, settings: dict) -> dict:
        """``race_result``: when each target was first reached (None: not within the budget)."""
        rows = [r for r in self.history if r["trainer"] == trainer]
        final = rows[-1]
        record = {"name": "race_result", "trainer": trainer, "value": final["success_rate"], "unit": "success rate",
                  "final_success_rate": final["success_rate"],
                  "best_success_rate": max(r["success_rate"] for r in rows),
                  "training_seconds": final["training_seconds"], "decisions": final["decisions"],
                  # Four significant figures: a tiny race's few decisions a second keep their precision too.
                  "decisions_per_second": float(f'{final["decisions"] / max(final["training_seconds"], 1e-9):.4g}'),
                  "evaluations": len(rows)}
        for target in self.targets:
            first = next((r for r in rows if r["success_rate"] >= target), None)
            label = f"{round(100 * target, 2):g}"
            record[f"seconds_to_{label}"] = None if first is None else first["training_seconds"]
            record[f"decisions_to_{label}"] = None if first is None else first["decisions"]
        record["settings"] = settings
        return record


def agrl_config(args):
    """agrl's training config: conf/'s defaults, the race's task, then ``--agrl-override``."""
    from agrl.config import compose_config, load_config

    overrides = [f"task={args.task}", f"seed={args.seed}", f"simulation.compile={str(args.compile).lower()}",
                 "progress=false", "target_success=0"]  # the race's rule stops it (Trainer._finished below)
    if args.max_decisions is not None:
        overrides.append(f"simulation.max_decisions={args.max_decisions}")
    return load_config(compose_config(*overrides, *args.agrl_override))


def race_agrl(args, evaluation: RaceEvaluation, clock: TrainingClock) -> dict:
    """agrl's Trainer with its own loop (curriculum, checkpoints, metrics); the race owns stopping and evaluation."""
    from agrl.rl.trainer import Trainer

    config = agrl_config(args)

    class RaceTrainer(Trainer):
        next_evaluation = 0.0

        def _evaluation_due(self, metrics: dict[str, float]) -> bool:
            if clock.seconds < self.next_evaluation or clock.seconds >= args.budget_seconds:
                return False  # (at the end of the budget the final evaluation follows)
            self.next_evaluation = clock.seconds + args.eval_every
            return True

        def _periodic_evaluation(self) -> dict[str, float]:
            self.next_evaluation = clock.seconds + args.eval_every
            record = evaluation("agrl", self.actor, self.counters.frames)
            return {"eval/success_rate": record["success_rate"]}

        def _finished(self) -> str | None:
            if clock.seconds >= args.budget_seconds:
                return "race budget"
            if not args.full_budget and evaluation.reached_last_target("agrl"):
                return "race target"
            return None

        def final_evaluation(self) -> dict[str, Any]:
            return {}  # the race's own final evaluation follows (the paper's 1000 episodes are not part of it)

    with tempfile.TemporaryDirectory() as folder:
        clock.start()
        trainer = RaceTrainer(config, Path(folder))
        trainer.train()
        evaluation("agrl", trainer.actor, trainer.counters.frames, final=True)
    ppo = config.ppo
    settings = {"num_envs": ppo.num_envs, "steps_per_env": ppo.steps_per_env, "minibatch": ppo.minibatch_size,
                "epochs": ppo.epochs, "learning_rate": ppo.learning_rate, "curriculum": config.curriculum.enabled,
                "compile": config.simulation.compile, "overrides": list(args.agrl_override)}
    return evaluation.result("agrl", settings)


def sb3_settings(args) -> dict:
    """stable-baselines3 PPO's keyword arguments for ``--sb3-geometry`` (``{}``: its own defaults)."""
    if args.sb3_geometry == "sb3":
        return {}
    config = agrl_config(args)
    ppo, agent = config.ppo, config.agent
    return {"n_steps": ppo.steps_per_env, "batch_size": ppo.minibatch_size, "n_epochs": ppo.epochs,
            "learning_rate": ppo.learning_rate, "gamma": config.reward.gamma, "gae_lambda": ppo.gae_lambda,
            "clip_range": ppo.clip_epsilon, "ent_coef": ppo.entropy_coeff, "vf_coef": ppo.critic_coeff,
            "max_grad_norm": ppo.max_grad_norm,
            "policy_kwargs": {"net_arch": {"pi": list(agent.actor_hidden), "vf": list(agent.critic_hidden)},
                              "activation_fn": agent.activation}}


def race_sb3(args, evaluation: RaceEvaluation, clock: TrainingClock) -> dict:
    """``PPO("MlpPolicy", vector env)``; a callback evaluates on the training clock and stops at the budget."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    from benchmarks.bench_peer import make_sb3_vector_env

    settings = sb3_settings(args)
    num_envs = agrl_config(args).ppo.num_envs if args.sb3_geometry == "agrl" else args.sb3_num_envs
    kwargs = dict(settings)
    if "policy_kwargs" in kwargs:
        activation = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU, "elu": torch.nn.ELU}
        kwargs["policy_kwargs"] = {**kwargs["policy_kwargs"],
                                   "activation_fn": activation[kwargs["policy_kwargs"]["activation_fn"]]}
    task = {"task": args.task} | ({} if args.max_decisions is None else {"max_decisions": args.max_decisions})

    class RaceCallback(BaseCallback):
        next_evaluation = 0.0

        def _on_step(self) -> bool:
            if clock.seconds >= args.budget_seconds:
                return False  # the final evaluation follows
            if clock.seconds >= self.next_evaluation:
                evaluation("stable-baselines3", actor, self.model.num_timesteps)
                self.next_evaluation = clock.seconds + args.eval_every
            return args.full_budget or not evaluation.reached_last_target("stable-baselines3")

    clock.start()
    if args.sb3_env == "single":  # what a stable-baselines3 user writes: one Python-float gym env per row
        from stable_baselines3.common.env_util import make_vec_env

        import agrl

        env = make_vec_env(agrl.GYM_ENV_ID, n_envs=num_envs, seed=args.seed, env_kwargs=task)
    else:
        env = make_sb3_vector_env(num_envs, args.compile, args.seed, **task)
    model = PPO("MlpPolicy", env, seed=args.seed, device="cpu", verbose=0, **kwargs)
    actor = Sb3Actor(model)
    callback = RaceCallback()
    evaluation("stable-baselines3", actor, 0)  # where it starts, as agrl's first periodic evaluation
    callback.next_evaluation = clock.seconds + args.eval_every
    model.learn(total_timesteps=10**12, callback=callback)
    evaluation("stable-baselines3", actor, model.num_timesteps, final=True)
    env.close()
    defaults = {"n_steps": model.n_steps, "batch_size": model.batch_size, "n_epochs": model.n_epochs,
                "learning_rate": model.learning_rate, "gamma": model.gamma, "gae_lambda": model.gae_lambda,
                "ent_coef": model.ent_coef, "vf_coef": model.vf_coef, "max_grad_norm": model.max_grad_norm,
                "net_arch": str(model.policy.net_arch), "activation_fn": model.policy.activation_fn.__name__}
    return evaluation.result("stable-baselines3", {"geometry": args.sb3_geometry, "env": args.sb3_env,
                                                   "num_envs": num_envs,
                                                   "compile": args.compile and args.sb3_env == "vector", **defaults})


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_race", description=__doc__.splitlines()[0])
    parser.add_argument("--budget-seconds", type=float, default=900.0, help="training seconds per trainer")
    parser.add_argument("--eval-every", type=float, default=30.0, help="training seconds between evaluations")
    parser.add_argument("--eval-episodes", type=int, default=256,
                        help="episodes of the fixed evaluation set (default 256, conf's periodic evaluation)")
    parser.add_argument("--targets", type=float, nargs="+", default=[0.95, 0.99],
                        help="success rates to time (default 0.95 0.99)")
    parser.add_argument("--full-budget", action="store_true",
                        help="train the whole budget (default: stop once the last target is reached)")
    parser.add_argument("--task", default="fixed", choices=("fixed", "uniform", "curved", "irregular"))
    parser.add_argument("--max-decisions", type=int, default=None, help="decision budget per episode (conf's)")
    parser.add_argument("--trainers", nargs="+", choices=TRAINERS, default=list(TRAINERS))
    parser.add_argument("--sb3-geometry", choices=("sb3", "agrl"), default="sb3",
                        help="sb3: stable-baselines3's PPO defaults; agrl: agrl's config (envs, steps, minibatch, "
                             "epochs, rates, networks)")
    parser.add_argument("--sb3-num-envs", type=int, default=8,
                        help="vector-env rows for --sb3-geometry sb3 (default 8)")
    parser.add_argument("--sb3-env", choices=("single", "vector"), default=None,
                        help="single: make_vec_env('agrl/Guidance-v0', n_envs) (DummyVecEnv of Python-float envs; "
                             "the default for --sb3-geometry sb3); vector: the batched gym vector env (the default "
                             "for --sb3-geometry agrl)")
    parser.add_argument("--agrl-override", nargs="*", default=[], metavar="KEY=VALUE",
                        help="Hydra overrides of agrl's training config (e.g. ppo.num_envs=256)")
    parser.add_argument("--compile", action=argparse.BooleanOptionalAction, default=True,
                        help="torch.compile the simulation step (both trainers and the evaluation; default on)")
    parser.add_argument("--threads", type=int, default=None, help="torch threads (default torch's)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    args.sb3_env = args.sb3_env or ("single" if args.sb3_geometry == "sb3" else "vector")
    for name in ("budget_seconds", "eval_every", "eval_episodes", "sb3_num_envs"):
        if not getattr(args, name) > 0:
            parser.error(f"--{name.replace('_', '-')}={getattr(args, name)} is not allowed: a positive number")
    if args.max_decisions is not None and args.max_decisions < 1:
        parser.error(f"--max-decisions={args.max_decisions} is not allowed: an integer >= 1")
    if not all(0 < target <= 1 for target in args.targets) or args.targets != sorted(args.targets):
        parser.error(f"--targets={args.targets} is not allowed: increasing success rates in (0, 1]")
    if args.threads is not None and args.threads < 1:
        parser.error(f"--threads={args.threads} is not allowed: an integer >= 1")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    if "stable-baselines3" in args.trainers:
        from benchmarks.bench_peer import _sb3

        _sb3()
    torchrl_logs_to_stderr()
    import torch

    from agrl.config import ConfigError, to_guidance_parameters
    from agrl.envs.gym import gym_parameters

    if args.threads is not None:
        torch.set_num_threads(args.threads)

    def emit(record: dict) -> None:
        print(json.dumps(record), flush=True)

    from hydra.errors import HydraException

    try:
        config = agrl_config(args)
    except (ConfigError, HydraException) as error:  # a bad --agrl-override: one line, not Hydra's traceback
        raise SystemExit(f"benchmarks.bench_race: error: {str(error).splitlines()[0]}") from None
    # One task for both: the gym env's parameters must be those agrl trains on (overrides may not change them).
    params = gym_parameters(task=args.task, max_decisions=args.max_decisions, compile=args.compile)
    trained = to_guidance_parameters(config.task, config.reward, config.simulation)
    if dataclasses.replace(trained, compile=params.compile) != params:
        raise SystemExit("benchmarks.bench_race: error: --agrl-override changed the task (task, reward or simulation): "
                         "both trainers must learn the same one")
    clock = TrainingClock()
    load = os.getloadavg()[0]
    evaluation = RaceEvaluation(params, args.eval_episodes, args.seed + EVALUATION_SEED_OFFSET, clock,
                                args.targets, emit)
    results = {}
    for trainer in args.trainers:
        torch._dynamo.reset()  # each trainer compiles its own simulation step on its own clock
        results[trainer] = (race_agrl if trainer == "agrl" else race_sb3)(args, evaluation, clock)
        emit(results[trainer])
    summary = {"name": "race_summary", "value": None, "unit": "x (stable-baselines3 seconds / agrl seconds)",
               "task": args.task, "budget_seconds": args.budget_seconds, "eval_every": args.eval_every,
               "eval_episodes": args.eval_episodes, "sb3_geometry": args.sb3_geometry,
               "threads": torch.get_num_threads(), "load_average_1min_at_start": round(load, 2),
               "load_average_1min_at_end": round(os.getloadavg()[0], 2)}
    if len(results) == 2:
        for target in args.targets:
            label = f"{round(100 * target, 2):g}"
            agrl_s, sb3_s = (results[name][f"seconds_to_{label}"] for name in TRAINERS)
            summary[f"speedup_to_{label}"] = None if agrl_s is None or sb3_s is None else round(sb3_s / agrl_s, 2)
            summary[f"agrl_reached_{label}_sb3_did_not"] = agrl_s is not None and sb3_s is None
        summary["value"] = summary[f"speedup_to_{f'{round(100 * args.targets[-1], 2):g}'}"]
    emit(summary)
    return 0


if __name__ == "__main__":
    sys.exit(main())
