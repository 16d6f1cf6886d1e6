"""Policy reuse by destination position prediction (the paper's Algorithm 1) as a replay-buffer transform.

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
import json
import math
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.modules import ProbabilisticActor
from torchrl.objectives.value import GAE

from agrl.core.destinations import DestinationState, move_destination
from agrl.core.observation import (
    ABSOLUTE_OBSERVATION_FEATURES,
    OBSERVATION_SIZE,
    absolute_observation,
    in_destination_frame,
    policy_observation,
)
from agrl.core.reward import step_reward
from agrl.core.termination import Outcome
from agrl.envs import GuidanceEnv, GuidanceParameters, MotionKind
from agrl.rl.checkpoint import save_checkpoint
from agrl.rl.models import make_actor, make_critic
from agrl.rl.reuse import PPO_KEYS, TRAJECTORY_KEY, PolicyReuseTransform, candidate_steps, relabelled_ppo_targets

BUDGET = 20  # decisions per episode: keeps the eager simulation cheap
NUM_ENVS = 4
STEP = 150.0  # m the 50 m/s destination moves in one 3 s decision
START = ((-6_000.0, -4_000.0), 0.0, 100.0)  # aircraft start: x range, y, z (m); heading +x, 200 m/s
FAR = 3_000.0  # m: the hand-built baseline accelerates while its target is farther than this

STEADY, LEFT, RIGHT, ACCELERATE, DECELERATE, PULL_UP, PUSH_OVER = range(7)
OWN_KEYS = [key for key in PPO_KEYS if key != "relabelled"]
#: The transform's knobs unless a test sets one: every episode selected (no decay), every step a candidate.
ALGORITHM_1 = {"initial_selection_factor": 1.0, "selection_decay": 0.0, "candidate_stride": 1, "keep": "earliest"}


# ---------------------------------------------------------------------------- stand-in agents and data
@pytest.fixture(scope="module")
def task_params(compose_parameters):
    """``task_params(kind, start, destination_start)``: conf's task ``kind`` with the paper's reward, the destination
    at 50 m/s (curved: conf's 1 km counter-clockwise circle; irregular: conf/task/irregular.yaml's redraws),
    starting at ``destination_start``, the aircraft in the hand-built ``start`` box and a budget of BUDGET."""

    def make(kind: MotionKind = MotionKind.UNIFORM, start=START,
             destination_start=(0.0, 0.0, 0.0, 0.0)) -> GuidanceParameters:
        (x_low, x_high), y, z = start
        speed = ("speed=50",) if kind in (MotionKind.UNIFORM, MotionKind.CURVED) else ()  # the tasks that use it
        task = compose_parameters(f"task={kind.value}", *speed, "reward=both")
        return dataclasses.replace(
            task,
            destination=dataclasses.replace(task.destination, start=destination_start),
            initial_state=dataclasses.replace(
                task.initial_state, x_range=(x_low, x_high), y_range=(y, y), z_range=(z, z),
                speed_range=(200.0, 200.0),
            ),
            max_decisions=BUDGET,
        )

    return make


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
        """The trainer's ``_ppo_targets`` (current-actor log-prob, GAE), keeping a copy of its input."""
        self.received.append(trajectories.clone())
        self.received_valid = valid.clone()
        return relabelled_ppo_targets(trajectories, valid, critic=self.critic, advantage=self.replay_gae,
                                      actor=self.actor)

    def transform(self, baseline=None, **kwargs) -> PolicyReuseTransform:
        kwargs = {**ALGORITHM_1, "max_candidates": BUDGET, **kwargs}
        return PolicyReuseTransform(baseline if baseline is not None else as_actor(PursuitLogits()), self.env,
                                    ppo_targets=self.ppo_targets, **kwargs)


@pytest.fixture(scope="module")
def uniform(torch_one_thread, task_params) -> Collected:
    return Collected(task_params(MotionKind.UNIFORM))


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


@pytest.fixture(scope="module")
def relabelled(uniform) -> Relabelled:
    return Relabelled(uniform)


@pytest.fixture(scope="module")
def fixed(torch_one_thread, task_params) -> Collected:
    # 3 km from a fixed destination: flying straight, the baseline arrives at the fourth decision.
    return Collected(task_params(MotionKind.FIXED, start=((-3_000.0, -3_000.0), 0.0, 100.0)))


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


# ---------------------------------------------------------------------------- the candidate grid
@pytest.mark.parametrize(
    ("budget", "stride", "cap"),
    [(20, 1, 64), (20, 1, 4), (20, 3, 64), (200, 1, 64), (200, 7, 10), (200, 1, 2), (5, 5, 3), (201, 4, 50)],
)
def test_candidate_steps_grid(budget, stride, cap):
    grid = candidate_steps(budget, stride, cap)
    full = list(range(stride, budget + 1, stride))
    assert grid.dtype == torch.int64
    assert grid.numel() == min(cap, len(full))
    assert bool((grid % stride == 0).all()), "candidates lie on the stride"
    assert bool((grid >= stride).all()) and bool((grid <= budget).all()), "within [stride, budget]"
    assert bool((grid[1:] > grid[:-1]).all()), "strictly increasing, no duplicates"
    assert int(grid[0]) == full[0] and int(grid[-1]) == full[-1], "the grid spans the whole budget"
    if cap >= len(full):
        assert grid.tolist() == full
    else:  # evenly spread: no gap is more than one stride wider than another
        gaps = grid.diff()
        assert int(gaps.max() - gaps.min()) <= stride


def test_transform_uses_the_grid_of_its_env(uniform):
    transform = uniform.transform(candidate_stride=3, max_candidates=4)
    assert transform.candidates.tolist() == candidate_steps(BUDGET, 3, 4).tolist()


# ---------------------------------------------------------------------------- the hand-built episode
def test_relabelled_tuples_carry_the_real_destination_trajectory(relabelled):
    flat, out, trajectories = relabelled.flat, relabelled.out, relabelled.trajectories
    starts = relabelled.starts
    assert (flat == relabelled.input).all(), "relabel does not write into its input"
    assert trajectories.shape[0] == starts.numel(), "every episode starting in the batch was relabelled"
    assert starts.numel() > NUM_ENVS, "some episodes start mid-batch (after the agent's own failures)"
    lengths = relabelled.lengths
    steps = int(lengths.max())
    actions = trajectories["action"][:, :steps]

    real = replay_in_fresh_env(flat[starts], actions, relabelled.collected.env.params)
    for episode in range(starts.numel()):
        length = int(lengths[episode])
        got, want = trajectories[episode, :length], real[episode, :length]
        for key in ("aircraft_state", "destination_state", "observation", "last_action", "step_count"):
            torch.testing.assert_close(got[key], want[key], rtol=0, atol=0, msg=key)
        for key in ("aircraft_state", "destination_state", "observation", "reward", "done", "terminated",
                    "outcome", "episode_return"):
            torch.testing.assert_close(got["next", key], want["next", key], rtol=0, atol=0, msg=f"next {key}")
        # (Bitwise: the re-simulation is the environment's own transition.)
        # The destination fields are the destination's own trajectory: straight along +x at 50 m/s, not the
        # predicted (fixed) point the baseline was steered by. Success freezes it inside the last decision.
        x = torch.cat((got["destination_state"][:, 0], got["next", "destination_state"][-1:, 0]))
        torch.testing.assert_close(x[:-1], STEP * torch.arange(length, dtype=torch.float32))
        assert 0 < float(x[-1] - x[-2]) <= STEP + 1e-3
        torch.testing.assert_close(got["destination_state"][:, 1:], torch.zeros(length, 3))

    # What the buffer receives for those rows is exactly these transitions, episode after episode.
    relabelled = out[out["relabelled"]]
    valid = torch.arange(trajectories.shape[1])[None, :] < lengths[:, None]
    torch.testing.assert_close(relabelled["observation"], trajectories["observation"][valid])
    assert torch.equal(relabelled["action"], trajectories["action"][valid])


