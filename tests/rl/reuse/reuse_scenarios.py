"""Hand-built scenarios, stand-in agents and independent checks shared by the policy-reuse tests.

The episodes are hand-built: the start box is a line, so every episode (and every auto-reset inside the
collector) starts from the same kind of scenario: the destination at the origin moving along +x at 50 m/s,
the aircraft 4-6 km behind it at 100 m altitude, flying the same way at 200 m/s. A baseline that flies
straight and accelerates while far from its target reaches the destination in six to ten decisions; the
agent being trained (random weights) mostly dives out of the airspace, so its batch holds short, long and
truncated episodes.

The collector rows get what the trainer gives them (GAE with a critic, then ``reshape(-1)``) and the transform
gets a ``ppo_targets`` like the trainer's (current-actor log-probability of the action, then GAE), which also
keeps a copy of the full re-played trajectories it receives (the buffer only keeps PPO's keys).
"""

from __future__ import annotations

import dataclasses

import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torchrl.collectors import Collector
from torchrl.modules import ProbabilisticActor
from torchrl.objectives.value import GAE

from agrl.core.observation import ABSOLUTE_OBSERVATION_FEATURES, policy_observation
from agrl.core.termination import Outcome
from agrl.envs import GuidanceEnv, GuidanceParameters, MotionKind
from agrl.rl.models import make_actor, make_critic
from agrl.rl.reuse import (
    PPO_KEYS,
    TRAJECTORY_KEY,
    PolicyReuseTransform,
    SearchResult,
    destination_prediction,
    relabelled_ppo_targets,
    search_candidates,
)

BUDGET = 20  # decisions per episode: keeps the eager simulation cheap
INTEGRATION_STEP = 0.3  # s: 10 integration steps per 3 s decision (conf's 0.02 s: 150), as in the tiny runs
NUM_ENVS = 4
STEP = 150.0  # m the 50 m/s destination moves in one 3 s decision
START = ((-6_000.0, -4_000.0), 0.0, 100.0)  # aircraft start: x range, y, z (m); heading +x, 200 m/s
FAR = 3_000.0  # m: the hand-built baseline accelerates while its target is farther than this

STEADY, LEFT, RIGHT, ACCELERATE, DECELERATE, PULL_UP, PUSH_OVER = range(7)
OWN_KEYS = [key for key in PPO_KEYS if key != "relabelled"]
#: The transform's knobs unless a test sets one: every episode selected (no decay), every step a candidate.
ALGORITHM_1 = {"initial_selection_factor": 1.0, "selection_decay": 0.0, "candidate_stride": 1, "keep": "earliest"}




def guidance_task(compose_parameters, kind: MotionKind = MotionKind.UNIFORM, start=START,
                  destination_start=(0.0, 0.0, 0.0, 0.0)) -> GuidanceParameters:
    """conf's task ``kind`` with the paper's reward and INTEGRATION_STEP, the destination at 50 m/s (curved: conf's
    1 km counter-clockwise circle; irregular: conf/task/irregular.yaml's redraws), starting at ``destination_start``,
    the aircraft in the hand-built ``start`` box and a budget of BUDGET."""
    (x_low, x_high), y, z = start
    speed = ("speed=50",) if kind in (MotionKind.UNIFORM, MotionKind.CURVED) else ()  # the tasks that use it
    task = compose_parameters(f"task={kind.value}", *speed, "reward=both",
                              f"simulation.integration_step={INTEGRATION_STEP}")
    return dataclasses.replace(
        task,
        destination=dataclasses.replace(task.destination, start=destination_start),
        initial_state=dataclasses.replace(
            task.initial_state, x_range=(x_low, x_high), y_range=(y, y), z_range=(z, z),
            speed_range=(200.0, 200.0),
        ),
        max_decisions=BUDGET,
    )


# ---------------------------------------------------------------------------- stand-in agents
class PursuitLogits(torch.nn.Module):
    """A hand-built fixed-destination agent B: turn towards the target, accelerate while it is far."""

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        distance = observation[..., 0] * 10_000.0  # feature 0 is distance / airspace half-width
        bearing_sin, bearing_cos = observation[..., 1], observation[..., 2]
        turn = torch.where(bearing_sin > 0, LEFT, RIGHT)  # left turns increase the heading
        action = torch.where(bearing_cos < 0.99, turn, torch.where(distance > FAR, ACCELERATE, STEADY))
        return 10.0 * torch.nn.functional.one_hot(action, 7).float()


