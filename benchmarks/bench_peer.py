"""``python -m benchmarks.bench_peer``: stable-baselines3 PPO on the gymnasium vector env against agrl's trainer.

Both train on the same batched simulator with the same batch geometry (``--num-envs`` 512 envs x
``--steps`` 64 decisions per iteration, ``--minibatch`` 512) and the training defaults of ``conf/`` (SB3 takes
epochs, learning rate, gamma, clip, GAE lambda, entropy and value coefficients, gradient norm and the network
sizes from the composed config), in the same process, and each reports the median
**seconds of one PPO iteration**, split into collection and update (the epochs of minibatches; GAE is in
SB3's collection and in agrl's update), from its second iteration on (the first one carries start-up and,
with ``--compile``, the ``torch.compile`` of the simulation step). The trainers' iterations alternate (one of
each in turn, ``--iterations`` rounds), so a machine whose speed drifts during the run slows them alike, and each
ratio is the median over rounds of the two trainers' ratio in that round. Prints one ``ppo_iteration_seconds``
line per trainer (with each round's seconds) and a ``ratio`` line (agrl's decisions/s over stable-baselines3's;
``update_ratio`` and ``collection_ratio`` per part).

``agrl`` is agrl's trainer with the eager loss (``ppo.compile_loss=false``, the default until 2026-12-07);
``--trainers ... agrl-compiled`` adds agrl with ``ppo.compile_loss=true``, ``python -m agrl.train``'s default now
(the loss's forward and backward compiled, :class:`agrl.rl.ppo.CompiledLoss`), and its ratio.

``--trainers ... floor`` adds a line: the simulator, networks and PPO update with nothing around them
(:func:`bench_floor`), plain PyTorch with no TensorDict, no loss module, no collector, and none of the work of
rewards, episode ends, resets and GAE, its update eager (a trainer compiling its update can pass that part). With
it, each agrl trainer also gets the two lines of the project's speed targets (docs/benchmarks.md), which were stated
against this floor:
``ratio_agrl_over_floor`` (its decisions/s over the floor's; the target is 0.9 or more) and
``collection_time_agrl_over_floor`` (its collection's seconds over the floor's; the target is 1.3 or less),
``agrl_compiled`` in both names for the compiled loss. ``floor-equal-work`` adds the same floor doing that
work too, plainly (rewards by the env's own function, fresh starts for the rows that ended only, GAE on one
critic pass): what a trainer of equal work costs done plainly, and the same two lines against it
(``..._over_floor_equal_work``). A ``ratio_floor_over_sb3`` line says how far ahead of stable-baselines3 the
bare arithmetic is.

``--set KEY=VALUE ...`` overrides ``conf/``'s ``agent.*`` and ``ppo.*`` for every trainer alike (networks,
epochs, rates; not the batch geometry, which the options above set), so the iteration of another recipe can be
compared, e.g. ``make train``'s: ``--num-envs 2048 --steps 16 --minibatch 4096 --set 'agent.actor_hidden=[64,64]'
'agent.critic_hidden=[64,64]'``. The lines then carry the ``settings``.

stable-baselines3 is the ``bench`` extra (``pip install -e '.[bench]'``; it leaves torch alone). It
sees the env through :class:`Sb3VectorEnv`, a thin adapter from
:class:`agrl.envs.gym_vector.GuidanceVectorEnv` (same-step autoreset) to its ``VecEnv`` interface.
agrl's side is :class:`agrl.rl.trainer.Trainer`, the one ``python -m agrl.train`` runs, built from
``conf/`` with matching overrides (curriculum off); each iteration is its collector's next batch, then
:meth:`~agrl.rl.trainer.Trainer.learn`.

Example::

    python -m benchmarks.bench_peer --iterations 4 --threads 1
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from benchmarks import torchrl_logs_to_stderr


def _sb3():
    try:
        import stable_baselines3
    except ImportError:
        raise SystemExit("benchmarks.bench_peer: error: needs stable-baselines3 (pip install -e '.[bench]')") from None
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


def iteration_record(trainer: str, collection: list[float], update: list[float], decisions: int) -> dict:
    """Median seconds of one PPO iteration's collection and update (GAE falls in SB3's collection and in
    agrl's update, where the trainer computes it: a few hundredths of a second either way), and each timed
    iteration's (``collection_each_s``, ``update_each_s``, in the order run)."""
    collection_s, update_s = statistics.median(collection), statistics.median(update)
    total = statistics.median(c + u for c, u in zip(collection, update, strict=True))
    return {"name": "ppo_iteration_seconds", "trainer": trainer, "value": round(total, 3), "unit": "s/iteration",
            "collection_s": round(collection_s, 3), "update_s": round(update_s, 3),
            "decisions_per_second": round(decisions / total, 1), "decisions_per_iteration": decisions,
            "iterations_timed": len(collection), "collection_each_s": [round(c, 6) for c in collection],
            "update_each_s": [round(u, 6) for u in update]}