def test_actions_are_the_baselines_on_the_predicted_destination(relabelled):
    flat, trajectories, lengths = relabelled.flat, relabelled.trajectories, relabelled.lengths
    uniform, transform, starts = relabelled.collected, relabelled.transform, relabelled.starts
    # The kept termination step t_n of each episode (the transform's own search; deterministic).
    prediction, motion = transform._destination_prediction(flat, starts, flat.get(TRAJECTORY_KEY))
    _, winner = transform._search(flat[starts], prediction, motion)
    assert bool((winner >= 0).all())
    target_step = transform.candidates[winner]
    # The prediction at t_n is where the destination really is at t_n (equation 19: it ignores the aircraft).
    expected_target = torch.zeros(starts.numel(), 4)
    expected_target[:, 0] = STEP * target_step.float()
    torch.testing.assert_close(prediction[torch.arange(starts.numel()), target_step], expected_target)

    simulation = uniform.env.params.simulation
    differs = 0
    for episode in range(starts.numel()):
        rows = trajectories[episode, : int(lengths[episode])]
        # Equation 20: the destination fields replaced by the destination state at t_n.
        target = expected_target[episode].expand(rows.shape[0], 4)
        observed = policy_observation(rows["aircraft_state"], target, rows["last_action"],
                                      simulation.airspace, simulation.limits)
        assert torch.equal(rows["action"], baseline_argmax(observed))
        differs += int((baseline_argmax(rows["observation"]) != rows["action"]).sum())
    assert differs > 0, "the scenario must tell the predicted destination from the real one"


def test_an_absolute_baseline_is_queried_in_the_predicted_destinations_frame(uniform):
    """Section 5.1: B, trained with equation 4 on the destination at the origin, sees the state moved into the
    predicted destination's frame, so a B that only ever flies to the origin catches the moving destination."""
    flat = uniform.flat()
    transform = uniform.transform(as_actor(AbsolutePursuitLogits()), baseline_observation="absolute")
    uniform.received.clear()
    transform.relabel(flat)
    stats = transform.last_statistics()
    assert stats["train/reuse_episodes_relabelled"] > 0 and stats["train/reuse_fraction"] > 0
    trajectories, valid = uniform.received[0], uniform.received_valid
    starts = starts_of(flat)
    prediction, motion = transform._destination_prediction(flat, starts, flat.get(TRAJECTORY_KEY))
    _, winner = transform._search(flat[starts], prediction, motion)
    target = prediction[winner >= 0, transform.candidates[winner[winner >= 0]]]
    rows = trajectories[valid]
    moved, origin = in_destination_frame(rows["aircraft_state"],
                                         target[:, None].expand(*valid.shape, 4)[valid])
    simulation = uniform.env.params.simulation
    observed = absolute_observation(moved, origin, rows["last_action"], simulation.airspace, simulation.limits)
    assert torch.equal(rows["action"], AbsolutePursuitLogits()(observed).argmax(-1))
    # Queried on the real (absolute) state instead, it would head for the origin and miss the destination.
    plain = absolute_observation(rows["aircraft_state"], target[:, None].expand(*valid.shape, 4)[valid],
                                 rows["last_action"], simulation.airspace, simulation.limits)
    assert bool((AbsolutePursuitLogits()(plain).argmax(-1) != rows["action"]).any())


def test_baseline_acts_by_its_mode_on_the_predicted_destination(uniform):
    """B's action is the argmax of its logits on the rewritten observation, never a sample."""
    torch.manual_seed(5)
    baseline = make_actor([16], "tanh")
    with torch.no_grad():
        baseline.module[0].module[-1].weight.mul_(300.0)  # undo make_actor's near-uniform output layer
    transform = uniform.transform(baseline)
    flat = uniform.flat()
    count = flat.numel()
    predicted = torch.stack((torch.linspace(-8e3, 8e3, count), torch.linspace(5e3, -5e3, count),
                             torch.full((count,), 1e3), torch.linspace(-3, 3, count)), -1)
    simulation = uniform.env.params.simulation
    observed = policy_observation(flat["aircraft_state"], predicted, flat["last_action"], simulation.airspace,
                                  simulation.limits)
    logits = baseline.module[0](TensorDict({"observation": observed}, [flat.numel()]))["logits"]
    assert float(logits.softmax(-1).max(-1).values.median()) < 0.9, "sampling would be seen"
    with set_exploration_type(ExplorationType.RANDOM):  # whatever the caller's setting
        for _ in range(3):
            assert torch.equal(transform._baseline_actions(flat, predicted), logits.argmax(-1))


class TiedLogits(torch.nn.Module):
    """Logits with exact ties between two maneuvers: the mode must break them as the actor does."""

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        logits = torch.zeros(*observation.shape[:-1], 7)
        logits[..., LEFT] = logits[..., RIGHT] = torch.where(observation[..., 0] > 0, 3.0, -3.0)
        return logits


@pytest.mark.parametrize("network", ["mlp", "tied", "actor"])
def test_direct_logits_query_equals_the_actor_in_deterministic_mode(uniform, network):
    """The search calls B's logits network directly (no TensorDict, no distribution module); its actions and
    log-probabilities are the ones B's TorchRL actor gives in deterministic mode, bitwise. ``actor``: the path
    for actors whose logits network is not found, which queries the actor itself."""
    torch.manual_seed(3)
    if network == "tied":
        baseline = as_actor(TiedLogits())
    else:
        baseline = make_actor([16], "tanh")
        with torch.no_grad():
            baseline.module[0].module[-1].weight.mul_(300.0)  # confident and varied, as a trained B
    transform = uniform.transform(baseline)
    assert transform._baseline_logits is not None, "the actor's logits network is found"
    if network == "actor":
        transform._baseline_logits = None
    observation = torch.randn(4_096, OBSERVATION_SIZE)
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        expected = baseline(TensorDict({"observation": observation}, [observation.shape[0]]))
    assert expected["action"].unique().numel() > 1
    with set_exploration_type(ExplorationType.RANDOM):  # whatever the caller's setting
        assert torch.equal(transform._baseline_mode(observation), expected["action"])
        action, log_prob = transform._baseline_mode_and_log_prob(observation)
    assert torch.equal(action, expected["action"])
    assert torch.equal(log_prob, expected["action_log_prob"])