class AbsolutePursuitLogits(torch.nn.Module):
    """PursuitLogits for a baseline that reads equation 4 as it stands (``agent.observation=absolute``) and was
    trained on the fixed destination at the origin: it flies to the origin, whatever the destination fields say."""

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        index = {name: i for i, name in enumerate(ABSOLUTE_OBSERVATION_FEATURES)}
        x, y = observation[..., index["x"]] * 10_000.0, observation[..., index["y"]] * 10_000.0  # [-10, 10] km
        heading = torch.atan2(observation[..., index["heading_sin"]], observation[..., index["heading_cos"]])
        bearing = torch.atan2(-y, -x) - heading
        turn = torch.where(torch.sin(bearing) > 0, LEFT, RIGHT)
        far = torch.sqrt(x * x + y * y) > FAR
        action = torch.where(torch.cos(bearing) < 0.99, turn, torch.where(far, ACCELERATE, STEADY))
        return 10.0 * torch.nn.functional.one_hot(action, 7).float()


class ConstantLogits(torch.nn.Module):
    def __init__(self, action: int):
        super().__init__()
        self.action = action

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        logits = torch.zeros(*observation.shape[:-1], 7)
        logits[..., self.action] = 5.0
        return logits


def as_actor(network: torch.nn.Module) -> ProbabilisticActor:
    return ProbabilisticActor(
        TensorDictModule(network, in_keys=["observation"], out_keys=["logits"]),
        in_keys=["logits"], out_keys=["action"], distribution_class=torch.distributions.Categorical,
        return_log_prob=True,
    )


def baseline_argmax(observation: torch.Tensor) -> torch.Tensor:
    """What the pursuit baseline picks in mode (deterministic) on ``observation``."""
    return PursuitLogits()(observation).argmax(-1)


class SkittishLogits(PursuitLogits):
    """Pursuit, but pull up when the target is within 2.5 km: B succeeds only if steered far enough ahead,
    so which t_n succeed depends on the predicted destination each candidate sees."""

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        near = observation[..., 0] * 10_000.0 < 2_500.0
        logits = super().forward(observation)
        pull_up = 10.0 * torch.nn.functional.one_hot(torch.tensor(PULL_UP), 7)
        return torch.where(near[..., None], pull_up, logits)


# ---------------------------------------------------------------------------- collected data
class Collected:
    """One collector batch of agent Z on a hand-built task, with GAE, as the trainer prepares it."""

    def __init__(self, params: GuidanceParameters, seed: int = 0):
        torch.manual_seed(seed)
        self.env = GuidanceEnv(params, num_envs=NUM_ENVS, seed=seed)
        self.actor = make_actor([32, 32], "tanh")
        self.critic = make_critic([32, 32], "tanh")
        self.gae = GAE(gamma=0.99, lmbda=0.95, value_network=self.critic, average_gae=False)
        self.replay_gae = GAE(gamma=0.99, lmbda=0.95, value_network=None, average_gae=False)
        collector = Collector(self.env, self.actor, frames_per_batch=NUM_ENVS * BUDGET, total_frames=-1,
                              auto_register_policy_transforms=False)
        data = next(iter(collector))
        collector.shutdown()
        with torch.no_grad():
            self.data = self.gae(data)
        self.received: list[TensorDict] = []

    def flat(self) -> TensorDict:
        return self.data.clone().reshape(-1)

    @torch.no_grad()
    def ppo_targets(self, trajectories, valid):
        """The trainer's PPO targets (current-actor log-prob, GAE), keeping a copy of its input."""
        self.received.append(trajectories.clone())
        self.received_valid = valid.clone()
        return relabelled_ppo_targets(trajectories, valid, critic=self.critic, advantage=self.replay_gae,
                                      actor=self.actor)

    def transform(self, baseline=None, **kwargs) -> PolicyReuseTransform:
        kwargs = {**ALGORITHM_1, "max_candidates": BUDGET, **kwargs}
        return PolicyReuseTransform(baseline if baseline is not None else as_actor(PursuitLogits()), self.env,
                                    ppo_targets=self.ppo_targets, **kwargs)


