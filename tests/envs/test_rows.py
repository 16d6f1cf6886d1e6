"""The one-row Python forms (agrl/rows.py) compute what agrl.core's batched torch functions compute."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch

from agrl.core.aircraft import AircraftLimits
from agrl.core.initial_states import sample_initial_aircraft, scale_distribution
from agrl.core.observation import OBSERVATION_SIZE, policy_observation
from agrl.core.reward import potential, step_reward
from agrl.core.termination import Airspace, Outcome
from agrl.rows import initial_aircraft_row, observation_row, potential_row, step_reward_row


def random_states(count: int, seed: int = 0):
    """Aircraft and destinations all over (and a little outside) the airspace, any angles, any last actions."""
    generator = torch.Generator().manual_seed(seed)

    def uniform(low, high):
        return low + (high - low) * torch.rand(count, generator=generator, dtype=torch.float64)

    aircraft = torch.stack((uniform(-10_500, 10_500), uniform(-10_500, 10_500), uniform(-100, 5_100),
                            uniform(100, 250), uniform(-0.52, 0.52), uniform(-7, 7), uniform(-1.2, 1.2)), -1)
    destination = torch.stack((uniform(-10_000, 10_000), uniform(-10_000, 10_000), uniform(0, 5_000),
                               uniform(-7, 7)), -1)
    actions = torch.randint(0, 7, (2, count), generator=generator)
    return aircraft, destination, actions[0], actions[1]


def test_observation_row_equals_policy_observation(paper_parameters):
    airspace, limits = paper_parameters.simulation.airspace, paper_parameters.simulation.limits
    aircraft, destination, last_action, _ = random_states(500)
    expected = policy_observation(aircraft, destination, last_action, airspace, limits)
    assert expected.dtype == torch.float64 and expected.shape == (500, OBSERVATION_SIZE)
    for index in range(500):
        row = observation_row(aircraft[index].tolist(), destination[index].tolist(), int(last_action[index]),
                              airspace, limits)
        torch.testing.assert_close(torch.tensor(row, dtype=torch.float64), expected[index], rtol=0, atol=1e-12)


def test_observation_row_follows_a_different_airspace():
    airspace = Airspace(x_min=-3_000.0, x_max=5_000.0, y_min=-1_000.0, y_max=2_000.0, z_min=100.0, z_max=900.0)
    limits = AircraftLimits(min_speed=80.0, max_speed=300.0, max_flight_path_angle_deg=17.0)
    aircraft, destination, last_action, _ = random_states(50, seed=1)
    expected = policy_observation(aircraft, destination, last_action, airspace, limits)
    for index in range(50):
        row = observation_row(aircraft[index].tolist(), destination[index].tolist(), int(last_action[index]),
                              airspace, limits)
        torch.testing.assert_close(torch.tensor(row, dtype=torch.float64), expected[index], rtol=0, atol=1e-12)


@pytest.mark.parametrize(("continuous", "position", "switch_cost"),
                         [(True, True, 0.0), (True, False, 0.0), (False, True, 0.0), (False, False, 0.0),
                          (True, True, 0.1)])
def test_potential_and_reward_rows_equal_the_torch_reward(continuous, position, switch_cost, paper_parameters):
    """potential_row is agrl.core.reward.potential and step_reward_row (on two potential_row values) is the total
    of agrl.core.reward.step_reward, the one batched assembly of the reward, on random transitions."""
    params = dataclasses.replace(paper_parameters.reward, use_continuous_action=continuous, use_position=position,
                                 switch_cost=switch_cost)
    aircraft, destination, last_action, before_last = random_states(200, seed=2)
    next_aircraft, next_destination, action, _ = random_states(200, seed=3)
    before_last[::3] = last_action[::3]  # held actions too (equation 9's c5) ...
    action[1::3] = last_action[1::3]  # ... and decisions that hold the maneuver (no switch cost)
    outcome = torch.arange(200) % len(Outcome)  # every outcome; S_{t+1} is terminal unless RUNNING
    terminal = outcome != Outcome.RUNNING
    # float64 inputs: the continuous-action term is float32 in agrl.core (c4, c5 are exact in neither)
    expected_before = potential(aircraft, destination, last_action, before_last, torch.zeros_like(terminal), params)
    expected_after = potential(next_aircraft, next_destination, action, last_action, terminal, params)
    expected_reward, _ = step_reward(outcome, aircraft, destination, last_action, before_last, action,
                                     next_aircraft, next_destination, params, action != last_action)
    for index in range(200):
        before = potential_row(aircraft[index].tolist(), destination[index].tolist(), int(last_action[index]),
                               int(before_last[index]), False, params)
        after = potential_row(next_aircraft[index].tolist(), next_destination[index].tolist(), int(action[index]),
                              int(last_action[index]), bool(terminal[index]), params)
        assert math.isclose(before, float(expected_before[index]), rel_tol=0, abs_tol=1e-7)
        assert math.isclose(after, float(expected_after[index]), rel_tol=0, abs_tol=1e-7)
        reward = step_reward_row(int(outcome[index]), before, after, params,
                                 switched=bool(action[index] != last_action[index]))
        assert math.isclose(reward, float(expected_reward[index]), rel_tol=0, abs_tol=1e-6)


@pytest.mark.parametrize("box", ["full", "curriculum", "crowded"])
def test_initial_aircraft_row_draws_the_starts_of_sample_initial_aircraft(box, paper_parameters):
    full = paper_parameters.initial_state
    distribution = {
        "full": full,
        "curriculum": scale_distribution(full, 0.15, (0.0, 0.0, 0.0), 200.0),  # the curriculum's first box
        # a box the exclusion disc nearly fills (many redraws) and a speed range whose bounds float32 rounds
        "crowded": dataclasses.replace(full, x_range=(-3_000.0, 3_000.0), y_range=(-2_500.0, 2_500.0),
                                       speed_range=(120.3, 250.7), min_horizontal_distance=1_999.9),
    }[box]
    start = torch.tensor([[123.456, -987.654, 0.0, 0.3]])
    batched, one_row = torch.Generator().manual_seed(3), torch.Generator().manual_seed(3)
    for _ in range(500):  # the two generators must also stay in step (the same number of draws)
        expected = sample_initial_aircraft(1, distribution, start, batched)[0].tolist()
        assert list(initial_aircraft_row(distribution, start[0].tolist(), one_row)) == expected
    with pytest.raises(ValueError, match="min_horizontal_distance"):
        initial_aircraft_row(dataclasses.replace(full, min_horizontal_distance=1e6), (0.0, 0.0), one_row)
