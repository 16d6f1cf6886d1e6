"""The batched TorchRL guidance environment: specs, resets, seeding, scenario replay, state restore."""

from __future__ import annotations

import dataclasses
import math
import warnings

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs.utils import check_env_specs

from agrl.core.observation import OBSERVATION_SIZE, absolute_observation, observation_size, policy_observation
from agrl.core.parameters import DestinationMotion
from agrl.core.termination import Outcome
from agrl.envs import GuidanceEnv, GuidanceParameters, MotionKind
from agrl.envs.guidance import REWARD_PART_KEYS, STATE_KEYS


@pytest.fixture(scope="module")
def make_params(paper_parameters, compose_parameters):
    """``make_params(kind, **changes)``: conf's parameters (reward=both) with a destination of ``kind`` (uniform
    and curved at 20 m/s, curved on a 500 m radius; irregular as conf/task/irregular.yaml) and ``changes``."""
    irregular = compose_parameters("task=irregular", "reward=both").destination

    def make(kind: MotionKind = MotionKind.FIXED, **changes) -> GuidanceParameters:
        if kind is MotionKind.IRREGULAR:
            destination = irregular
        else:
            destination = DestinationMotion(name=kind, speed=20.0, radius=500.0, turn_direction=1.0)
        return dataclasses.replace(paper_parameters, destination=destination, **changes)

    return make


def cycling_policy(td: TensorDict) -> TensorDict:
    """Deterministic, state-dependent actions (so rollouts differ when states differ)."""
    td["action"] = (td["step_count"] + (td["aircraft_state"][..., 0] > 0).long() * 3) % 7
    return td


def assert_same(a: TensorDict, b: TensorDict, keys) -> None:
    for key in keys:
        assert torch.equal(a[key], b[key]), key


@pytest.mark.parametrize("kind", list(MotionKind))
def test_check_env_specs(kind, make_params):
    env = GuidanceEnv(make_params(kind), num_envs=2, seed=0)
    check_env_specs(env)
    td = env.reset()
    assert td["observation"].shape == (2, OBSERVATION_SIZE)
    assert env.action_spec.shape == (2,)
    assert env.action_spec.space.n == 7


@pytest.mark.parametrize(
    "kind,reward_changes",
    [*((kind, {"switch_cost": 0.3}) for kind in MotionKind),
     (MotionKind.FIXED, {"use_continuous_action": False, "use_position": False, "switch_cost": 0.3}),
     (MotionKind.FIXED, {"switch_cost": 1.5, "gamma": 0.9, "use_position": False})],
)
def test_reward_parts_sum_to_the_reward(kind, reward_changes, paper_parameters, make_params):
    """The reward is the sum of its parts, each paid where it should be. The parts are computed once per decision,
    whatever the integration step: a 0.3 s step (10 per decision, as the tiny training runs) instead of 20 ms."""
    reward = dataclasses.replace(paper_parameters.reward, **reward_changes)
    simulation = dataclasses.replace(paper_parameters.simulation, integration_step=0.3)
    env = GuidanceEnv(make_params(kind, reward=reward, simulation=simulation, max_decisions=8), num_envs=6, seed=3)
    td = env.rollout(20, policy=cycling_policy, break_when_any_done=False)
    step = td["next"]
    parts = {key: step[key] for key in REWARD_PART_KEYS}
    torch.testing.assert_close(sum(parts.values()), step["reward"].squeeze(-1), atol=1e-5, rtol=0)
    done = step["done"].squeeze(-1)
    assert done.any()
    # Termination pays only on the last step of an episode; the switch cost on each instruction.
    assert (parts["reward_termination"][~done] == 0).all()
    assert (parts["reward_termination"][done] != 0).all()
    # td["last_action"] is the maneuver flown before each step (0, steady flight, after a reset).
    changed = (td["action"] != td["last_action"]).float()
    torch.testing.assert_close(parts["reward_switch_cost"], -reward.switch_cost * changed)
    for key, used in (("reward_action_shaping", reward.use_continuous_action),
                      ("reward_position_shaping", reward.use_position)):
        assert bool((parts[key] != 0).any()) == used, key