class Relabelled:
    """One ``relabel`` call with the pursuit baseline (keep the earliest successful t_n), and what it saw."""

    def __init__(self, collected: Collected):
        self.collected = collected
        self.flat = collected.flat()
        self.input = self.flat.clone()
        self.transform = collected.transform()
        collected.received.clear()
        self.out = self.transform.relabel(self.flat)
        assert len(collected.received) == 1, "ppo_targets is called once, on all re-played episodes"
        self.trajectories = collected.received[0]
        self.valid = collected.received_valid  # kept here: later relabel calls on `collected` overwrite it
        self.lengths = episode_lengths(self.trajectories)
        self.starts = starts_of(self.flat)


SPANNING_STEPS = 11  # decisions per env per batch: the 20-decision episodes span two or three batches


class Spanning:
    """Consecutive collector batches of an agent Z that circles left (it never arrives, so its episodes run
    to the budget or leave the airspace), 11 decisions per env each, with GAE as the trainer gives them."""

    def __init__(self, params: GuidanceParameters, batches: int = 4):
        torch.manual_seed(1)
        self.env = GuidanceEnv(params, num_envs=NUM_ENVS, seed=1)
        critic = make_critic([32, 32], "tanh")
        gae = GAE(gamma=0.99, lmbda=0.95, value_network=critic, average_gae=False)
        self.replay_gae = GAE(gamma=0.99, lmbda=0.95, value_network=None, average_gae=False)
        self.critic = critic
        collector = Collector(self.env, as_actor(ConstantLogits(LEFT)), frames_per_batch=NUM_ENVS * SPANNING_STEPS,
                              total_frames=-1, auto_register_policy_transforms=False)
        self.batches = []
        for data in collector:
            with torch.no_grad():
                self.batches.append(gae(data).reshape(-1))
            if len(self.batches) == batches:
                break
        collector.shutdown()
        self.received: list[tuple[TensorDict, torch.Tensor]] = []

    @torch.no_grad()
    def ppo_targets(self, trajectories, valid):
        self.received.append((trajectories.clone(), valid.clone()))
        return relabelled_ppo_targets(trajectories, valid, critic=self.critic, advantage=self.replay_gae)

    def transform(self, **kwargs) -> PolicyReuseTransform:
        kwargs = {**ALGORITHM_1, "max_candidates": BUDGET, **kwargs}
        return PolicyReuseTransform(as_actor(SkittishLogits()), self.env, ppo_targets=self.ppo_targets, **kwargs)

    def batch_of(self) -> dict[int, int]:
        """Episode (collector trajectory id) -> the batch it starts in."""
        first = {}
        for number, batch in enumerate(self.batches):
            for trajectory in batch.get(TRAJECTORY_KEY)[batch["step_count"] == 0].tolist():
                first.setdefault(trajectory, number)
        return first

    def start_of(self, trajectory: int) -> TensorDict:
        for batch in self.batches:
            row = (batch.get(TRAJECTORY_KEY) == trajectory) & (batch["step_count"] == 0)
            if bool(row.any()):
                return batch[row.nonzero()[0, 0]]
        raise AssertionError(f"episode {trajectory} has no start row")



# ---------------------------------------------------------------------------- independent checks
def episode_lengths(trajectories: TensorDict) -> torch.Tensor:
    """Decisions up to and including the first terminal one, per re-played episode."""
    done = trajectories["next", "done"].squeeze(-1)
    assert bool(done.any(-1).all()), "every stored re-played episode must end"
    return done.long().argmax(-1) + 1