#: A trainer's iterations: a generator that builds the trainer, then times one PPO iteration per ``next()``,
#: yielding its (collection, update) seconds (the first one carries start-up and compilation).
Iterations = Iterator[tuple[float, float]]


def bench_sb3(num_envs: int, steps: int, minibatch: int, compile: bool, seed: int, task: dict,
              settings: Sequence[str] = ()) -> Iterations:
    """SB3 PPO, one rollout and update per ``model.learn`` call (``reset_num_timesteps=False``: it goes on);
    its PPO settings and networks from ``conf/`` with the ``settings`` overrides."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    marks: dict[str, float] = {}

    class IterationClock(BaseCallback):
        def _on_rollout_start(self) -> None:
            marks["start"] = time.perf_counter()

        def _on_rollout_end(self) -> None:  # SB3 calls it after its GAE: GAE counts as collection here
            marks["end"] = time.perf_counter()

        def _on_step(self) -> bool:
            return True

    from agrl.config import compose_config, load_config

    config = load_config(compose_config(f"task={task['task']}", *settings))  # agrl's training config, conf/
    ppo, agent = config.ppo, config.agent
    activation = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU, "elu": torch.nn.ELU}[agent.activation]
    env = make_sb3_vector_env(num_envs, compile, seed, **task)
    model = PPO(
        "MlpPolicy", env, n_steps=steps, batch_size=minibatch, n_epochs=ppo.epochs,
        learning_rate=ppo.learning_rate, gamma=config.reward.gamma, gae_lambda=ppo.gae_lambda,
        clip_range=ppo.clip_epsilon, ent_coef=ppo.entropy_coeff, vf_coef=ppo.critic_coeff,
        max_grad_norm=ppo.max_grad_norm, seed=seed, device="cpu",
        policy_kwargs={"net_arch": {"pi": list(agent.actor_hidden), "vf": list(agent.critic_hidden)},
                       "activation_fn": activation},
        verbose=0,
    )
    clock = IterationClock()
    try:
        while True:
            model.learn(total_timesteps=num_envs * steps, callback=clock, reset_num_timesteps=False)
            done = time.perf_counter()
            yield marks["end"] - marks["start"], done - marks["end"]
    finally:
        env.close()


def bench_agrl(num_envs: int, steps: int, minibatch: int, compile: bool, seed: int, task: dict,
               settings: Sequence[str] = (), compile_loss: bool = False) -> Iterations:
    """agrl's Trainer (the one ``python -m agrl.train`` runs) with the same geometry and ``settings``: collection +
    GAE, update. ``compile_loss``: with ``ppo.compile_loss=true`` (its compilation falls in the warm-up iteration)."""
    from agrl.config import compose_config, load_config
    from agrl.rl.trainer import Trainer

    overrides = [
        f"task={task['task']}", f"ppo.num_envs={num_envs}", f"ppo.steps_per_env={steps}",
        f"ppo.minibatch_size={minibatch}", "curriculum.enabled=false", "progress=false",
        f"seed={seed}", f"simulation.compile={str(compile).lower()}", f"ppo.compile_loss={str(compile_loss).lower()}",
        *settings,
    ]
    config = load_config(compose_config(*overrides))
    with tempfile.TemporaryDirectory() as folder:
        trainer = Trainer(config, Path(folder))
        batches = iter(trainer.collector)
        try:
            while True:
                start = time.perf_counter()
                data = next(batches)
                middle = time.perf_counter()
                trainer.learn(data)
                yield middle - start, time.perf_counter() - middle
        finally:
            trainer.collector.shutdown()


def plain_gae(rewards, dones, values, gamma: float, lmbda: float):
    """Generalised advantage estimates and value targets of ``T`` decisions of ``N`` rows in plain PyTorch:
    ``rewards`` and ``dones`` ``(T, N)``, ``values`` ``(T + 1, N)`` (the critic on each decision's observation and on
    the one after the last). Every episode end is a termination (agrl's env marks each end ``terminated``), so a
    done row's next value is not used and its observation there may be the next episode's first."""
    import torch

    not_done = 1.0 - dones.float()
    advantages = torch.empty_like(rewards)
    running = torch.zeros_like(rewards[0])
    for t in range(rewards.shape[0] - 1, -1, -1):
        delta = rewards[t] + gamma * values[t + 1] * not_done[t] - values[t]
        running = delta + gamma * lmbda * not_done[t] * running
        advantages[t] = running
    return advantages, advantages + values[:-1]


def plain_decision_end(params, decisions, aircraft, destination, last_action, action_before_last, action, result):
    """The reward and end of a decision ``action`` from (``aircraft``, ``destination``, ``last_action``,
    ``action_before_last``), the simulator's ``result`` of it, its row's ``decisions`` counted with it, as the env
    computes them (:meth:`agrl.envs.guidance.GuidanceEnv.complete_transition`), without its bookkeeping:
    ``(reward, done)``."""
    from agrl.core.reward import step_reward
    from agrl.core.termination import Outcome, decision_outcome

    outcome = decision_outcome(result.outcome, decisions, params.max_decisions)
    reward, _ = step_reward(outcome, aircraft, destination, last_action, action_before_last, action,
                            result.aircraft_state, result.destination_state, params.reward, action != last_action)
    return reward, outcome != Outcome.RUNNING


def bench_floor(num_envs: int, steps: int, minibatch: int, compile: bool, seed: int, task: dict,
                settings: Sequence[str] = (), equal_work: bool = False) -> Iterations:
    """The iteration's arithmetic alone, in plain eager PyTorch: the bound of a trainer of the same work and no compiled
    update.

    Collection: per decision, the observation (:func:`agrl.core.observation.policy_observation`), the actor's
    network, a categorical sample and the simulator (:class:`agrl.core.simulation.DecisionSimulator`, compiled
    as in training). Update: ``epochs`` passes of ``minibatch`` rows through actor and critic (agrl's network
    sizes and activation, from ``conf/``), the clipped PPO objective with normalised advantages, a smooth-L1 value
    loss and the entropy bonus, gradient clipping and fused Adam, as :class:`torchrl.objectives.ClipPPOLoss` and
    :func:`agrl.rl.ppo.ppo_update` compute them.

    ``equal_work=False`` (``--trainers floor``, the floor the speed targets were stated against): no rewards,
    episode ends or resets, and random advantages (no GAE, whose critic pass over the batch is about a tenth of
    agrl's update at ``make train``'s shape): less work than a trainer does.
    ``equal_work=True`` (``--trainers floor-equal-work``): what PPO needs of a trainer besides, done plainly:
    each decision's reward (:func:`agrl.core.reward.step_reward`, the env's) and end (an outcome, or the decision
    budget), fresh starts for the rows that ended (drawn for those rows only), and in the update GAE
    (:func:`plain_gae`) on one critic pass over the batch's observations and the last one's successors.
    """
    import torch
    from torchrl.modules import MLP

    from agrl.config import compose_config, guidance_parameters, load_config
    from agrl.core.initial_states import sample_initial_aircraft
    from agrl.core.observation import OBSERVATION_SIZE, policy_observation
    from agrl.core.simulation import DecisionSimulator
    from agrl.envs.guidance import NUM_ACTIONS
    from agrl.rl.models import ACTIVATIONS

    config = load_config(compose_config(f"task={task['task']}", *settings))
    ppo, agent = config.ppo, config.agent
    params = guidance_parameters(f"task={task['task']}", *settings, compile=compile)
    simulation = params.simulation
    generator = torch.Generator().manual_seed(seed)
    torch.manual_seed(seed)
    activation = ACTIVATIONS[agent.activation]
    actor = MLP(in_features=OBSERVATION_SIZE, out_features=NUM_ACTIONS, num_cells=list(agent.actor_hidden),
                activation_class=activation)
    critic = MLP(in_features=OBSERVATION_SIZE, out_features=1, num_cells=list(agent.critic_hidden),
                 activation_class=activation)
    parameters = [*actor.parameters(), *critic.parameters()]
    optimizer = torch.optim.Adam(parameters, lr=ppo.learning_rate, eps=1e-5, fused=True)
    simulator = DecisionSimulator(simulation, params.maneuvers.controls(), compile=compile)
    start_of_destination = torch.tensor(params.destination.start)
    destination = start_of_destination.expand(num_envs, 4).clone()
    speed, turn_rate = params.destination.initial_motion(num_envs, generator, torch.device("cpu"))  # per row
    aircraft = sample_initial_aircraft(num_envs, params.initial_state, destination, generator)
    last_action = torch.zeros(num_envs, dtype=torch.int64)
    action_before_last = torch.zeros(num_envs, dtype=torch.int64)
    decisions = torch.zeros(num_envs, dtype=torch.int64)

    def restart(rows: torch.Tensor) -> None:
        """New episodes in ``rows`` (equal work): the env's fresh starts, drawn for these rows only."""
        count = rows.numel()
        destination[rows] = start_of_destination
        row_speed, row_turn_rate = params.destination.initial_motion(count, generator, torch.device("cpu"))
        speed[rows], turn_rate[rows] = row_speed, row_turn_rate
        aircraft[rows] = sample_initial_aircraft(count, params.initial_state, destination[rows], generator)
        last_action[rows], action_before_last[rows], decisions[rows] = 0, 0, 0

    def observe() -> torch.Tensor:
        return policy_observation(aircraft, destination, last_action, simulation.airspace, simulation.limits)

    def collect() -> tuple[torch.Tensor, ...]:
        nonlocal aircraft, destination, last_action, action_before_last
        observations, actions, log_probs, rewards, dones = [], [], [], [], []
        with torch.no_grad():
            for _ in range(steps):
                observation = observe()
                log_prob = torch.log_softmax(actor(observation), -1)
                action = torch.multinomial(log_prob.exp(), 1).squeeze(-1)
                observations.append(observation)
                actions.append(action)
                log_probs.append(log_prob.gather(-1, action.unsqueeze(-1)).squeeze(-1))
                result = simulator(aircraft, destination, speed, turn_rate, action)
                if equal_work:
                    decisions.add_(1)
                    reward, done = plain_decision_end(params, decisions, aircraft, destination, last_action,
                                                      action_before_last, action, result)
                    rewards.append(reward)
                    dones.append(done)
                aircraft, destination = result.aircraft_state, result.destination_state
                action_before_last, last_action = last_action, action
                if equal_work and bool(done.any()):
                    restart(done.nonzero().squeeze(-1))
            if equal_work:
                observations.append(observe())  # the last decision's successors, for its next value
        if not equal_work:
            return torch.cat(observations), torch.cat(actions), torch.cat(log_probs)
        # Observations (T + 1, N, features): GAE's critic pass reads the successors of the last decision too.
        return torch.stack(observations), torch.cat(actions), torch.cat(log_probs), torch.stack(rewards), \
            torch.stack(dones)

    def update(observations: torch.Tensor, actions: torch.Tensor, behaviour_log_probs: torch.Tensor,
               rewards: torch.Tensor | None = None, dones: torch.Tensor | None = None) -> None:
        if equal_work:
            with torch.no_grad():
                values = critic(observations).squeeze(-1)
                advantages, value_targets = plain_gae(rewards, dones, values, config.reward.gamma, ppo.gae_lambda)
            observations, advantages, value_targets = observations[:-1].flatten(0, 1), advantages.flatten(), \
                value_targets.flatten()
        rows = len(observations)
        if not equal_work:
            advantages, value_targets = torch.randn(rows, generator=generator), torch.randn(rows, generator=generator)
        for _ in range(ppo.epochs):
            order = torch.randperm(rows, generator=generator)
            for start in range(0, rows - minibatch + 1, minibatch):
                index = order[start:start + minibatch]
                log_prob_all = torch.log_softmax(actor(observations[index]), -1)
                log_prob = log_prob_all.gather(-1, actions[index].unsqueeze(-1)).squeeze(-1)
                advantage = advantages[index]
                advantage = (advantage - advantage.mean()) / advantage.std().clamp_min(1e-6)
                ratio = (log_prob - behaviour_log_probs[index]).exp()
                objective = torch.min(ratio * advantage,
                                      ratio.clamp(1 - ppo.clip_epsilon, 1 + ppo.clip_epsilon) * advantage)
                entropy = -(log_prob_all.exp() * log_prob_all).sum(-1).mean()
                value_loss = torch.nn.functional.smooth_l1_loss(critic(observations[index]).squeeze(-1),
                                                                value_targets[index])
                loss = -objective.mean() + ppo.critic_coeff * value_loss - ppo.entropy_coeff * entropy
                optimizer.zero_grad(set_to_none=True)
                loss.backward()
                torch.nn.utils.clip_grad_norm_(parameters, ppo.max_grad_norm)
                optimizer.step()

    while True:
        start = time.perf_counter()
        batch = collect()
        middle = time.perf_counter()
        update(*batch)
        yield middle - start, time.perf_counter() - middle


