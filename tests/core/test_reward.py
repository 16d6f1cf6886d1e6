"""Reward (equations 5-11): terms, switches and the telescoping of the potential-based shaping."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch

from agrl.core.parameters import DestinationMotion
from agrl.core.reward import (
    REWARD_PART_KEYS,
    RewardParameters,
    continuous_action_potential,
    position_potential,
    potential,
    shaping_reward,
    step_reward,
    switch_cost_reward,
    termination_reward,
)
from agrl.core.termination import Outcome
from agrl.envs import GuidanceEnv, GuidanceParameters, MotionKind

CUSTOM = RewardParameters(
    success=7.0,
    out_of_airspace=-3.0,
    budget_exhausted=-2.0,
    action_change=-0.3,
    action_hold=-0.02,
    distance_weight=2e-4,
    heading_weight=0.7,
    altitude_weight=3e-5,
    gamma=0.9,
    use_continuous_action=True,
    use_position=True,
    switch_cost=0.0,
)


@pytest.fixture(scope="module")
def paper_reward(paper_parameters):
    """conf/reward/both.yaml: Table 2's constants, both shaping terms, no switch cost."""
    return paper_parameters.reward


def hand_position_potential(aircraft, destination, params: RewardParameters) -> float:
    ax, ay, az, _, _, apsi, _ = (float(v) for v in aircraft)
    dx, dy, dz, dpsi = (float(v) for v in destination)
    return (
        -params.distance_weight * math.sqrt((ax - dx) ** 2 + (ay - dy) ** 2)
        + params.heading_weight * math.cos(apsi - dpsi)
        - params.altitude_weight * abs(az - dz)
    )


def hand_potential(aircraft, destination, last_action, action_before_last, params: RewardParameters) -> float:
    value = 0.0
    if params.use_continuous_action:
        value += params.action_change if int(last_action) != int(action_before_last) else params.action_hold
    if params.use_position:
        value += hand_position_potential(aircraft, destination, params)
    return value


def random_states(count: int, seed: int):
    generator = torch.Generator().manual_seed(seed)
    aircraft = torch.rand(count, 7, generator=generator, dtype=torch.float64)
    aircraft[:, :2] = aircraft[:, :2] * 20_000 - 10_000
    aircraft[:, 2] *= 5_000
    aircraft[:, 5] = aircraft[:, 5] * 20 - 10  # unwrapped headings
    destination = torch.rand(count, 4, generator=generator, dtype=torch.float64)
    destination[:, :2] = destination[:, :2] * 20_000 - 10_000
    destination[:, 2] *= 5_000
    destination[:, 3] = destination[:, 3] * 2 * math.pi - math.pi
    return aircraft, destination


def test_termination_reward_values(paper_reward):
    outcome = torch.tensor(
        [Outcome.RUNNING, Outcome.SUCCESS, Outcome.OUT_OF_AIRSPACE, Outcome.BUDGET_EXHAUSTED]
    )
    assert termination_reward(outcome, CUSTOM).tolist() == [0.0, 7.0, -3.0, -2.0]
    assert termination_reward(outcome, paper_reward).tolist() == [0.0, 20.0, -20.0, -10.0]  # Table 2


def test_continuous_action_potential():
    last = torch.tensor([0, 1, 2, 6, 3])
    before = torch.tensor([0, 2, 2, 5, 3])
    got = continuous_action_potential(last, before, CUSTOM)
    assert got.tolist() == pytest.approx([-0.02, -0.3, -0.02, -0.3, -0.02])


def test_position_potential_against_hand_computation():
    aircraft, destination = random_states(16, seed=5)
    got = position_potential(aircraft, destination, CUSTOM)
    for i in range(16):
        assert float(got[i]) == pytest.approx(
            hand_position_potential(aircraft[i], destination[i], CUSTOM), rel=1e-9, abs=1e-12
        )