def test_rejects_an_unknown_observation_in_one_line(make_params):
    with pytest.raises(ValueError, match=r"^observation='polar' is not allowed: one of relative, absolute$"):
        GuidanceEnv(make_params(), num_envs=1, seed=0, observation="polar")


def test_rejects_an_empty_decision_budget(make_params):
    with pytest.raises(ValueError, match=r"^max_decisions=0 is not allowed: an integer >= 1$"):
        GuidanceEnv(make_params(max_decisions=0), num_envs=1, seed=0)


@pytest.mark.parametrize(("arguments", "message"), [
    ({"num_envs": 0}, "num_envs=0 is not allowed: an integer >= 1"),
    ({"num_envs": 2.5}, "num_envs=2.5 is not allowed: an integer >= 1"),
    ({"device": "tpu"}, "device='tpu' is not allowed: a torch device, e.g. cpu or cuda"),
])
def test_rejects_a_bad_batch_or_device_in_one_line(make_params, arguments, message):
    with pytest.raises(ValueError) as raised:
        GuidanceEnv(make_params(), seed=0, **arguments)
    assert str(raised.value) == message


@pytest.mark.parametrize("kind,function", [("relative", policy_observation), ("absolute", absolute_observation)])
def test_observation_matches_the_state(make_params, kind, function):
    env = GuidanceEnv(make_params(MotionKind.CURVED), num_envs=3, seed=1, observation=kind)
    check_env_specs(env)
    assert env.observation_spec["observation"].shape == (3, observation_size(kind))
    td = env.rollout(3, policy=cycling_policy, break_when_any_done=False)
    for sub in (td, td["next"]):
        expected = function(
            sub["aircraft_state"],
            sub["destination_state"],
            sub["last_action"],
            env.params.simulation.airspace,
            env.params.simulation.limits,
        )
        torch.testing.assert_close(sub["observation"], expected)


def test_bookkeeping_counters(make_params):
    env = GuidanceEnv(make_params(), num_envs=1, seed=0)
    td = env.reset(env.scenario(aircraft_state=torch.tensor([-5_000.0, 0.0, 2_500.0, 200.0, 0.0, 0.0, 0.0])))
    rewards = []
    for action in (0, 0, 3, 3, 1):
        td["action"] = torch.tensor([action])
        td = env.step(td)
        rewards.append(float(td["next", "reward"]))
        td = env.step_mdp(td)
    assert int(td["step_count"]) == 5
    assert int(td["instruction_count"]) == 2  # 0 -> 3 and 3 -> 1
    assert int(td["last_action"]) == 1 and int(td["action_before_last"]) == 3
    assert float(td["episode_return"]) == pytest.approx(sum(rewards), abs=1e-5)


def test_partial_reset_only_changes_masked_rows(make_params):
    env = GuidanceEnv(make_params(MotionKind.IRREGULAR), num_envs=4, seed=2)
    td = env.reset()
    for _ in range(2):
        td["action"] = torch.tensor([1, 2, 3, 5])
        td = env.step_mdp(env.step(td))
    before = td.clone()
    mask = torch.tensor([[True], [False], [True], [False]])
    td["_reset"] = mask
    after = env.reset(td)
    keep, reset = ~mask.squeeze(-1), mask.squeeze(-1)
    for key in (*STATE_KEYS, "observation", "outcome"):
        assert torch.equal(after[key][keep], before[key][keep]), key
    assert after["step_count"].tolist() == [0, 2, 0, 2]
    assert torch.all(after["episode_return"][reset] == 0)
    assert torch.all(after["last_action"][reset] == 0)
    assert not torch.equal(after["aircraft_state"][reset], before["aircraft_state"][reset])
    # Fresh starts: theta = psi = phi = 0 at the task's destination start.
    assert torch.all(after["aircraft_state"][reset][:, 4:] == 0)
    assert torch.all(after["destination_state"][reset] == 0)
    assert not after["done"].any()