def test_success_ends_each_relabelled_episode_and_gae_does_not_look_past_it(relabelled):
    out, trajectories, lengths = relabelled.out, relabelled.trajectories, relabelled.lengths
    index = torch.arange(trajectories.shape[0])
    last = trajectories[index, lengths - 1]
    assert bool((last["next", "outcome"] == Outcome.SUCCESS).all()), "the stored episode ends at a success"
    before = torch.arange(trajectories.shape[1])[None, :] < (lengths - 1)[:, None]
    assert not bool(trajectories["next", "done"].squeeze(-1)[before].any()), "nothing terminal before it"
    rows = out[out["relabelled"]]
    assert rows.numel() == int(lengths.sum()), "no row after the success is stored"
    # Episode by episode the last stored row is the success step: its target is the reward, no bootstrap.
    ends = lengths.cumsum(0) - 1
    torch.testing.assert_close(rows["value_target"][ends], last["next", "reward"])
    torch.testing.assert_close(rows["advantage"][ends], last["next", "reward"] - rows["state_value"][ends])
    # The behaviour log-probability is the current actor's for B's action (PPO's ratio starts at 1).
    expected = relabelled.collected.actor.get_dist(rows).log_prob(rows["action"])
    torch.testing.assert_close(rows["action_log_prob"], expected)


def test_ppo_targets_on_valid_rows_equal_gae_on_the_whole_table(relabelled):
    """The critic runs on the valid rows only; the advantages equal TorchRL's GAE run on the padded table."""
    collected = relabelled.collected
    trajectories, valid = relabelled.trajectories.clone(), relabelled.valid
    assert bool(valid.any()) and not bool(valid.all()), "the table holds padding"
    masked = relabelled_ppo_targets(trajectories.clone(), valid, critic=collected.critic,
                                    advantage=collected.replay_gae)
    with torch.no_grad():
        full = collected.gae(trajectories.clone())
    for key in ("state_value", ("next", "state_value"), "advantage", "value_target"):
        torch.testing.assert_close(masked[key][valid], full[key][valid])
    # Without an actor the behaviour log-probability is B's own.
    torch.testing.assert_close(masked["action_log_prob"], trajectories["baseline_log_prob"])


def test_rewards_are_the_environments_for_the_real_destination(relabelled):
    """Equation 5 on the real destination fields (the independent env replay checks the same numbers)."""
    trajectories, lengths = relabelled.trajectories, relabelled.lengths
    reward_params = relabelled.collected.env.params.reward

    for episode in range(trajectories.shape[0]):
        rows = trajectories[episode, : int(lengths[episode])]
        expected, _ = step_reward(rows["next", "outcome"], rows["aircraft_state"], rows["destination_state"],
                                  rows["last_action"], rows["action_before_last"], rows["action"],
                                  rows["next", "aircraft_state"], rows["next", "destination_state"], reward_params)
        torch.testing.assert_close(rows["next", "reward"].squeeze(-1), expected)
        assert float(rows["next", "reward"][-1]) > 10.0, "the success pays c1"


# ---------------------------------------------------------------------------- what is kept
def test_own_rows_of_untouched_episodes_are_kept_verbatim(uniform):
    flat = uniform.flat()
    transform = uniform.transform(initial_selection_factor=0.5, seed=3)
    out = transform.relabel(flat)
    stats = transform.last_statistics()
    starts = starts_of(flat)
    assert 0 < stats["train/reuse_episodes_relabelled"] < starts.numel(), "a mixed batch"
    own = out[~out["relabelled"]]
    assert bool(out["relabelled"][own.numel():].all()), "own rows first, then the re-played ones"
    # Match each own row to its collector row (observations are continuous: exact matches are unique).
    same = (own["observation"][:, None] == flat["observation"][None]).all(-1) & (
        own["action"][:, None] == flat["action"][None])
    assert bool((same.sum(-1) == 1).all())
    source = same.long().argmax(-1)
    assert bool((source.diff() > 0).all()), "in the collector's order"
    for key in OWN_KEYS:
        assert torch.equal(own[key], flat[key][source]), key
    # Whole episodes are dropped, exactly the relabelled ones, each starting in this batch.
    traj_ids = flat.get(TRAJECTORY_KEY)
    dropped = set(traj_ids.tolist()) - set(traj_ids[source].tolist())
    assert len(dropped) == stats["train/reuse_episodes_relabelled"]
    assert dropped <= set(traj_ids[starts].tolist())
    assert set(traj_ids[source].tolist()).isdisjoint(dropped)
    kept_ids = torch.tensor(sorted(set(traj_ids.tolist()) - dropped))
    assert source.numel() == int(torch.isin(traj_ids, kept_ids).sum())


def test_a_baseline_that_never_succeeds_leaves_the_batch_unchanged(uniform):
    flat = uniform.flat()
    transform = uniform.transform(as_actor(ConstantLogits(PUSH_OVER)))  # dives into the ground
    out = transform.relabel(flat)
    stats = transform.last_statistics()
    assert stats["train/reuse_episodes_selected"] == starts_of(flat).numel()
    assert stats["train/reuse_episodes_relabelled"] == 0 and stats["train/reuse_fraction"] == 0.0
    assert (out == own_rows(flat)).all()


# ---------------------------------------------------------------------------- the selection factor e
def test_with_e_zero_nothing_is_relabelled(uniform):
    flat = uniform.flat()
    uniform.received.clear()
    transform = uniform.transform(initial_selection_factor=0.0, selection_decay=0.1)
    out = transform.relabel(flat)
    expected = own_rows(flat)
    assert out.batch_size == flat.batch_size
    assert set(out.keys()) == set(PPO_KEYS)
    assert (out == expected).all()
    assert uniform.received == [], "no episode was re-played"
    assert transform.last_statistics()["train/e"] == 0.0
    assert transform.last_statistics()["train/reuse_fraction"] == 0.0
    assert transform.last_statistics()["train/reuse_episodes_selected"] == 0


def test_e_drops_by_k_per_selected_episode_and_stops_at_zero(uniform):
    flat = uniform.flat()
    episodes = starts_of(flat).numel()
    never = as_actor(ConstantLogits(PUSH_OVER))  # cheap: its candidates end after a decision or two
    transform = uniform.transform(never, initial_selection_factor=1.0, selection_decay=0.05)
    transform.relabel(flat)
    stats = transform.last_statistics()
    assert stats["train/reuse_episodes_selected"] == episodes, "e = 1 selects every episode"
    assert stats["train/e"] == pytest.approx(1.0 - 0.05 * episodes)
    assert transform.selection_factor == pytest.approx(1.0 - 0.05 * episodes)

    # Fractional e: the decay counts the episodes actually selected (u < e), whether or not they succeed.
    for _ in range(3):
        before = transform.selection_factor
        transform.relabel(flat)
        stats = transform.last_statistics()
        assert 0 <= stats["train/reuse_episodes_selected"] <= episodes
        selected = stats["train/reuse_episodes_selected"]
        assert stats["train/e"] == pytest.approx(max(0.0, before - 0.05 * selected))

    floor = uniform.transform(never, initial_selection_factor=1.0, selection_decay=0.3)
    assert floor.selection_factor == 1.0, "e starts at initial_selection_factor"
    floor.relabel(flat)  # 1 - 0.3 * episodes < 0
    assert floor.selection_factor == 0.0 and floor.last_statistics()["train/e"] == 0.0
    floor.relabel(flat)
    assert floor.last_statistics()["train/reuse_episodes_selected"] == 0
    assert floor.selection_factor == 0.0