def test_position_potential_terms(paper_reward):
    params = paper_reward
    dest = torch.tensor([0.0, 0.0, 0.0, 0.0])
    # 3-4-5 triangle (5 km), 1 km above, same heading: -0.5 + 0.5 - 0.01.
    on_track = position_potential(
        torch.tensor([3_000.0, 4_000.0, 1_000.0, 200.0, 0.0, 0.0, 0.0]), dest, params
    )
    assert float(on_track) == pytest.approx(-0.5 + 0.5 - 0.01, abs=1e-6)
    # Opposite heading costs 2 * c7, closer is better.
    reverse = position_potential(
        torch.tensor([3_000.0, 4_000.0, 1_000.0, 200.0, 0.0, math.pi, 0.0]), dest, params
    )
    assert float(on_track - reverse) == pytest.approx(2 * params.heading_weight, abs=1e-6)
    closer = position_potential(torch.tensor([300.0, 400.0, 1_000.0, 200.0, 0.0, 0.0, 0.0]), dest, params)
    assert float(closer) > float(on_track)


def test_potential_switches_and_terminal(paper_reward):
    aircraft, destination = random_states(8, seed=9)
    last = torch.tensor([0, 1, 1, 2, 3, 4, 5, 6])
    before = torch.tensor([0, 0, 1, 2, 4, 4, 6, 6])
    not_terminal = torch.zeros(8, dtype=torch.bool)
    for use_c in (True, False):
        for use_p in (True, False):
            params = dataclasses.replace(paper_reward, use_continuous_action=use_c, use_position=use_p)
            got = potential(aircraft, destination, last, before, not_terminal, params)
            expected = [
                hand_potential(aircraft[i], destination[i], last[i], before[i], params) for i in range(8)
            ]
            assert got.tolist() == pytest.approx(expected, rel=1e-6, abs=1e-6)
            if not use_c and not use_p:
                assert got.tolist() == [0.0] * 8
    terminal = torch.tensor([True, False] * 4)
    got = potential(aircraft, destination, last, before, terminal, paper_reward)
    assert got[terminal].tolist() == [0.0] * 4
    assert all(v != 0.0 for v in got[~terminal].tolist())


def test_shaping_reward():
    before = torch.tensor([1.0, -2.0, 0.5])
    after = torch.tensor([0.5, -1.0, 0.0])
    shaping = shaping_reward(before, after, CUSTOM)
    assert shaping.tolist() == pytest.approx([0.9 * 0.5 - 1.0, 0.9 * -1.0 + 2.0, -0.5])


@pytest.mark.parametrize(("use_c", "use_p", "switch_cost"),
                         [(True, True, 0.0), (True, False, 0.25), (False, True, 0.25), (False, False, 0.0)])
def test_step_reward_by_hand(use_c, use_p, switch_cost):
    """Equation 5 plus the switch cost, part by part: S_t = (aircraft, destination, last, before_last),
    S_{t+1} = (next aircraft, next destination, action, last), terminal unless the outcome is RUNNING."""
    params = dataclasses.replace(CUSTOM, use_continuous_action=use_c, use_position=use_p, switch_cost=switch_cost)
    aircraft, destination = random_states(8, seed=5)
    next_aircraft, next_destination = random_states(8, seed=6)
    last = torch.tensor([0, 3, 3, 1, 1, 0, 2, 2])
    before_last = torch.tensor([0, 0, 3, 3, 1, 1, 2, 5])
    action = torch.tensor([0, 3, 1, 1, 0, 0, 2, 6])
    outcome = torch.tensor([Outcome.RUNNING, Outcome.RUNNING, Outcome.SUCCESS, Outcome.OUT_OF_AIRSPACE,
                            Outcome.BUDGET_EXHAUSTED, Outcome.RUNNING, Outcome.SUCCESS, Outcome.RUNNING])
    total, parts = step_reward(outcome, aircraft, destination, last, before_last, action, next_aircraft,
                               next_destination, params, action != last)
    assert tuple(parts) == REWARD_PART_KEYS
    torch.testing.assert_close(sum(parts.values()), total, rtol=0, atol=0)
    termination_values = {Outcome.RUNNING: 0.0, Outcome.SUCCESS: 7.0, Outcome.OUT_OF_AIRSPACE: -3.0,
                          Outcome.BUDGET_EXHAUSTED: -2.0}
    for i in range(8):
        running = int(outcome[i]) == Outcome.RUNNING
        c_before = params.action_change if int(last[i]) != int(before_last[i]) else params.action_hold
        c_after = params.action_change if int(action[i]) != int(last[i]) else params.action_hold
        p_before = hand_position_potential(aircraft[i], destination[i], params)
        p_after = hand_position_potential(next_aircraft[i], next_destination[i], params)
        expected = {
            "reward_termination": termination_values[Outcome(int(outcome[i]))],
            "reward_action_shaping": (0.9 * c_after * running - c_before) * use_c,
            "reward_position_shaping": (0.9 * p_after * running - p_before) * use_p,
            "reward_switch_cost": -switch_cost * (int(action[i]) != int(last[i])),
        }
        for key, value in expected.items():
            assert float(parts[key][i]) == pytest.approx(value, rel=1e-6, abs=1e-6), (key, i)
        assert float(total[i]) == pytest.approx(sum(expected.values()), rel=1e-6, abs=1e-6)