@pytest.mark.parametrize(("kind", "num_envs", "actions", "observation"), [
    (MotionKind.FIXED, 512, "maneuvers", "relative"),  # the defaults' batch
    (MotionKind.IRREGULAR, 2048, "maneuvers", "relative"),  # make train's; the irregular motion draws too
    (MotionKind.FIXED, 192, "targets", "relative"),
    (MotionKind.CURVED, 128, "maneuvers", "absolute"),
])
def test_maybe_reset_gives_torchrls_partial_reset_bit_for_bit(kind, num_envs, actions, observation, make_params,
                                                              compose_parameters):
    from torchrl.envs import EnvBase

    params = make_params(kind)
    if actions == "targets":
        params = dataclasses.replace(params, actions=compose_parameters("actions=targets").actions)
    env = GuidanceEnv(params, num_envs=num_envs, seed=4, observation=observation)
    state = env.reset()
    state["collector", "traj_ids"] = torch.arange(num_envs)  # a nested field, as a collector adds
    choose = torch.Generator().manual_seed(0)
    for step, ended in enumerate((1, 7, 64, 100, num_envs)):
        after_step = env.step_mdp(env.rand_step(state.clone()))
        after_step["action_log_prob"] = torch.randn(num_envs, generator=choose)  # a field the new rows lack
        after_step["done"][torch.randperm(num_envs, generator=choose)[:ended]] = True
        if step == 2:
            del after_step["episode_return"]  # a field only the new rows have
        draws = env.generator_state()
        expected = EnvBase.maybe_reset(env, after_step.clone())
        draws_after = env.generator_state()
        env.set_generator_state(draws)
        state = env.maybe_reset(after_step.clone())
        assert torch.equal(env.generator_state(), draws_after)  # the same draws, whatever the number of ended rows
        assert set(state.keys(True, True)) == set(expected.keys(True, True))
        for key in expected.keys(True, True):
            assert state[key].dtype == expected[key].dtype, key
            assert torch.equal(state[key], expected[key]), (key, ended)


def test_maybe_reset_leaves_the_step_it_follows_untouched(make_params):
    env = GuidanceEnv(make_params(), num_envs=64, seed=1)
    step = env.rand_step(env.reset())
    step["next", "done"][::3] = True
    before = step.clone()
    after = env.maybe_reset(env.step_mdp(step))
    assert not after["done"].any()
    for key in before.keys(True, True):  # a collector stores the step: its fields are not written over
        assert torch.equal(step[key], before[key]), key


def test_fresh_rows_with_rows_are_those_rows_of_the_whole_batch(make_params):
    env = GuidanceEnv(make_params(MotionKind.IRREGULAR), num_envs=1, seed=0)
    draws = env.generator_state()
    whole = env.fresh_rows(256)
    rows = torch.tensor([0, 3, 100, 101, 255])
    env.set_generator_state(draws)
    some = env.fresh_rows(256, rows)
    assert some.batch_size == (5,)
    for key in whole.keys():
        assert torch.equal(some[key], whole[key][rows]), key
    assert env.fresh_rows(256, rows[:0]).batch_size == (0,)


def test_rollout_auto_resets_done_rows(make_params):
    env = GuidanceEnv(make_params(max_decisions=2), num_envs=2, seed=3)
    td = env.rollout(5, policy=cycling_policy, break_when_any_done=False)
    # Budget of 2: done at steps 2 and 4, then fresh episodes.
    assert td["next", "done"].squeeze(-1).tolist() == [[False, True, False, True, False]] * 2
    assert td["next", "outcome"][:, 1].tolist() == [Outcome.BUDGET_EXHAUSTED] * 2
    assert td["next", "step_count"].tolist() == [[1, 2, 1, 2, 1]] * 2
    assert td["step_count"].tolist() == [[0, 1, 0, 1, 0]] * 2


@pytest.mark.parametrize("kind", [MotionKind.FIXED, MotionKind.IRREGULAR])
def test_same_seed_same_rollouts(kind, make_params):
    def rollout(seed):
        env = GuidanceEnv(make_params(kind, max_decisions=3), num_envs=3, seed=seed)
        return env.rollout(4, policy=cycling_policy, break_when_any_done=False)

    first, second, other = rollout(7), rollout(7), rollout(8)
    for key in first.keys(include_nested=True, leaves_only=True):
        assert torch.equal(first[key], second[key]), key
    assert not torch.equal(first["aircraft_state"], other["aircraft_state"])
    if kind is MotionKind.IRREGULAR:
        assert not torch.equal(first["destination_speed"], other["destination_speed"])