#: The keys each trainer's config gets from the command's own options, which ``--set`` may not change.
BENCH_SET_KEYS = ("ppo.num_envs", "ppo.steps_per_env", "ppo.minibatch_size", "ppo.compile_loss")

#: {--trainers name: (its iterations, the trainer its record names)}.
TRAINERS = {"agrl": (bench_agrl, "agrl"),
            "agrl-compiled": (functools.partial(bench_agrl, compile_loss=True), "agrl (compiled loss)"),
            "stable-baselines3": (bench_sb3, "stable-baselines3"),
            "floor": (bench_floor, "floor (plain PyTorch)"),
            "floor-equal-work": (functools.partial(bench_floor, equal_work=True), "floor, equal work (plain PyTorch)")}


def alternate(trainers: dict[str, Iterations], rounds: int) -> dict[str, tuple[list[float], list[float]]]:
    """One warm-up iteration of each trainer (not kept), then ``rounds`` rounds of one iteration of each in turn:
    {name: (collection seconds, update seconds), one per round}."""
    timed = {name: ([], []) for name in trainers}
    for iterations in trainers.values():
        next(iterations)  # start-up and compilation
    for _ in range(rounds):
        for name, iterations in trainers.items():
            collection, update = next(iterations)
            timed[name][0].append(collection)
            timed[name][1].append(update)
    return timed