def test_selection_is_seeded_and_restored_from_state_dict(uniform):
    flat = uniform.flat()
    never = as_actor(ConstantLogits(PUSH_OVER))
    a = uniform.transform(never, initial_selection_factor=0.6, selection_decay=0.01, seed=7)
    a.relabel(flat)
    saved = a.state_dict()
    a.relabel(flat)
    b = uniform.transform(never, initial_selection_factor=1.0, selection_decay=0.01, seed=0)
    b.load_state_dict(saved)
    b.relabel(flat)
    assert a.last_statistics()["train/reuse_episodes_selected"] == b.last_statistics()[
        "train/reuse_episodes_selected"]
    assert a.selection_factor == b.selection_factor


@pytest.mark.parametrize("max_rows", [None, 40])
def test_reuse_fraction_is_the_share_of_relabelled_rows_in_the_output(relabelled, max_rows):
    if max_rows is None:
        transform, out = relabelled.transform, relabelled.out
    else:  # the buffer's cap cuts re-played rows: the statistic describes what is stored
        transform = relabelled.collected.transform(max_rows=max_rows)
        out = transform.relabel(relabelled.flat)
    stats = transform.last_statistics()
    assert stats["train/reuse_episodes_relabelled"] > 0
    assert max_rows is None or out.numel() == max_rows
    assert stats["train/reuse_fraction"] == pytest.approx(float(out["relabelled"].float().mean()))
    assert 0.0 < stats["train/reuse_fraction"] <= 1.0


def test_episodes_past_max_rows_are_not_replayed_and_the_output_is_the_cut_one(relabelled):
    """Not re-playing episodes that would fall past ``max_rows`` saves work and changes nothing stored."""
    uncut = relabelled.out
    relabelled.collected.received.clear()
    transform = relabelled.collected.transform(max_rows=40)
    cut = transform.relabel(relabelled.flat)
    assert cut.numel() == 40 < uncut.numel()
    assert (cut == uncut[:40]).all()
    replayed = relabelled.collected.received[0].batch_size[0]
    assert replayed < relabelled.trajectories.batch_size[0], "fewer episodes were re-played"
    assert transform.last_statistics()["train/reuse_episodes_relabelled"] == replayed


# ---------------------------------------------------------------------------- which candidate is kept
class SkittishLogits(PursuitLogits):
    """Pursuit, but pull up when the target is within 2.5 km: B succeeds only if steered far enough ahead,
    so which t_n succeed depends on the predicted destination each candidate sees."""

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        near = observation[..., 0] * 10_000.0 < 2_500.0
        logits = super().forward(observation)
        pull_up = 10.0 * torch.nn.functional.one_hot(torch.tensor(PULL_UP), 7)
        return torch.where(near[..., None], pull_up, logits)


def brute_force_search(grid: torch.Tensor, starts: torch.Tensor,
                       params: GuidanceParameters) -> tuple[torch.Tensor, torch.Tensor]:
    """Each (episode, candidate t_n) on its own row of a fresh env of ``params``: B steered to the destination's
    position at t_n, for at most ``t_n + spacing`` decisions. Returns arrival steps ``(E, C)`` (0 = no success)
    and B's actions ``(E, C, BUDGET)``."""
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
    simulation = env.params.simulation
    for step in range(BUDGET):
        if not bool(running.any()):
            break
        observed = policy_observation(td["aircraft_state"], target, td["last_action"], simulation.airspace,
                                      simulation.limits)
        td["action"] = SkittishLogits()(observed).argmax(-1)
        actions[:, step] = td["action"]
        td = env.step(td)
        success = running & (td["next", "outcome"] == Outcome.SUCCESS)
        arrival[success] = step + 1
        running &= (td["next", "outcome"] == Outcome.RUNNING) & (step + 1 < limit)
        td = env.step_mdp(td)
    return arrival.reshape(episodes, candidates), actions.reshape(episodes, candidates, BUDGET)


@pytest.mark.parametrize(("keep", "stride", "cap"), [("earliest", 1, BUDGET), ("latest", 1, BUDGET),
                                                      ("earliest", 2, 6)])
def test_search_keeps_the_earliest_or_latest_successful_candidate(uniform, keep, stride, cap):
    """The batched search (all episodes and candidates at once, pruned) against one rollout per candidate."""
    transform = uniform.transform(as_actor(SkittishLogits()), keep=keep, candidate_stride=stride,
                                  max_candidates=cap)
    aircraft = torch.tensor([[x, 0.0, 100.0, 200.0, 0.0, 0.0, 0.0] for x in (-6_000.0, -5_000.0, -4_000.0)])
    env = GuidanceEnv(uniform.env.params, num_envs=aircraft.shape[0], seed=0)
    start_rows = env.reset(env.scenario(aircraft_state=aircraft))
    trajectory = torch.zeros(aircraft.shape[0], BUDGET + 1, 4)
    trajectory[..., 0] = STEP * torch.arange(BUDGET + 1, dtype=torch.float32)
    motion = torch.tensor([50.0, 0.0]).expand(aircraft.shape[0], BUDGET, 2)
    arrival, winner = transform._search(start_rows, trajectory, motion)

    brute, _ = brute_force_search(transform.candidates, aircraft, uniform.env.params)
    for episode in range(aircraft.shape[0]):
        succeeded = (brute[episode] > 0).nonzero().squeeze(-1)
        assert 2 <= succeeded.numel() < transform.candidates.numel(), "some candidates succeed, not all"
        expected = succeeded.min() if keep == "earliest" else succeeded.max()
        assert int(winner[episode]) == int(expected), episode
        assert int(arrival[episode]) == int(brute[episode, expected]), episode


def test_earliest_and_latest_differ_when_every_candidate_succeeds(fixed):
    flat = fixed.flat()
    starts = starts_of(flat)
    results = {}
    for keep in ("earliest", "latest"):
        transform = fixed.transform(keep=keep, max_candidates=4)  # t_n in {1, 7, 14, 20}, spacing 6
        prediction, motion = transform._destination_prediction(flat, starts, flat.get(TRAJECTORY_KEY))
        # A fixed destination: the prediction is its position, whatever t_n.
        position = flat["destination_state"][starts][:, None]
        torch.testing.assert_close(prediction, position.expand_as(prediction))
        results[keep] = transform._search(flat[starts], prediction, motion)
    assert results["earliest"][1].tolist() == [0] * starts.numel()
    assert results["latest"][1].tolist() == [3] * starts.numel()
    # Same arrival (the steered point is the same): the kept re-played episodes are the same too.
    assert torch.equal(results["earliest"][0], results["latest"][0])
    assert bool((results["earliest"][0] == 4).all())