def test_set_seed_restarts_the_stream(make_params):
    env = GuidanceEnv(make_params(MotionKind.IRREGULAR), num_envs=2, seed=0)
    env.set_seed(11)
    first = env.reset()
    env.set_seed(11)
    second = env.reset()
    assert_same(first, second, ("aircraft_state", "destination_speed", "destination_turn_rate"))


@pytest.mark.parametrize("kind", [MotionKind.UNIFORM, MotionKind.CURVED])
def test_scenario_replay_starts_from_the_given_conditions(kind, make_params):
    aircraft = torch.tensor(
        [
            [-4_000.0, 1_000.0, 1_500.0, 180.0, 0.1, 0.5, 0.0],
            [3_000.0, -2_000.0, 3_500.0, 220.0, -0.1, -2.0, 0.0],
        ]
    )
    destination = torch.tensor([[100.0, 200.0, 300.0, 1.0], [-500.0, 600.0, 700.0, -1.0]])
    speed = torch.tensor([15.0, 30.0])
    turn_rate = torch.tensor([0.01, -0.02])

    def replay(seed):
        env = GuidanceEnv(make_params(kind), num_envs=2, seed=seed)
        td = env.reset(
            env.scenario(
                aircraft_state=aircraft,
                destination_state=destination,
                destination_speed=speed,
                destination_turn_rate=turn_rate,
            )
        )
        return td, env.rollout(3, policy=cycling_policy, auto_reset=False, tensordict=td)

    start, trajectory = replay(0)
    assert torch.equal(start["aircraft_state"], aircraft)
    assert torch.equal(start["destination_state"], destination)
    assert torch.equal(start["destination_speed"], speed)
    assert torch.equal(start["destination_turn_rate"], turn_rate)
    assert start["step_count"].tolist() == [0, 0] and start["last_action"].tolist() == [0, 0]
    # Deterministic from there, whatever the env's seed.
    _, again = replay(123)
    for key in trajectory.keys(include_nested=True, leaves_only=True):
        assert torch.equal(trajectory[key], again[key]), key
    # And the destination really moved with the given motion: 3 decisions of 3 s.
    end = trajectory["next", "destination_state"][:, -1]
    travelled = torch.hypot(end[:, 0] - destination[:, 0], end[:, 1] - destination[:, 1])
    for row in range(2):
        w, v = float(turn_rate[row]), float(speed[row])
        chord = 2 * v / abs(w) * math.sin(abs(w) * 9.0 / 2)
        assert float(travelled[row]) == pytest.approx(chord, rel=1e-4)


def test_scenario_defaults_to_the_task_destination(make_params):
    env = GuidanceEnv(make_params(MotionKind.CURVED), num_envs=2, seed=0)
    aircraft = torch.tensor([-4_000.0, 1_000.0, 1_500.0, 180.0, 0.0, 0.0, 0.0])
    td = env.reset(env.scenario(aircraft_state=aircraft))
    assert torch.equal(td["aircraft_state"], aircraft.expand(2, 7))
    assert torch.all(td["destination_state"] == 0)  # Table 1's start (0, 0, 0, 0)
    assert td["destination_speed"].tolist() == [20.0, 20.0]
    assert td["destination_turn_rate"].tolist() == pytest.approx([20.0 / 500.0] * 2)