def paired_ratio(numerator: dict, reference: dict, part: str) -> float:
    """The median over rounds of ``reference``'s seconds over ``numerator``'s, for ``part``: "collection",
    "update" or "total" (a speed ratio: above 1 is faster than the reference)."""
    def seconds(record: dict, index: int) -> float:
        if part == "total":
            return record["collection_each_s"][index] + record["update_each_s"][index]
        return record[f"{part}_each_s"][index]

    rounds = range(numerator["iterations_timed"])
    return statistics.median(seconds(reference, i) / seconds(numerator, i) for i in rounds)


def ratio_record(name: str, numerator: dict, reference: dict, args, threads: int, load: float) -> dict:
    """``numerator``'s decisions/s over ``reference``'s, and per part its speed over the reference's, each the
    median of the rounds' ratios (:func:`paired_ratio`)."""
    return {"name": name, "value": round(paired_ratio(numerator, reference, "total"), 3), "unit": "x",
            "update_ratio": round(paired_ratio(numerator, reference, "update"), 3),
            "collection_ratio": round(paired_ratio(numerator, reference, "collection"), 3),
            **_sitting(args, threads, load)}


def collection_time_record(name: str, numerator: dict, floor: dict, args, threads: int, load: float) -> dict:
    """``numerator``'s collection seconds over the floor's (a time ratio, as the collection target is stated),
    the median of the rounds' ratios."""
    return {"name": name, "value": round(paired_ratio(floor, numerator, "collection"), 3), "unit": "x time",
            **_sitting(args, threads, load)}


