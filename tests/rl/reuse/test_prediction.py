"""Destination prediction (``agrl.rl.reuse.prediction``, equations 19-20): the destination's trajectory recorded
and extended by its motion model, and the baseline B queried on a predicted destination."""

from __future__ import annotations

import pytest
import torch
from reuse_scenarios import (
    BUDGET,
    LEFT,
    RIGHT,
    STEP,
    AbsolutePursuitLogits,
    Collected,
    as_actor,
    kept_candidates,
    starts_of,
)
from tensordict import TensorDict
from torchrl.envs import ExplorationType, set_exploration_type

from agrl.core.destinations import DestinationState, move_destination
from agrl.core.observation import OBSERVATION_SIZE, absolute_observation, in_destination_frame, policy_observation
from agrl.envs import MotionKind
from agrl.rl.models import make_actor
from agrl.rl.reuse import TRAJECTORY_KEY, BaselinePolicy, destination_prediction


def predict_episodes(collected, rows=None) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``(starts, trajectory, motion)`` of every episode starting in ``collected``'s flat batch (or ``rows``)."""
    rows = collected.flat() if rows is None else rows
    starts = starts_of(rows)
    trajectory, motion = destination_prediction(rows, starts, rows.get(TRAJECTORY_KEY), collected.env.params)
    return starts, trajectory, motion


# ---------------------------------------------------------------------------- the destination's trajectory
@pytest.mark.parametrize("kind", [MotionKind.UNIFORM, MotionKind.FIXED])
def test_prediction_past_the_episode_follows_the_motion_model(uniform, fixed, kind):
    collected = uniform if kind is MotionKind.UNIFORM else fixed
    flat = collected.flat()
    starts, prediction, motion = predict_episodes(collected, flat)
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


def test_curved_prediction_follows_the_arc_heading_included(torch_one_thread, task_params):
    """A curved destination (50 m/s on a 1 km radius, counter-clockwise from (0, 0) heading +x): recorded and
    extended predictions are the circle x = R sin(wt), y = R (1 - cos wt), heading wt (the heading field is
    predicted too, and it is what the baseline sees)."""
    collected = Collected(task_params(MotionKind.CURVED))
    flat = collected.flat()
    starts, prediction, motion = predict_episodes(collected, flat)
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
    starts, prediction, _ = predict_episodes(collected)
    travelled = STEP * torch.arange(BUDGET + 1, dtype=torch.float64)
    x = torch.where(travelled <= 500.0, 9_500.0 + travelled, 10_000.0 - (travelled - 500.0))
    heading = torch.where(travelled <= 500.0, torch.zeros_like(travelled), torch.full_like(travelled, torch.pi))
    for episode in range(starts.numel()):
        torch.testing.assert_close(prediction[episode, :, 0].double(), x, atol=0.05, rtol=0)
        torch.testing.assert_close(prediction[episode, :, 1].double(), torch.zeros_like(x), atol=0.05, rtol=0)
        torch.testing.assert_close(torch.cos(prediction[episode, :, 3].double()), torch.cos(heading),
                                   atol=1e-4, rtol=0)


def test_irregular_prediction_extends_each_episode_with_its_last_speed_and_turn_rate(torch_one_thread, task_params):
    """Irregular destinations redraw speed and turn rate at random: inside an episode the prediction is the
    recorded track; past its last recorded transition it keeps the last recorded (speed, turn rate)."""
    collected = Collected(task_params(MotionKind.IRREGULAR), seed=3)
    flat = collected.flat()
    starts, prediction, motion = predict_episodes(collected, flat)
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


# ---------------------------------------------------------------------------- B on the predicted destination
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
    prediction, _, (_, winner, _) = kept_candidates(transform, flat, starts)
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
            assert torch.equal(transform.baseline.actions(flat, predicted), logits.argmax(-1))


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
    assert transform.baseline.logits is not None, "the actor's logits network is found"
    policy = transform.baseline
    if network == "actor":
        policy = BaselinePolicy(baseline, uniform.env.params.simulation, direct=False)
        assert policy.logits is None
    observation = torch.randn(4_096, OBSERVATION_SIZE)
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        expected = baseline(TensorDict({"observation": observation}, [observation.shape[0]]))
    assert expected["action"].unique().numel() > 1
    with set_exploration_type(ExplorationType.RANDOM):  # whatever the caller's setting
        assert torch.equal(policy.mode(observation), expected["action"])
        action, log_prob = policy.mode_and_log_prob(observation)
    assert torch.equal(action, expected["action"])
    assert torch.equal(log_prob, expected["action_log_prob"])




@pytest.mark.parametrize("observation", ["relative", "absolute"])
def test_baselines_input_is_its_observation_of_the_predicted_destination(uniform, observation):
    """Equation 20: B reads its own observation of the state with the destination fields replaced; the absolute
    one (equation 4) in the predicted destination's frame (section 5.1)."""
    simulation = uniform.env.params.simulation
    policy = BaselinePolicy(as_actor(AbsolutePursuitLogits()), simulation, observation)
    flat = uniform.flat()
    count = flat.numel()
    destination = torch.stack((torch.linspace(-8e3, 8e3, count), torch.linspace(5e3, -5e3, count),
                               torch.full((count,), 1e3), torch.linspace(-3, 3, count)), -1)
    got = policy.observation(flat["aircraft_state"], destination, flat["last_action"])
    if observation == "relative":
        expected = policy_observation(flat["aircraft_state"], destination, flat["last_action"], simulation.airspace,
                                      simulation.limits)
    else:
        moved, origin = in_destination_frame(flat["aircraft_state"], destination)
        assert not bool(origin.any()), "the predicted destination is B's origin"
        expected = absolute_observation(moved, origin, flat["last_action"], simulation.airspace, simulation.limits)
    assert torch.equal(got, expected)