def test_keep_changes_the_relabelled_actions_on_a_moving_destination(relabelled):
    latest_out = relabelled.collected.transform(keep="latest").relabel(relabelled.flat)
    outs = {"earliest": relabelled.out, "latest": latest_out}
    earliest, latest = (outs[k][outs[k]["relabelled"]] for k in ("earliest", "latest"))
    # Steered at a farther predicted point, the latest candidate accelerates for longer.
    assert int((latest["action"] == ACCELERATE).sum()) > int((earliest["action"] == ACCELERATE).sum())


def test_rejects_an_unknown_keep(uniform):
    with pytest.raises(ValueError, match="keep"):
        uniform.transform(keep="best")


# ---------------------------------------------------------------------------- prediction past the episode
@pytest.mark.parametrize("kind", [MotionKind.UNIFORM, MotionKind.FIXED])
def test_prediction_past_the_episode_follows_the_motion_model(uniform, fixed, kind):
    collected = uniform if kind is MotionKind.UNIFORM else fixed
    flat = collected.flat()
    transform = collected.transform()
    starts = starts_of(flat)
    prediction, motion = transform._destination_prediction(flat, starts, flat.get(TRAJECTORY_KEY))
    assert prediction.shape == (starts.numel(), BUDGET + 1, 4) and motion.shape == (starts.numel(), BUDGET, 2)
    # Episodes that end early (the agent dives out) and episodes cut by the batch's end are both there.
    traj_ids = flat.get(TRAJECTORY_KEY)
    recorded = torch.stack([(traj_ids == traj_ids[s]).sum() for s in starts])
    assert bool((recorded < BUDGET).any())
    start = flat["destination_state"][starts]
    expected = start[:, None].repeat(1, BUDGET + 1, 1)
    if kind is MotionKind.UNIFORM:  # a straight line along +x at 50 m/s: 150 m per decision
        expected[..., 0] += STEP * torch.arange(BUDGET + 1, dtype=torch.float32)
        torch.testing.assert_close(motion, torch.tensor([50.0, 0.0]).expand_as(motion))
    else:
        torch.testing.assert_close(motion, torch.zeros_like(motion))
    torch.testing.assert_close(prediction, expected, atol=1e-2, rtol=0)


# ---------------------------------------------------------------------------- episodes across batches
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


@pytest.fixture(scope="module")
def spanning(torch_one_thread, task_params) -> Spanning:
    return Spanning(task_params(MotionKind.UNIFORM))


def test_episodes_spanning_two_and_three_batches_are_relabelled_like_a_brute_force_search(spanning):
    transform = spanning.transform()
    first_batch = spanning.batch_of()
    spans = {}
    for batch in spanning.batches:
        for trajectory in set(batch.get(TRAJECTORY_KEY).tolist()):
            spans[trajectory] = spans.get(trajectory, 0) + 1
    assert {2, 3} <= set(spans.values()), "the batches hold episodes spanning two and three batches"
    checked_spans = set()
    for number, batch in enumerate(spanning.batches):
        spanning.received.clear()
        out = transform.relabel(batch)
        traj_ids = batch.get(TRAJECTORY_KEY)
        # Every episode with rows in this batch has a known start (the first batch starts every env afresh).
        episodes = sorted(set(traj_ids.tolist()), key=lambda t: int((traj_ids == t).nonzero()[0, 0]))
        starts = torch.stack([spanning.start_of(t)["aircraft_state"] for t in episodes])
        arrival, actions = brute_force_search(transform.candidates, starts, spanning.env.params)
        success = arrival > 0
        assert bool(success.any(-1).any()) and not bool(success.all()), "some candidates succeed, not all"
        # Brute force: the earliest successful t_n per episode, its arrival step and B's actions.
        expected_ids = [t for t, ok in zip(episodes, success.any(-1).tolist(), strict=True) if ok]
        winner = torch.where(success, torch.arange(success.shape[1]), success.shape[1]).min(-1).values
        assert transform.last_statistics()["train/reuse_episodes_relabelled"] == len(expected_ids)
        assert len(spanning.received) == 1
        trajectories, valid = spanning.received[0]
        assert trajectories.shape[0] == len(expected_ids)
        for row, trajectory in enumerate(expected_ids):
            episode = episodes.index(trajectory)
            length = int(arrival[episode, winner[episode]])
            got = trajectories[row]
            assert int(valid[row].sum()) == length, (number, trajectory)
            start = spanning.start_of(trajectory)
            assert torch.equal(got["aircraft_state"][0], start["aircraft_state"]), "re-played from the real S_0"
            assert torch.equal(got["destination_state"][0], start["destination_state"])
            assert got["action"][:length].tolist() == actions[episode, winner[episode], :length].tolist()
            assert int(got["next", "outcome"][length - 1]) == Outcome.SUCCESS
            checked_spans.add(number - first_batch[trajectory])
        # Stored: this batch's rows of the episodes left alone, then the re-played episodes.
        own_expected = int((~torch.isin(traj_ids, torch.tensor(expected_ids))).sum())
        assert int((~out["relabelled"]).sum()) == own_expected
        assert int(out["relabelled"].sum()) == int(valid.sum())
        # The rows kept for the next batch: each env's unfinished episode since its start, under the budget.
        assert transform._carry_lengths.shape == (NUM_ENVS,)
        assert int(transform._carry_lengths.max()) < BUDGET
        assert transform._carry.numel() == int(transform._carry_lengths.sum())
    assert {0, 1, 2} <= checked_spans, "relabelled: episodes starting in this batch, one and two batches before"


def test_kept_rows_are_in_the_state_dict_and_resume_is_exact(spanning, tmp_path):
    first, second, third = spanning.batches[:3]
    running = spanning.transform(initial_selection_factor=0.7, seed=4)
    running.relabel(first)
    running.relabel(second)
    path = tmp_path / "reuse.pt"
    torch.save(running.state_dict(), path)
    resumed = spanning.transform(seed=99)
    resumed.load_state_dict(torch.load(path, weights_only=True))
    expected, got = running.relabel(third), resumed.relabel(third)
    assert (expected == got).all()
    assert {k: v for k, v in running.last_statistics().items() if not k.startswith("time/")} == {
        k: v for k, v in resumed.last_statistics().items() if not k.startswith("time/")}
    assert running.last_statistics()["train/reuse_episodes_carried"] > 0
    # Without the kept rows the episodes that started earlier are left alone: the state is what differs.
    fresh = spanning.transform()
    fresh.load_state_dict({k: v for k, v in torch.load(path, weights_only=True).items() if k != "carry"})
    fewer = fresh.relabel(third)  # the same draws for the episodes starting in this batch
    assert int(fewer["relabelled"].sum()) < int(expected["relabelled"].sum())
    assert fresh.last_statistics()["train/reuse_episodes_carried"] == 0



