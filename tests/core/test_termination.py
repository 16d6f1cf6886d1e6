"""Episode termination: success (equation 2, checked at every 20 ms step), airspace exit, decision budget."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch

from agrl.core.aircraft import MANEUVER_NAMES
from agrl.core.reward import RewardParameters
from agrl.core.simulation import DecisionSimulator
from agrl.core.termination import Outcome, SuccessTolerance, decision_outcome, is_outside_airspace, is_success
from agrl.envs import GuidanceEnv

TOLERANCE = SuccessTolerance(distance=1_000.0, altitude=200.0, heading_deg=30.0)


def success(aircraft, destination, tolerance=TOLERANCE) -> bool:
    """aircraft = (x, y, z, psi), destination = (x, y, z, psi)."""
    a = [torch.tensor(float(v), dtype=torch.float64) for v in aircraft]
    d = [torch.tensor(float(v), dtype=torch.float64) for v in destination]
    return bool(is_success(*a, *d, tolerance))


def test_is_success_distance_tolerance():
    dest = (100.0, -200.0, 1_000.0, 0.0)
    # 600-800-1000 triangle: exactly on the boundary counts, just beyond does not.
    assert success((700.0, 600.0, 1_000.0, 0.0), dest)
    assert success((100.0 + 999.0, -200.0, 1_000.0, 0.0), dest)
    assert not success((100.0 + 1_001.0, -200.0, 1_000.0, 0.0), dest)
    assert not success((100.0 + 720.0, -200.0 + 720.0, 1_000.0, 0.0), dest)  # 1018 m diagonally
    assert success((100.0 + 700.0, -200.0 - 700.0, 1_000.0, 0.0), dest)  # 990 m diagonally


def test_is_success_altitude_tolerance():
    dest = (0.0, 0.0, 1_000.0, 0.0)
    assert success((0.0, 0.0, 1_199.0, 0.0), dest)
    assert success((0.0, 0.0, 801.0, 0.0), dest)
    assert not success((0.0, 0.0, 1_201.0, 0.0), dest)
    assert not success((0.0, 0.0, 799.0, 0.0), dest)


def test_is_success_heading_tolerance_and_wrap_around():
    dest = (0.0, 0.0, 0.0, math.radians(10))
    assert success((0.0, 0.0, 0.0, math.radians(39)), dest)
    assert success((0.0, 0.0, 0.0, math.radians(-19)), dest)
    assert not success((0.0, 0.0, 0.0, math.radians(41)), dest)
    assert not success((0.0, 0.0, 0.0, math.radians(-21)), dest)
    # 179 deg and -179 deg are 2 deg apart.
    narrow = SuccessTolerance(distance=1_000.0, altitude=200.0, heading_deg=5.0)
    assert success((0.0, 0.0, 0.0, math.radians(179)), (0.0, 0.0, 0.0, math.radians(-179)), narrow)
    assert success((0.0, 0.0, 0.0, math.radians(-179)), (0.0, 0.0, 0.0, math.radians(179)), narrow)
    # Unwrapped headings (several turns apart) are compared modulo 2 pi.
    assert success(
        (0.0, 0.0, 0.0, math.radians(179) + 4 * math.pi), (0.0, 0.0, 0.0, math.radians(-179)), narrow
    )
    tight = SuccessTolerance(distance=1_000.0, altitude=200.0, heading_deg=1.0)
    assert not success((0.0, 0.0, 0.0, math.radians(179)), (0.0, 0.0, 0.0, math.radians(-179)), tight)
    # Opposite headings never succeed, whatever the position.
    assert not success((0.0, 0.0, 0.0, math.pi), (0.0, 0.0, 0.0, 0.0))


def test_is_success_is_batched():
    x = torch.tensor([0.0, 2_000.0, 0.0, 0.0])
    z = torch.tensor([0.0, 0.0, 500.0, 0.0])
    psi = torch.tensor([0.0, 0.0, 0.0, 2.0])
    zeros = torch.zeros(4)
    got = is_success(x, zeros, z, psi, zeros, zeros, zeros, zeros, TOLERANCE)
    assert got.tolist() == [True, False, False, False]


def test_is_outside_airspace_each_wall(paper_parameters):
    space = paper_parameters.simulation.airspace  # Table 1: 20 km x 20 km x 5 km
    points = [
        ((0.0, 0.0, 2_500.0), False),
        ((10_000.0, 10_000.0, 5_000.0), False),  # the boundary is inside
        ((-10_000.0, -10_000.0, 0.0), False),
        ((10_000.1, 0.0, 100.0), True),
        ((-10_000.1, 0.0, 100.0), True),
        ((0.0, 10_000.1, 100.0), True),
        ((0.0, -10_000.1, 100.0), True),
        ((0.0, 0.0, 5_000.1), True),
        ((0.0, 0.0, -0.1), True),
    ]
    xyz = torch.tensor([p for p, _ in points], dtype=torch.float64)
    got = is_outside_airspace(xyz[:, 0], xyz[:, 1], xyz[:, 2], space)
    assert got.tolist() == [outside for _, outside in points]


def test_success_is_caught_when_passing_through_between_decisions(paper_parameters):
    # 250 m/s for 3 s = 750 m per decision: from x = -400 m to x = +350 m. Both decision boundaries are
    # outside d_e = 300 m, but the straight path crosses the destination mid-decision.
    tolerance = SuccessTolerance(distance=300.0, altitude=200.0, heading_deg=30.0)
    params = dataclasses.replace(paper_parameters.simulation, tolerance=tolerance)
    simulator = DecisionSimulator(params, paper_parameters.maneuvers.controls(), compile=False)
    aircraft = torch.tensor([[-400.0, 0.0, 1_000.0, 250.0, 0.0, 0.0, 0.0]])
    dest = torch.tensor([[0.0, 0.0, 1_000.0, 0.0]])
    zero = torch.zeros(1)
    # A check at decision boundaries only would miss it:
    unconstrained_end = -400.0 + 250.0 * 3.0
    assert abs(-400.0) > 300.0 and abs(unconstrained_end) > 300.0
    result = simulator(aircraft, dest, zero, zero, torch.zeros(1, dtype=torch.int64))
    assert result.outcome.tolist() == [Outcome.SUCCESS]
    # The row is frozen at the first integration step inside the tolerance region (5 m steps).
    x = float(result.aircraft_state[0, 0])
    assert -300.0 <= x <= -295.0
    assert success((x, 0.0, 1_000.0, 0.0), (0.0, 0.0, 1_000.0, 0.0), tolerance)


def test_out_of_airspace_is_detected_mid_decision_and_frozen(paper_parameters):
    simulator = DecisionSimulator(paper_parameters.simulation, paper_parameters.maneuvers.controls(), compile=False)
    aircraft = torch.tensor(
        [
            [9_800.0, 0.0, 2_500.0, 200.0, 0.0, 0.0, 0.0],  # leaves through +x
            [5_000.0, 0.0, 60.0, 200.0, -0.3, 0.0, 0.0],  # hits the floor
            [0.0, 5_000.0, 2_500.0, 200.0, 0.0, 0.0, 0.0],
        ]
    )  # stays in
    dest = torch.tensor([0.0, 0.0, 0.0, 0.0]).expand(3, 4)
    zeros = torch.zeros(3)
    result = simulator(aircraft, dest, zeros, zeros, torch.zeros(3, dtype=torch.int64))
    assert result.outcome.tolist() == [Outcome.OUT_OF_AIRSPACE, Outcome.OUT_OF_AIRSPACE, Outcome.RUNNING]
    # Frozen at the first step outside (4 m per step), not carried on to the decision's end.
    assert 10_000.0 < float(result.aircraft_state[0, 0]) <= 10_004.0
    assert -1.2 <= float(result.aircraft_state[1, 2]) < 0.0


# ---------------------------------------------------------------- through the environment
def hand_potential(aircraft, destination, changed: bool, params: RewardParameters) -> float:
    """Equation 8 computed with math: C + c6 D + c7 H + c8 A."""
    ax, ay, az, _, _, apsi, _ = (float(v) for v in aircraft)
    dx, dy, dz, dpsi = (float(v) for v in destination)
    c = params.action_change if changed else params.action_hold
    return (
        c
        - params.distance_weight * math.hypot(ax - dx, ay - dy)
        + params.heading_weight * math.cos(apsi - dpsi)
        - params.altitude_weight * abs(az - dz)
    )


def step(env, td, action: int):
    td["action"] = torch.full(env.batch_size, action, dtype=torch.int64)
    return env.step(td)


def test_env_out_of_airspace_ends_episode_with_c2_plus_shaping(paper_parameters):
    params = paper_parameters
    env = GuidanceEnv(params, num_envs=1, seed=0)
    start = [9_800.0, 0.0, 2_500.0, 200.0, 0.0, 0.0, 0.0]
    td = env.reset(env.scenario(aircraft_state=torch.tensor(start)))
    td = step(env, td, 0)
    nxt = td["next"]
    assert nxt["outcome"].tolist() == [Outcome.OUT_OF_AIRSPACE]
    assert nxt["done"].tolist() == [[True]] and nxt["terminated"].tolist() == [[True]]
    reward = params.reward
    # Phi(terminal) = 0, so R = c2 + gamma * 0 - Phi(S_0).
    expected = reward.out_of_airspace - hand_potential(start, (0, 0, 0, 0), False, reward)
    assert float(nxt["reward"]) == pytest.approx(expected, abs=1e-5)


def test_env_budget_exhaustion_gives_c3(paper_parameters):
    params = dataclasses.replace(paper_parameters, max_decisions=2)
    env = GuidanceEnv(params, num_envs=1, seed=0)
    start = [-5_000.0, 0.0, 2_500.0, 200.0, 0.0, 0.0, 0.0]
    td = env.reset(env.scenario(aircraft_state=torch.tensor(start)))
    td = step(env, td, 0)
    first = td["next"]
    assert first["outcome"].tolist() == [Outcome.RUNNING]
    assert first["done"].tolist() == [[False]]
    reward = params.reward
    phi0 = hand_potential(start, (0, 0, 0, 0), False, reward)
    phi1 = hand_potential(first["aircraft_state"][0], first["destination_state"][0], False, reward)
    assert float(first["reward"]) == pytest.approx(reward.gamma * phi1 - phi0, abs=1e-5)

    td = env.step_mdp(td)
    td = step(env, td, 3)  # accelerate: the action changes, but the terminal potential is 0 anyway
    second = td["next"]
    assert second["outcome"].tolist() == [Outcome.BUDGET_EXHAUSTED]
    assert second["done"].tolist() == [[True]] and second["terminated"].tolist() == [[True]]
    assert int(second["step_count"]) == 2
    assert float(second["reward"]) == pytest.approx(reward.budget_exhausted - phi1, abs=1e-5)


def test_env_airspace_exit_on_last_decision_is_not_budget_exhaustion(paper_parameters):
    env = GuidanceEnv(dataclasses.replace(paper_parameters, max_decisions=1), num_envs=2, seed=0)
    start = torch.tensor(
        [[9_800.0, 0.0, 2_500.0, 200.0, 0.0, 0.0, 0.0], [-5_000.0, 0.0, 2_500.0, 200.0, 0.0, 0.0, 0.0]]
    )
    td = env.reset(env.scenario(aircraft_state=start))
    nxt = step(env, td, 0)["next"]
    assert nxt["outcome"].tolist() == [Outcome.OUT_OF_AIRSPACE, Outcome.BUDGET_EXHAUSTED]


def test_env_success_pays_c1(paper_parameters):
    params = paper_parameters
    env = GuidanceEnv(params, num_envs=1, seed=0)
    # Flying straight at the fixed destination (0, 0, 0, 0) at 100 m altitude: inside d_e within 3 s.
    start = [-1_200.0, 0.0, 100.0, 200.0, 0.0, 0.0, 0.0]
    td = env.reset(env.scenario(aircraft_state=torch.tensor(start)))
    nxt = step(env, td, MANEUVER_NAMES.index("steady_flight"))["next"]
    assert nxt["outcome"].tolist() == [Outcome.SUCCESS]
    expected = params.reward.success - hand_potential(start, (0, 0, 0, 0), False, params.reward)
    assert float(nxt["reward"]) == pytest.approx(expected, abs=1e-5)


def test_a_decision_ends_the_episode_at_its_budget_only_if_the_simulator_left_it_running():
    simulated = torch.tensor([Outcome.RUNNING, Outcome.RUNNING, Outcome.SUCCESS, Outcome.OUT_OF_AIRSPACE])
    at_budget = torch.full((4,), 30)
    assert decision_outcome(simulated, at_budget, max_decisions=30).tolist() == [
        Outcome.BUDGET_EXHAUSTED, Outcome.BUDGET_EXHAUSTED, Outcome.SUCCESS, Outcome.OUT_OF_AIRSPACE]
    assert decision_outcome(simulated, at_budget - 1, max_decisions=30).tolist() == simulated.tolist()
