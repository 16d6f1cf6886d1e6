"""``python -m agrl.bench_peer``: stable-baselines3 PPO on the gymnasium vector env against agrl's trainer.

Both train on the same batched simulator with the same batch geometry (``--num-envs`` 512 envs x
``--steps`` 64 decisions per iteration) and the training defaults of ``conf/`` (SB3 takes epochs, minibatch,
learning rate, gamma, clip, GAE lambda, entropy and value coefficients, gradient norm and the network sizes
from the composed config), one after the other in the same sitting, and each reports
training **decisions per second** from its second iteration on (the first one carries start-up and,
with ``--compile``, the ``torch.compile`` of the simulation step). Prints one JSON line per
trainer and a ``ratio`` line (agrl / stable-baselines3).

stable-baselines3 is the ``bench`` extra (``pip install 'agrl[bench]'``; it leaves torch alone). It
sees the env through :class:`Sb3VectorEnv`, a thin adapter from
:class:`agrl.envs.gym_vector.GuidanceVectorEnv` (same-step autoreset) to its ``VecEnv`` interface.
agrl's trainer runs as ``python -m agrl.train`` in a subprocess with matching overrides (curriculum
off, no periodic evaluation, a 16-episode final evaluation excluded from the timing).

Example::

    python -m agrl.bench_peer --iterations 4 --threads 1
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np


def _sb3():
    try:
        import stable_baselines3
    except ImportError:
        raise SystemExit("agrl.bench_peer: error: needs stable-baselines3 (pip install 'agrl[bench]')") from None
    return stable_baselines3


def make_sb3_vector_env(num_envs: int, compile: bool, seed: int, **task):
    """:class:`agrl.envs.gym_vector.GuidanceVectorEnv` behind stable-baselines3's ``VecEnv`` interface."""
    _sb3()
    from stable_baselines3.common.vec_env import VecEnv

    from agrl.envs.gym_vector import GuidanceVectorEnv

    class Sb3VectorEnv(VecEnv):
        """SB3 resets finished envs within the step and wants ``terminal_observation`` in their info."""

        def __init__(self):
            self.vector_env = GuidanceVectorEnv(num_envs=num_envs, compile=compile, autoreset_mode="SameStep",
                                                **task)
            super().__init__(num_envs, self.vector_env.single_observation_space,
                             self.vector_env.single_action_space)
            self._seed, self._actions = seed, None

        def reset(self):
            observations, _ = self.vector_env.reset(seed=self._seed)
            return observations

        def step_async(self, actions):
            self._actions = np.asarray(actions).reshape(self.num_envs).astype(np.int64)

        def step_wait(self):
            observations, rewards, terminated, truncated, info = self.vector_env.step(self._actions)
            dones = terminated | truncated
            infos = [{} for _ in range(self.num_envs)]
            for row in np.flatnonzero(dones):
                infos[row]["terminal_observation"] = info["final_obs"][row]
                infos[row]["TimeLimit.truncated"] = bool(truncated[row])
            return observations, rewards.astype(np.float32), dones, infos

        def close(self):
            self.vector_env.close()

        def get_attr(self, attr_name, indices=None):
            return [getattr(self.vector_env, attr_name)] * len(self._get_indices(indices))

        def set_attr(self, attr_name, value, indices=None):
            setattr(self.vector_env, attr_name, value)

        def env_method(self, method_name, *method_args, indices=None, **method_kwargs):
            result = getattr(self.vector_env, method_name)(*method_args, **method_kwargs)
            return [result] * len(self._get_indices(indices))

        def env_is_wrapped(self, wrapper_class, indices=None):
            return [False] * len(self._get_indices(indices))

    return Sb3VectorEnv()