def test_restore_on_next_reset_returns_the_given_state(make_params):
    params = make_params(MotionKind.CURVED)
    env = GuidanceEnv(params, num_envs=3, seed=4)
    td = env.reset()
    for action in (1, 3):
        td["action"] = torch.full((3,), action)
        td = env.step_mdp(env.step(td))
    saved = td.clone()

    other = GuidanceEnv(params, num_envs=3, seed=99)
    other.restore_on_next_reset(saved)
    restored = other.reset()
    assert_same(restored, saved, (*STATE_KEYS, "outcome", "done", "terminated", "observation"))
    # Both continue identically (curved motion is deterministic).
    saved["action"] = torch.tensor([0, 5, 6])
    restored["action"] = torch.tensor([0, 5, 6])
    a, b = env.step(saved)["next"], other.step(restored)["next"]
    assert_same(a, b, (*STATE_KEYS, "reward", "outcome", "observation"))
    # Only the next reset is affected.
    fresh = other.reset()
    assert fresh["step_count"].tolist() == [0, 0, 0]


def test_no_future_warnings(make_params):
    with warnings.catch_warnings():
        warnings.simplefilter("error", FutureWarning)
        env = GuidanceEnv(make_params(MotionKind.UNIFORM, max_decisions=2), num_envs=2, seed=0)
        check_env_specs(env)
        trajectory = env.rollout(3, break_when_any_done=False)
        td = env.reset()
        td["_reset"] = torch.tensor([[True], [False]])
        env.reset(td)
    assert trajectory["next", "outcome"].shape == (2, 3)


def test_outcomes_are_terminal_consistently(make_params):
    env = GuidanceEnv(make_params(max_decisions=2), num_envs=4, seed=5)
    td = env.rollout(2, policy=cycling_policy, break_when_any_done=False)
    outcome = td["next", "outcome"]
    done = td["next", "done"].squeeze(-1)
    assert torch.equal(done, outcome != Outcome.RUNNING)
    assert torch.equal(done, td["next", "terminated"].squeeze(-1))


# ---------------------------------------------------------------------------- actions=targets
@pytest.fixture(scope="module")
def targets_params(compose_parameters):
    return compose_parameters("task=uniform", "speed=20", "actions=targets")


def _action(table, kind, value) -> int:
    """The index of the table's action setting ``kind`` to ``value``."""
    from agrl.core.autopilot import TargetKind

    matches = ((table.kind == TargetKind[kind.upper()]) & torch.isclose(table.value, torch.tensor(float(value))))
    return int(matches.nonzero()[0, 0])


@pytest.mark.parametrize("observation", ["relative", "absolute"])
def test_a_targets_env_has_one_action_per_target_and_starts_holding_what_it_flies(targets_params, observation):
    from agrl.core.observation import held_target_features, observation_features

    env = GuidanceEnv(targets_params, num_envs=4, seed=3, observation=observation)
    check_env_specs(env)
    table = targets_params.actions.target_table(targets_params.simulation.airspace, targets_params.simulation.limits)
    assert env.action_spec.space.n == len(table) == targets_params.num_actions == 1 + 12 + 10 + 3
    td = env.reset()
    aircraft = td["aircraft_state"]
    assert torch.equal(td["held_targets"], aircraft[:, [5, 2, 3]])  # heading, altitude, speed
    names = observation_features(observation, holds_targets=True)
    assert td["observation"].shape == (4, len(names)) and "last_action_left_turn" not in names
    simulation = targets_params.simulation
    expected = held_target_features(aircraft, td["held_targets"], simulation.airspace, simulation.limits)
    assert torch.equal(td["observation"][:, -4:], expected)
    assert torch.equal(expected, torch.tensor([[0.0, 1.0, 0.0, 0.0]] * 4))  # every target reached at the start