def ended_in(batch: TensorDict) -> set[int]:
    """The episodes (trajectory ids) whose last row in ``batch`` is terminal: they end in this batch."""
    traj_ids, done = batch.get(TRAJECTORY_KEY), batch["next", "done"].reshape(-1)
    return {t for t in set(traj_ids.tolist()) if bool(done[(traj_ids == t).nonzero()[-1, 0]])}


def test_without_relabel_unfinished_each_episode_is_searched_once_in_the_batch_where_it_ends(spanning):
    algorithm_1, deferred = spanning.transform(), spanning.transform(relabel_unfinished=False)
    searched = []
    for batch in spanning.batches:
        traj_ids = batch.get(TRAJECTORY_KEY)
        episodes = sorted(set(traj_ids.tolist()), key=lambda t: int((traj_ids == t).nonzero()[0, 0]))
        ended = ended_in(batch)
        starts = torch.stack([spanning.start_of(t)["aircraft_state"] for t in episodes])
        arrival, _ = brute_force_search(algorithm_1.candidates, starts, spanning.env.params)
        winners = [t for t, ok in zip(episodes, (arrival > 0).any(-1).tolist(), strict=True) if ok]
        spanning.received.clear()
        algorithm_1.relabel(batch)
        full, full_valid = spanning.received[0]  # Algorithm 1's re-played episodes: the winners, in batch order
        spanning.received.clear()
        out = deferred.relabel(batch)
        stats = deferred.last_statistics()
        assert stats["train/reuse_episodes_selected"] == len(episodes), "the selection itself is unchanged"
        assert stats["train/reuse_episodes_searched"] == len(ended)
        searched += sorted(ended)
        # Relabelled: Algorithm 1's episodes of this batch that end in it, re-played the same way.
        expected = [t for t in winners if t in ended]
        assert stats["train/reuse_episodes_relabelled"] == len(expected)
        assert int((~out["relabelled"]).sum()) == int((~torch.isin(traj_ids, torch.tensor(expected))).sum())
        if not expected:
            assert spanning.received == []
            continue
        got, got_valid = spanning.received[0]
        keep = torch.tensor([t in ended for t in winners])
        length = got_valid.shape[1]
        assert torch.equal(got_valid, full_valid[keep][:, :length])
        for key in ("action", "aircraft_state", "destination_state", ("next", "reward"), ("next", "done")):
            assert torch.equal(got[key], full[key][keep][:, :length]), key
    assert {len(ended_in(batch)) for batch in spanning.batches} != {0}
    assert len(searched) == len(set(searched)), "no episode is searched twice"


def test_without_relabel_own_successes_the_agents_successful_episodes_keep_its_rows(relabelled):
    flat, out = relabelled.input.clone(), relabelled.out  # Algorithm 1's output on this batch
    traj_ids, done = flat.get(TRAJECTORY_KEY), flat["next", "done"].reshape(-1)
    # The episodes Algorithm 1 replaced: those without own rows in its output (observations match uniquely).
    own = out[~out["relabelled"]]
    source = (own["observation"][:, None] == flat["observation"][None]).all(-1).long().argmax(-1)
    replaced = set(traj_ids.tolist()) - set(traj_ids[source].tolist())
    # Two of them that end in this batch are marked as Z's own successes.
    marked = sorted(t for t in replaced if bool(done[(traj_ids == t).nonzero()[-1, 0]]))[:2]
    assert len(marked) == 2
    last_rows = torch.stack([(traj_ids == t).nonzero()[-1, 0] for t in marked])
    flat["next", "outcome"][last_rows] = int(Outcome.SUCCESS)
    outcome = flat["next", "outcome"].reshape(-1)
    successes = {t for t in set(traj_ids.tolist()) if done[(traj_ids == t).nonzero()[-1, 0]]
                 and outcome[(traj_ids == t).nonzero()[-1, 0]] == Outcome.SUCCESS}  # the marked, and Z's own
    transform = relabelled.collected.transform(relabel_own_successes=False)
    shortcut = transform.relabel(flat)
    stats, full = transform.last_statistics(), relabelled.transform.last_statistics()
    assert stats["train/reuse_episodes_selected"] == full["train/reuse_episodes_selected"]
    started = set(traj_ids[starts_of(flat)].tolist())  # every episode with a start here is selected (e = 1)
    assert stats["train/reuse_episodes_searched"] == full["train/reuse_episodes_searched"] - len(successes & started)
    assert stats["train/reuse_episodes_relabelled"] == full["train/reuse_episodes_relabelled"] - len(
        successes & replaced)
    # Z's rows of the marked episodes are stored verbatim, with the other own rows, in the collector's order.
    kept = ~torch.isin(traj_ids, torch.tensor(sorted(replaced - successes)))
    assert (shortcut[~shortcut["relabelled"]] == own_rows(flat[kept])).all()


# ---------------------------------------------------------------------------- as a replay-buffer transform
def test_extend_does_not_write_into_the_collector_batch(uniform):
    data = uniform.data.clone()
    flat = data.reshape(-1)  # as in the trainer: views of the collector's tensors
    before = data.clone()
    transform = uniform.transform()
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(3 * flat.numel()),
                                    sampler=SamplerWithoutReplacement(), batch_size=16, transform=transform)
    buffer.extend(flat)
    assert (data == before).all(), "rb.extend changed the collector's batch in place"
    assert set(data.keys(True, True)) == set(before.keys(True, True))
    stored = buffer[:]
    assert len(buffer) == stored.numel()
    assert bool(stored["relabelled"].any()), "the buffer holds relabelled rows"
    assert transform.last_statistics()["train/reuse_fraction"] == pytest.approx(
        float(stored["relabelled"].float().mean()))
    # Sampling returns stored rows unchanged (forward is the identity).
    sample = buffer.sample()
    assert set(sample.keys()) >= set(PPO_KEYS)


def test_rejects_unflattened_rows(uniform):
    with pytest.raises(ValueError, match="flat rows"):
        uniform.transform().relabel(uniform.data)


# ---------------------------------------------------------------------------- end to end
#: The hand-built scenario for a whole training run: every episode starts 5 km behind the destination.
SCENARIO_START = ["simulation.initial_state.x_range=[-5000,-5000]", "simulation.initial_state.y_range=[0,0]",
                  "simulation.initial_state.z_range=[100,100]"]


def steady_checkpoint(path: Path, observation: str | None = None) -> Path:
    """A fixed-task baseline checkpoint in the trainer's format whose actor always flies steady:
    in the hand-built scenario that reaches the destination, so relabelling happens in the run.
    ``observation`` None: a checkpoint written before ``agent.observation`` existed (relative)."""
    torch.manual_seed(0)
    actor = make_actor([16, 16], "tanh", observation=observation or "relative")
    output_layer = actor.module[0].module[-1]
    with torch.no_grad():
        output_layer.weight.zero_()
        output_layer.bias.zero_()
        output_layer.bias[STEADY] = 10.0
    agent = {"name": "small", "actor_hidden": [16, 16], "critic_hidden": [16, 16], "activation": "tanh"}
    if observation is not None:
        agent["observation"] = observation
    critic = make_critic([16, 16], "tanh", observation=observation or "relative")
    save_checkpoint({"actor": actor.state_dict(), "critic": critic.state_dict(),
                     "config": {"agent": agent, "task": {"name": "fixed"}}}, path)
    return path