def run_episodes(params: GuidanceParameters, num_envs: int, seed: int):
    """Random policy until every row has finished; per row: initial state, steps up to the first done."""
    env = GuidanceEnv(params, num_envs=num_envs, seed=seed)
    generator = torch.Generator().manual_seed(seed)
    td = env.reset()
    start = td.clone()
    records = []
    finished = torch.zeros(num_envs, dtype=torch.bool)
    for _ in range(params.max_decisions):
        td["action"] = torch.randint(0, 7, (num_envs,), generator=generator)
        td = env.step(td)
        records.append(td["next"].clone())
        finished |= td["next", "done"].squeeze(-1)
        if bool(finished.all()):
            break
        td = env.step_mdp(td)
    assert bool(finished.all())
    return start, records


@pytest.mark.parametrize(
    "kind,reward_changes",
    [
        (MotionKind.FIXED, {}),
        (MotionKind.CURVED, {"gamma": 0.9, "use_continuous_action": True, "use_position": True}),
    ],
)
def test_shaping_telescopes_over_an_episode(kind, reward_changes, paper_parameters):
    reward = dataclasses.replace(paper_parameters.reward, **reward_changes)
    destination = DestinationMotion(name=kind, speed=20.0, radius=1_000.0, turn_direction=1.0)
    params = dataclasses.replace(paper_parameters, max_decisions=12, reward=reward, destination=destination)
    num_envs = 4
    start, records = run_episodes(params, num_envs, seed=11)
    gamma = reward.gamma
    outcomes_seen = set()
    for row in range(num_envs):
        phi0 = hand_potential(
            start["aircraft_state"][row],
            start["destination_state"][row],
            start["last_action"][row],
            start["action_before_last"][row],
            reward,
        )
        shaped_sum = 0.0  # float64 accumulation
        for t, nxt in enumerate(records):
            outcome = int(nxt["outcome"][row])
            terminal_reward = float(termination_reward(torch.tensor(outcome), reward))
            shaped_sum += gamma**t * (float(nxt["reward"][row, 0]) - terminal_reward)
            if bool(nxt["done"][row, 0]):
                outcomes_seen.add(outcome)
                assert outcome != Outcome.RUNNING
                # Phi(terminal) = 0: sum_t gamma^t F_t = -Phi(S_0).
                assert shaped_sum == pytest.approx(-phi0, abs=1e-4)
                break
            # Before the end, each prefix telescopes to gamma^(t+1) Phi(S_{t+1}) - Phi(S_0).
            phi_next = hand_potential(
                nxt["aircraft_state"][row],
                nxt["destination_state"][row],
                nxt["last_action"][row],
                nxt["action_before_last"][row],
                reward,
            )
            assert shaped_sum == pytest.approx(gamma ** (t + 1) * phi_next - phi0, abs=1e-4)
        else:
            pytest.fail(f"row {row} never finished")
    assert outcomes_seen  # at least one terminal kind observed