def test_a_targets_step_counts_and_prices_only_actions_that_change_a_target(targets_params):
    params = dataclasses.replace(targets_params, reward=dataclasses.replace(targets_params.reward, switch_cost=0.25))
    env = GuidanceEnv(params, num_envs=4, seed=0)
    table = env.target_table
    start = torch.tensor([[-6000.0, 3000.0, 2500.0, 200.0, 0.0, 0.0, 0.0]] * 4)
    td = env.reset(env.scenario(aircraft_state=start))
    # hold; heading 0 (already held); climb to 3 500 m; slow to the minimum speed
    td["action"] = torch.tensor([0, _action(table, "heading", 0.0), _action(table, "altitude", 3500.0),
                                 _action(table, "speed", params.simulation.limits.min_speed)])
    after = env.step(td)["next"]
    assert after["instruction_count"].tolist() == [0, 0, 1, 1]
    assert after["reward_switch_cost"].tolist() == [0.0, 0.0, -0.25, -0.25]
    held = after["held_targets"]
    assert held[:2].tolist() == [[0.0, 2500.0, 200.0]] * 2
    assert held[2].tolist() == [0.0, 3500.0, 200.0] and held[3].tolist() == [0.0, 2500.0, 100.0]
    # The climbing row climbs, the slowing row slows; the others fly on level at 200 m/s.
    assert after["aircraft_state"][2, 2] > 2500.0 and after["aircraft_state"][3, 3] < 200.0
    assert torch.allclose(after["aircraft_state"][:2, 2:4], torch.tensor([[2500.0, 200.0]] * 2))
    # The same clearance again is no instruction; a new one is.
    after["action"] = torch.tensor([_action(table, "heading", math.pi / 2), 0, _action(table, "altitude", 3500.0),
                                    _action(table, "altitude", 500.0)])
    again = env.step(after)["next"]
    assert again["instruction_count"].tolist() == [1, 0, 1, 2]


def test_a_targets_decision_is_the_autopilot_flying_the_held_targets(targets_params):
    """The env's transition against the core's one-step law applied 150 times (agrl.core.autopilot)."""
    from agrl.core.aircraft import AircraftState
    from agrl.core.autopilot import HeldTargets, autopilot_step

    env = GuidanceEnv(targets_params, num_envs=3, seed=1)
    td = env.reset()
    td["action"] = torch.tensor([_action(env.target_table, "heading", -math.pi / 2), _action(env.target_table,
                                 "altitude", 100.0), _action(env.target_table, "speed", 250.0)])
    after = env.step(td)["next"]
    simulation = targets_params.simulation
    autopilot = targets_params.actions.autopilot(targets_params.maneuvers)
    aircraft = AircraftState.from_tensor(td["aircraft_state"])
    targets = HeldTargets(*after["held_targets"].unbind(-1))
    for _ in range(simulation.substeps):
        aircraft = autopilot_step(aircraft, targets, simulation.integration_step, simulation.limits, autopilot)
    expected = aircraft.to_tensor()
    got = after["aircraft_state"]
    assert torch.allclose(got[:, :5], expected[:, :5], rtol=1e-5, atol=1e-3)
    assert torch.allclose(torch.remainder(got[:, 5] - expected[:, 5] + math.pi, 2 * math.pi) - math.pi,
                          torch.zeros(3), atol=1e-4)


def test_restore_on_next_reset_carries_the_held_targets(targets_params):
    env = GuidanceEnv(targets_params, num_envs=2, seed=0)
    td = env.reset()
    td["action"] = torch.tensor([5, 20])
    after = env.step(td)["next"]
    other = GuidanceEnv(targets_params, num_envs=2, seed=9)
    other.restore_on_next_reset(after)
    restored = other.reset()
    assert torch.equal(restored["held_targets"], after["held_targets"])
    assert torch.equal(restored["observation"], after["observation"])


@pytest.mark.parametrize("name", ["baseline-absolute", "baseline-targets"])
def test_a_saved_agent_acts_in_the_env_its_checkpoint_describes(name):
    from agrl.config import TaskConfig, validated_section
    from agrl.rl.models import load_agent

    actor, saved, _ = load_agent(name)
    env = GuidanceEnv.for_saved_agent(saved, 4, seed=0, compile=False)
    assert env.observation_kind == saved["agent"].get("observation", "relative")
    assert env.holds_targets == (saved.get("actions", {}).get("name") == "targets")
    assert env.params.destination.name is MotionKind.FIXED and not env.params.compile
    td = actor(env.reset())
    assert td["action"].shape == (4,) and bool((td["action"] < env.num_actions).all())

    uniform = validated_section(TaskConfig, {"name": "uniform", "speed": 50.0})
    other = GuidanceEnv.for_saved_agent(saved, 2, task=uniform, seed=0)
    assert other.params.destination.name is MotionKind.UNIFORM and other.params.destination.speed == 50.0
    assert other.params.compile == saved["simulation"]["compile"]