@pytest.fixture(scope="module")
def steady_baseline(tmp_path_factory) -> Path:
    return steady_checkpoint(tmp_path_factory.mktemp("baseline") / "steady.pt")


def scalar_values(run_dir: Path) -> dict[str, list[float]]:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    values: dict[str, list[float]] = {}
    for events in run_dir.rglob("events.out.tfevents.*"):
        accumulator = EventAccumulator(str(events))
        accumulator.Reload()
        for tag in accumulator.Tags()["scalars"]:
            values.setdefault(tag, []).extend(event.value for event in accumulator.Scalars(tag))
    return values


@pytest.fixture(scope="module")
def reuse_runs(run_cli, tiny_args, steady_baseline, tmp_path_factory) -> dict[str, tuple[Path, object]]:
    """Two tiny ``python -m agrl.train method=reuse`` runs at once: {name: (run directory, CompletedProcess)}.
    ``relative``: from the steady baseline; ``absolute``: Z and B both read equation 4 (agent.observation=absolute)."""
    folder = tmp_path_factory.mktemp("reuse_runs")
    absolute_baseline = steady_checkpoint(folder / "steady_absolute.pt", observation="absolute")
    args = tiny_args({"ppo.total_frames": 512, "eval.interval": 1, "eval.episodes": 8})
    runs = {"relative": folder / "reuse", "absolute": folder / "reuse_absolute"}
    results = run_cli.batch({
        "relative": ("train", "task=uniform", "speed=50", "method=reuse", f"method.baseline={steady_baseline}",
                     "method.max_candidates=4", *args, *SCENARIO_START, f"hydra.run.dir={runs['relative']}"),
        "absolute": ("train", "task=uniform", "speed=50", "method=reuse", f"method.baseline={absolute_baseline}",
                     "agent.observation=absolute", "method.max_candidates=4", *args, *SCENARIO_START,
                     f"hydra.run.dir={runs['absolute']}"),
    })
    return {name: (run_dir, results[name]) for name, run_dir in runs.items()}


def test_reuse_training_runs_end_to_end(reuse_runs):
    run_dir, result = reuse_runs["relative"]
    assert result.returncode == 0, result.stderr[-3000:]
    values = scalar_values(run_dir)
    assert {"train/e", "train/reuse_fraction"} <= set(values), sorted(values)
    assert 0 < values["train/reuse_fraction"][-1] <= 1, "the steady baseline arrives: rows are relabelled"
    assert 0 < values["train/e"][-1] < 1, "e dropped by k per selected episode"
    # PPO's clip fraction per source of rows: relabelled rows exist, Z's own rows only if not all were relabelled
    assert all(0 <= value <= 1 for value in values["loss/clip_fraction_relabelled"]), sorted(values)
    assert ("loss/clip_fraction_own" in values) == (min(values["train/reuse_fraction"]) < 1), sorted(values)
    summary = json.loads((run_dir / "eval" / "eval.json").read_text())
    assert summary["method"] == "reuse" and summary["task"] == "uniform"


def test_reuse_with_the_papers_observation_runs_end_to_end(reuse_runs, compose_evaluate, tmp_path):
    """Z and B both read equation 4 as it stands (agent.observation=absolute); B is queried in the predicted
    destination's frame, and the trained agent evaluates on its own input (agrl.evaluate's evaluation, in
    process: its command line is tested in tests/test_evaluate_cli.py)."""
    from agrl.evaluate import evaluate

    run_dir, result = reuse_runs["absolute"]
    assert result.returncode == 0, result.stderr[-3000:]
    assert 0 < scalar_values(run_dir)["train/reuse_fraction"][-1] <= 1
    evaluation = evaluate(compose_evaluate(f"checkpoint={run_dir}", "episodes=8", "trajectories=0",
                                           f"output_dir={tmp_path / 'eval'}"))
    assert evaluation["episodes"] == 8
    assert json.loads((tmp_path / "eval" / "eval.json").read_text())["episodes"] == 8


def test_pretrained_from_a_baseline_of_another_observation_is_a_one_line_error(run_cli, tiny_args, tmp_path,
                                                                               steady_baseline):
    # Refused by agrl.cli's checks before Hydra runs: in process (real processes: tests/test_train_cli.py).
    result = run_cli.checks("train", "method=pretrained", f"method.baseline={steady_baseline}",
                            "agent.observation=absolute", "agent.actor_hidden=[16,16]", "agent.critic_hidden=[16,16]",
                            *tiny_args(), f"hydra.run.dir={tmp_path / 'pretrained'}")
    assert result.returncode == 2, result.stderr[-3000:]
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert lines[0].startswith("agrl.train: error:") and str(steady_baseline) in lines[0]
    assert "agent.observation=absolute" in lines[0] and "observation=relative" in lines[0]
    assert not (tmp_path / "pretrained").exists()


def test_pretrained_with_a_different_actor_is_a_one_line_error(run_cli, tiny_args, tiny_run, tmp_path):
    baseline = tiny_run.run_dir / "checkpoints" / "latest.pt"  # fixed task, the default [128, 128] actor
    result = run_cli.checks("train", "method=pretrained", f"method.baseline={baseline}",
                            "agent.actor_hidden=[32,32]", *tiny_args(), f"hydra.run.dir={tmp_path / 'pretrained'}")
    assert result.returncode == 2, result.stderr[-3000:]
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("agrl.train: error:") and str(baseline) in lines[0] and "actor" in lines[0]
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "pretrained").exists()


@pytest.mark.parametrize("task", [
    ("task=uniform", "speed=50"),
    # The irregular destination's random redraws, with the start-box curriculum on (the tiny runs turn it off).
    ("task=irregular", "curriculum.enabled=true", "method.use_curriculum=true", "curriculum.promotion_success=0.01"),
], ids=["uniform", "irregular+curriculum"])
def test_reuse_resume_matches_an_uninterrupted_run_bitwise(tmp_path, compose_train, tiny_args, steady_baseline,
                                                          task):
    """4 reuse iterations in a row == 2, then a resumed Trainer for 2 more (the kept rows are in the checkpoint)."""
    from agrl.rl.checkpoint import load_checkpoint
    from agrl.rl.trainer import Trainer

    overrides = [*task, "method=reuse", f"method.baseline={steady_baseline}",
                 "method.max_candidates=4", *SCENARIO_START]
    straight, half = tmp_path / "straight", tmp_path / "half"
    Trainer(compose_train(*tiny_args({"ppo.total_frames": 4 * 512}), *overrides), straight).train()
    Trainer(compose_train(*tiny_args({"ppo.total_frames": 2 * 512}), *overrides), half).train()
    first = load_checkpoint(half / "checkpoints" / "latest.pt")
    assert first["reuse"]["carry"]["lengths"].sum() > 0, "episodes were carried over at the cut"
    if "curriculum.enabled=true" in task:  # resumed below the full start box
        assert first["counters"]["curriculum_scale"] < 1.0
    config = compose_train(*tiny_args({"ppo.total_frames": 4 * 512}), *overrides)
    Trainer(config, half, resume_payload=first).train()
    expected = load_checkpoint(straight / "checkpoints" / "latest.pt")
    resumed = load_checkpoint(half / "checkpoints" / "latest.pt")
    for key in ("actor", "critic", "reuse"):
        assert_equal_nested(resumed[key], expected[key], key)
    for key in ("iteration", "frames", "curriculum_scale"):
        assert resumed["counters"][key] == expected["counters"][key], key