def _sitting(args, threads: int, load: float) -> dict:
    return {"num_envs": args.num_envs, "steps": args.steps, "compile": args.compile, "threads": threads,
            **({"settings": args.set} if args.set else {}),
            "load_average_1min_at_start": round(load, 2), "load_average_1min_at_end": round(os.getloadavg()[0], 2)}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_peer", description=__doc__.splitlines()[0])
    parser.add_argument("--num-envs", type=int, default=512)
    parser.add_argument("--steps", type=int, default=64, help="decisions per env per iteration")
    parser.add_argument("--minibatch", type=int, default=512, help="minibatch size (default 512, Table 2)")
    parser.add_argument("--iterations", type=int, default=4,
                        help="timed iterations per trainer (after one warm-up), in rounds of one of each")
    parser.add_argument("--compile", action=argparse.BooleanOptionalAction, default=True,
                        help="fuse the simulation step with torch.compile in both (default on, as training)")
    parser.add_argument("--threads", type=int, default=None, help="torch threads for both (default torch's)")
    parser.add_argument("--trainers", nargs="+", choices=tuple(TRAINERS), default=["agrl", "stable-baselines3"],
                        help="which trainers to time (default agrl and stable-baselines3; agrl: with the eager loss; "
                             "agrl-compiled: with the compiled loss, agrl's default; floor: the arithmetic in plain "
                             "PyTorch without rewards, resets or GAE; floor-equal-work: with them)")
    parser.add_argument("--task", default="fixed")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", nargs="+", default=[], metavar="KEY=VALUE",
                        help="Hydra overrides of conf/'s agent.* and ppo.* for every trainer (networks, epochs, "
                             "rates), e.g. --set 'agent.actor_hidden=[64,64]' 'agent.critic_hidden=[64,64]'")
    args = parser.parse_args(argv)
    for setting in args.set:
        key = setting.split("=", 1)[0]
        if "=" not in setting or not key.startswith(("agent.", "ppo.")) or key in BENCH_SET_KEYS:
            parser.error(f"--set {setting} is not allowed: KEY=VALUE with an agent.* or ppo.* key other than "
                         f"{', '.join(BENCH_SET_KEYS)} (--num-envs, --steps, --minibatch and --trainers set those)")
    for name in ("num_envs", "steps", "minibatch", "iterations"):
        if getattr(args, name) < 1 or (name == "iterations" and args.iterations < 2):
            parser.error(f"--{name.replace('_', '-')}={getattr(args, name)} is not allowed: a positive integer "
                         "(--iterations: at least 2)")
    if "stable-baselines3" in args.trainers:
        _sb3()
    torchrl_logs_to_stderr()
    import torch

    if args.threads is not None:
        torch.set_num_threads(args.threads)
    task = {"task": args.task}
    load = os.getloadavg()[0]
    iterations = {name: TRAINERS[name][0](args.num_envs, args.steps, args.minibatch, args.compile, args.seed, task,
                                          settings=tuple(args.set))
                  for name in dict.fromkeys(args.trainers)}
    try:
        timed = alternate(iterations, args.iterations)
    finally:
        for trainer in iterations.values():
            trainer.close()  # each trainer's own shutdown (collectors, envs)
    records = {}
    for name, (collection, update) in timed.items():
        records[name] = {**iteration_record(TRAINERS[name][1], collection, update, args.num_envs * args.steps),
                         "shape": f"{args.num_envs}x{args.steps}",  # envs x decisions each, per iteration
                         **({"settings": args.set} if args.set else {})}
        print(json.dumps(records[name]), flush=True)
    if "stable-baselines3" in records:
        for trainer in ("agrl", "agrl-compiled", "floor", "floor-equal-work"):
            if trainer in records:
                name = f"ratio_{trainer.replace('-', '_')}_over_sb3"
                print(json.dumps(ratio_record(name, records[trainer], records["stable-baselines3"], args,
                                        torch.get_num_threads(), load)), flush=True)
    for floor in ("floor", "floor-equal-work"):  # "floor": the speed targets (docs/benchmarks.md)
        if floor not in records:
            continue
        suffix = floor.replace("-", "_")
        for trainer in ("agrl", "agrl-compiled"):
            if trainer in records:
                label = trainer.replace("-", "_")
                print(json.dumps(ratio_record(f"ratio_{label}_over_{suffix}", records[trainer], records[floor],
                                              args, torch.get_num_threads(), load)), flush=True)
                print(json.dumps(collection_time_record(f"collection_time_{label}_over_{suffix}", records[trainer],
                                                        records[floor], args, torch.get_num_threads(), load)),
                      flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