EPISODE_START = torch.tensor([-5_000.0, 0.0, 2_500.0, 200.0, 0.0, 0.0, 0.0])  # mid-airspace, heading +x


def env_rewards(params: GuidanceParameters, reward_params: RewardParameters,
                actions: list[int]) -> tuple[list[float], int]:
    """The env's reward (``params`` with ``reward_params``) at each decision of ``actions`` from EPISODE_START
    (none ends the episode), and the episode's instruction count."""
    env = GuidanceEnv(dataclasses.replace(params, reward=reward_params), num_envs=1, seed=0)
    td = env.reset(env.scenario(aircraft_state=EPISODE_START))
    out = []
    for action in actions:
        td["action"] = torch.tensor([action])
        td = env.step(td)
        assert td["next", "outcome"].tolist() == [Outcome.RUNNING]
        out.append(float(td["next", "reward"]))
        td = env.step_mdp(td)
    return out, int(td["instruction_count"])


def test_env_reward_switches(paper_parameters):
    actions = [0, 3, 3, 1]  # hold, change, hold, change

    def rewards(reward_params):
        return env_rewards(paper_parameters, reward_params, actions)[0]

    def shaping(use_continuous_action, use_position):
        return dataclasses.replace(paper_parameters.reward, use_continuous_action=use_continuous_action,
                                   use_position=use_position)

    gamma = 0.99
    off = rewards(shaping(False, False))
    assert off == [0.0] * len(actions)
    c4, c5 = -0.1, -0.01
    only_c = rewards(shaping(True, False))
    # C(S_0) = c5 (no previous change); C(S_{t+1}) is c4 if A_t != A_{t-1}.
    expected_c = [gamma * c5 - c5, gamma * c4 - c5, gamma * c5 - c4, gamma * c4 - c5]
    assert only_c == pytest.approx(expected_c, abs=1e-6)
    only_p = rewards(shaping(False, True))
    both = rewards(paper_parameters.reward)
    assert both == pytest.approx([c + p for c, p in zip(only_c, only_p, strict=True)], abs=1e-5)
    # Flying towards the destination: the position shaping is positive on the first (steady) step.
    assert only_p[0] > 0


# ---------------------------------------------------------------------------- switch cost (not in the paper)
def test_switch_cost_reward_by_hand(paper_reward):
    # An episode starts in steady flight (0); each decision compares with the maneuver being flown.
    actions = torch.tensor([0, 3, 3, 1, 1, 0])
    previous = torch.tensor([0, 0, 3, 3, 1, 1])
    priced = dataclasses.replace(paper_reward, switch_cost=0.25)
    got = switch_cost_reward(actions != previous, priced)  # the maneuvers' instructions (GuidanceEnv's rule)
    assert got.tolist() == [0.0, -0.25, 0.0, -0.25, 0.0, -0.25]
    # Off in the paper's rewards (conf/reward/both.yaml), so its four variants are unchanged.
    assert switch_cost_reward(actions != previous, paper_reward).tolist() == [0.0] * 6


def test_env_switch_cost_adds_minus_cost_per_instruction(paper_parameters):
    actions = [2, 2, 0, 5, 5, 6]  # instructions: 0->2, 2->0, 0->5, 5->6 = 4
    cost = 0.4
    plain, _ = env_rewards(paper_parameters, paper_parameters.reward, actions)
    priced, instructions = env_rewards(paper_parameters, dataclasses.replace(paper_parameters.reward,
                                                                             switch_cost=cost), actions)
    assert instructions == 4
    expected = [p - cost * c for p, c in zip(plain, [1, 0, 1, 1, 0, 1], strict=True)]
    assert priced == pytest.approx(expected, abs=1e-6)