def assert_equal_nested(a, b, where: str) -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), where
        for key in a:
            assert_equal_nested(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, torch.Tensor):
        assert torch.equal(a, b), f"{where} differs"
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def test_curved_prediction_follows_the_arc_heading_included(torch_one_thread, task_params):
    """A curved destination (50 m/s on a 1 km radius, counter-clockwise from (0, 0) heading +x): recorded and
    extended predictions are the circle x = R sin(wt), y = R (1 - cos wt), heading wt (the heading field is
    predicted too, and it is what the baseline sees)."""
    collected = Collected(task_params(MotionKind.CURVED))
    flat = collected.flat()
    transform = collected.transform()
    starts = starts_of(flat)
    prediction, motion = transform._destination_prediction(flat, starts, flat.get(TRAJECTORY_KEY))
    radius, speed = 1_000.0, 50.0
    rate = speed / radius
    torch.testing.assert_close(motion, torch.tensor([speed, rate]).expand_as(motion))
    # Every episode, also one begun mid-batch, starts its destination at (0, 0) heading +x.
    assert bool((flat["step_count"][starts] == 0).all())
    angle = rate * 3.0 * torch.arange(BUDGET + 1, dtype=torch.float64).expand(starts.numel(), -1)
    expected = torch.stack((radius * torch.sin(angle), radius * (1 - torch.cos(angle)),
                            torch.zeros_like(angle)), -1)
    torch.testing.assert_close(prediction[..., :3].double(), expected, atol=0.05, rtol=0)
    heading = prediction[..., 3].double()
    torch.testing.assert_close(torch.cos(heading), torch.cos(angle), atol=1e-4, rtol=0)
    torch.testing.assert_close(torch.sin(heading), torch.sin(angle), atol=1e-4, rtol=0)


def test_prediction_reflects_at_the_airspace_wall(torch_one_thread, task_params):
    """A uniform destination starting 500 m from the +x wall: it reaches the wall after 10 s, 3 1/3 decisions,
    then flies back along -x with heading pi (the destination's motion model, beyond each episode too)."""
    collected = Collected(task_params(MotionKind.UNIFORM, destination_start=(9_500.0, 0.0, 0.0, 0.0)))
    flat = collected.flat()
    transform = collected.transform()
    starts = starts_of(flat)
    prediction, _ = transform._destination_prediction(flat, starts, flat.get(TRAJECTORY_KEY))
    travelled = STEP * torch.arange(BUDGET + 1, dtype=torch.float64)
    x = torch.where(travelled <= 500.0, 9_500.0 + travelled, 10_000.0 - (travelled - 500.0))
    heading = torch.where(travelled <= 500.0, torch.zeros_like(travelled), torch.full_like(travelled, torch.pi))
    for episode in range(starts.numel()):
        torch.testing.assert_close(prediction[episode, :, 0].double(), x, atol=0.05, rtol=0)
        torch.testing.assert_close(prediction[episode, :, 1].double(), torch.zeros_like(x), atol=0.05, rtol=0)
        torch.testing.assert_close(torch.cos(prediction[episode, :, 3].double()), torch.cos(heading),
                                   atol=1e-4, rtol=0)


def test_baseline_log_prob_is_the_baselines_on_the_predicted_destination(relabelled):
    """``method.behaviour_log_prob=baseline`` uses B's log-probability of its own action on the observation
    with the predicted destination (equation 20), here recomputed from B's logits directly."""
    trajectories, lengths, starts = relabelled.trajectories, relabelled.lengths, relabelled.starts
    flat, transform = relabelled.flat, relabelled.transform
    prediction, motion = transform._destination_prediction(flat, starts, flat.get(TRAJECTORY_KEY))
    _, winner = transform._search(flat[starts], prediction, motion)
    target = prediction[torch.arange(starts.numel()), transform.candidates[winner]]
    simulation = relabelled.collected.env.params.simulation
    for episode in range(starts.numel()):
        rows = trajectories[episode, : int(lengths[episode])]
        observed = policy_observation(rows["aircraft_state"], target[episode].expand(rows.shape[0], 4),
                                      rows["last_action"], simulation.airspace, simulation.limits)
        log_probs = torch.log_softmax(PursuitLogits()(observed), -1)
        expected = log_probs.gather(-1, rows["action"][:, None]).squeeze(-1)
        torch.testing.assert_close(rows["baseline_log_prob"], expected)
        # A confident baseline: its argmax log-probability, 10 - log(e^10 + 6), not a uniform -log 7.
        torch.testing.assert_close(expected, torch.full_like(expected, 10.0 - math.log(math.exp(10.0) + 6.0)))


def test_irregular_prediction_extends_each_episode_with_its_last_speed_and_turn_rate(torch_one_thread, task_params):
    """Irregular destinations redraw speed and turn rate at random: inside an episode the prediction is the
    recorded track; past its last recorded transition it keeps the last recorded (speed, turn rate)."""
    collected = Collected(task_params(MotionKind.IRREGULAR), seed=3)
    flat = collected.flat()
    transform = collected.transform()
    starts = starts_of(flat)
    prediction, motion = transform._destination_prediction(flat, starts, flat.get(TRAJECTORY_KEY))
    traj_ids = flat.get(TRAJECTORY_KEY)
    airspace = collected.env.params.simulation.airspace
    extended = 0
    for episode, start in enumerate(starts.tolist()):
        rows = flat[start:][: int((traj_ids == traj_ids[start]).sum())]
        recorded = torch.stack((rows["next", "destination_speed"], rows["next", "destination_turn_rate"]), -1)
        length = recorded.shape[0]
        torch.testing.assert_close(motion[episode, :length], recorded)
        torch.testing.assert_close(motion[episode, length:], recorded[-1].expand(BUDGET - length, 2))
        live = length - int(bool(rows["next", "done"][-1]))  # the last recorded position is frozen on a done row
        torch.testing.assert_close(prediction[episode, 1: live + 1], rows["next", "destination_state"][:live])
        for step in range(live, BUDGET):  # one decision of the motion model per step, from the prediction
            following = move_destination(DestinationState.from_tensor(prediction[episode, step : step + 1]),
                                         recorded[-1:, 0], recorded[-1:, 1], 3.0,
                                         (airspace.x_min, airspace.x_max), (airspace.y_min, airspace.y_max))
            torch.testing.assert_close(prediction[episode, step + 1], following.to_tensor()[0])
            extended += 1
    assert extended > 0, "some episodes must end (or be cut by the batch) before the budget"
    assert bool((motion[..., 1] != 0).any()) and motion[..., 0].unique().numel() > 2, "the motion really varies"