def replay_in_fresh_env(start: TensorDict, actions: torch.Tensor, params: GuidanceParameters) -> TensorDict:
    """An independent rollout: a new env of ``params`` started from ``start``'s scenario, stepping ``actions``
    (E, T)."""
    episodes, steps = actions.shape
    env = GuidanceEnv(params, num_envs=episodes, seed=123)
    td = env.reset(env.scenario(
        aircraft_state=start["aircraft_state"], destination_state=start["destination_state"],
        destination_speed=start["destination_speed"], destination_turn_rate=start["destination_turn_rate"],
    ))
    out = []
    for step in range(steps):
        td["action"] = actions[:, step]
        td = env.step(td)
        out.append(td.clone())
        td = env.step_mdp(td)
    return torch.stack(out, 1)


def own_rows(rows: TensorDict) -> TensorDict:
    """What the buffer gets for rows that are not relabelled: PPO's keys, flagged as the agent's own."""
    return rows.select(*OWN_KEYS).set("relabelled", torch.zeros(rows.numel(), dtype=torch.bool))


def starts_of(rows: TensorDict) -> torch.Tensor:
    return (rows["step_count"] == 0).nonzero().squeeze(-1)


def kept_candidates(transform: PolicyReuseTransform, rows: TensorDict,
                    starts: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, SearchResult]:
    """The transform's prediction and search for the episodes starting at ``starts`` of the flat collector ``rows``
    (the public functions, with the transform's grid, ``keep``, B and environment): ``(prediction, motion,
    search result)``."""
    params = transform.env.params
    prediction, motion = destination_prediction(rows, starts, rows.get(TRAJECTORY_KEY), params)
    result = search_candidates(rows[starts], prediction, motion, candidates=transform.candidates,
                               keep=transform.keep, baseline=transform.baseline, simulator=transform.env.simulator,
                               max_decisions=params.max_decisions)
    return prediction, motion, result


def brute_force_search(grid: torch.Tensor, starts: torch.Tensor,
                       params: GuidanceParameters) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Each (episode, candidate t_n) on its own row of a fresh env of ``params``: B (:class:`SkittishLogits`)
    steered to the destination's position at t_n, for at most ``t_n + spacing`` decisions. Returns arrival steps
    ``(E, C)`` (0 = no success), B's actions ``(E, C, BUDGET)`` and the aircraft state after each step
    ``(E, C, BUDGET, 7)``."""
    episodes, candidates = starts.shape[0], grid.numel()
    spacing = int(grid[1] - grid[0]) if candidates > 1 else 1
    env = GuidanceEnv(params, num_envs=episodes * candidates, seed=11)
    td = env.reset(env.scenario(aircraft_state=starts.repeat_interleave(candidates, 0)))
    target = torch.zeros(episodes * candidates, 4)
    target[:, 0] = STEP * grid.float().repeat(episodes)
    limit = (grid + spacing).clamp(max=BUDGET).repeat(episodes)
    arrival = torch.zeros(episodes * candidates, dtype=torch.long)
    running = torch.ones(episodes * candidates, dtype=torch.bool)
    actions = torch.zeros(episodes * candidates, BUDGET, dtype=torch.long)
    aircraft = torch.zeros(episodes * candidates, BUDGET, 7)
    simulation = env.params.simulation
    for step in range(BUDGET):
        if not bool(running.any()):
            break
        observed = policy_observation(td["aircraft_state"], target, td["last_action"], simulation.airspace,
                                      simulation.limits)
        td["action"] = SkittishLogits()(observed).argmax(-1)
        actions[:, step] = td["action"]
        td = env.step(td)
        aircraft[:, step] = td["next", "aircraft_state"]
        success = running & (td["next", "outcome"] == Outcome.SUCCESS)
        arrival[success] = step + 1
        running &= (td["next", "outcome"] == Outcome.RUNNING) & (step + 1 < limit)
        td = env.step_mdp(td)
    return (arrival.reshape(episodes, candidates), actions.reshape(episodes, candidates, BUDGET),
            aircraft.reshape(episodes, candidates, BUDGET, 7))


def ended_in(batch: TensorDict) -> set[int]:
    """The episodes (trajectory ids) whose last row in ``batch`` is terminal: they end in this batch."""
    traj_ids, done = batch.get(TRAJECTORY_KEY), batch["next", "done"].reshape(-1)
    return {t for t in set(traj_ids.tolist()) if bool(done[(traj_ids == t).nonzero()[-1, 0]])}