def bench_sb3(num_envs: int, steps: int, iterations: int, compile: bool, seed: int, task: dict) -> dict:
    """Train SB3 PPO for ``iterations`` rollouts + updates; decisions/s from the second iteration on."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    starts: list[float] = []

    class IterationClock(BaseCallback):
        def _on_rollout_start(self) -> None:
            starts.append(time.perf_counter())

        def _on_step(self) -> bool:
            return True

    from agrl.config import compose_config, load_config

    config = load_config(compose_config(f"task={task['task']}"))  # agrl's training defaults, conf/
    ppo, agent = config.ppo, config.agent
    activation = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU, "elu": torch.nn.ELU}[agent.activation]
    env = make_sb3_vector_env(num_envs, compile, seed, **task)
    model = PPO(
        "MlpPolicy", env, n_steps=steps, batch_size=ppo.minibatch_size, n_epochs=ppo.epochs,
        learning_rate=ppo.learning_rate, gamma=config.reward.gamma, gae_lambda=ppo.gae_lambda,
        clip_range=ppo.clip_epsilon, ent_coef=ppo.entropy_coeff, vf_coef=ppo.critic_coeff,
        max_grad_norm=ppo.max_grad_norm, seed=seed, device="cpu",
        policy_kwargs={"net_arch": {"pi": list(agent.actor_hidden), "vf": list(agent.critic_hidden)},
                       "activation_fn": activation},
        verbose=0,
    )
    model.learn(total_timesteps=(iterations + 2) * num_envs * steps, callback=IterationClock())
    # starts[i] is the start of rollout i; iteration i (rollout + update) ends where i + 1 starts.
    timed = len(starts) - 2  # rollouts 1 .. len-2 each followed by a complete update and the next start
    seconds = starts[-1] - starts[1]
    env.close()
    return {"name": "peer_sb3_ppo_decisions_per_second", "value": round(timed * num_envs * steps / seconds, 1),
            "unit": "decisions/s", "iterations_timed": timed, "seconds": round(seconds, 2)}


def bench_agrl(num_envs: int, steps: int, iterations: int, compile: bool, seed: int, task: dict,
               threads: int | None) -> dict:
    """Run ``python -m agrl.train`` with the same geometry; decisions/s from its logged metrics (iterations 2..)."""
    from agrl.report import read_metrics

    with tempfile.TemporaryDirectory() as folder:
        overrides = [
            f"task={task['task']}", f"ppo.num_envs={num_envs}", f"ppo.steps_per_env={steps}",
            f"ppo.total_frames={(iterations + 1) * num_envs * steps}",
            "ppo.max_minutes=0", "eval.interval=0", "eval.episodes=16", "curriculum.enabled=false",
            "target_success=0", "checkpoint_interval=1000", "progress=false", f"seed={seed}",
            f"simulation.compile={str(compile).lower()}", f"hydra.run.dir={folder}/run",
        ]
        if "speed" in task:
            overrides.append(f"speed={task['speed']}")
        environment = dict(os.environ)
        if threads is not None:
            environment["OMP_NUM_THREADS"] = str(threads)
        completed = subprocess.run([sys.executable, "-m", "agrl.train", *overrides], capture_output=True, text=True,
                                   env=environment, check=False)
        if completed.returncode != 0:
            raise SystemExit(f"agrl.bench_peer: error: python -m agrl.train failed: {completed.stderr[-2000:]}")
        rows = [row for row in read_metrics(Path(folder) / "run") if row["frames"] and row["wall_time"]]
    frames = [float(row["frames"]) for row in rows]
    wall = [float(row["wall_time"]) for row in rows]
    seconds = wall[-1] - wall[0]
    return {"name": "peer_agrl_trainer_decisions_per_second", "value": round((frames[-1] - frames[0]) / seconds, 1),
            "unit": "decisions/s", "iterations_timed": len(rows) - 1, "seconds": round(seconds, 2)}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m agrl.bench_peer", description=__doc__.splitlines()[0])
    parser.add_argument("--num-envs", type=int, default=512)
    parser.add_argument("--steps", type=int, default=64, help="decisions per env per iteration")
    parser.add_argument("--iterations", type=int, default=4, help="timed iterations per trainer (after one warm-up)")
    parser.add_argument("--compile", action=argparse.BooleanOptionalAction, default=True,
                        help="fuse the simulation step with torch.compile in both (default on, as training)")
    parser.add_argument("--threads", type=int, default=None, help="torch threads for both (default torch's)")
    parser.add_argument("--task", default="fixed")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    for name in ("num_envs", "steps", "iterations"):
        if getattr(args, name) < 1 or (name == "iterations" and args.iterations < 2):
            parser.error(f"--{name.replace('_', '-')}={getattr(args, name)} is not allowed: a positive integer "
                         "(--iterations: at least 2)")
    _sb3()
    import torch

    if args.threads is not None:
        torch.set_num_threads(args.threads)
    task = {"task": args.task}
    load = os.getloadavg()[0]
    sb3 = bench_sb3(args.num_envs, args.steps, args.iterations, args.compile, args.seed, task)
    print(json.dumps(sb3), flush=True)
    agrl = bench_agrl(args.num_envs, args.steps, args.iterations, args.compile, args.seed, task, args.threads)
    print(json.dumps(agrl), flush=True)
    print(json.dumps({"name": "ratio_agrl_over_sb3", "value": round(agrl["value"] / sb3["value"], 3), "unit": "x",
                      "num_envs": args.num_envs, "steps": args.steps, "compile": args.compile,
                      "threads": torch.get_num_threads(), "load_average_1min_at_start": round(load, 2),
                      "load_average_1min_at_end": round(os.getloadavg()[0], 2)}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
