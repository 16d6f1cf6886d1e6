"""The policy input: size, finiteness, invariances of the relative features, last-action one-hot."""

from __future__ import annotations

import math

import pytest
import torch

from agrl.core.aircraft import MANEUVER_NAMES
from agrl.core.observation import (
    ABSOLUTE_OBSERVATION_FEATURES,
    OBSERVATION_FEATURES,
    OBSERVATION_SIZE,
    absolute_observation,
    in_destination_frame,
    observation_size,
    policy_observation,
)

INDEX = {name: i for i, name in enumerate(OBSERVATION_FEATURES)}
ABSOLUTE_XY = [INDEX["x"], INDEX["y"]]
NUM_ACTIONS = len(MANEUVER_NAMES)


@pytest.fixture(scope="module")
def airspace(paper_parameters):
    return paper_parameters.simulation.airspace


@pytest.fixture(scope="module")
def observe(paper_parameters):
    """``policy_observation`` with conf's airspace and limits."""
    simulation = paper_parameters.simulation
    return lambda aircraft, destination, last_action: policy_observation(
        aircraft, destination, last_action, simulation.airspace, simulation.limits)


def random_inputs(count: int, seed: int):
    generator = torch.Generator().manual_seed(seed)
    u = lambda *shape: torch.rand(*shape, generator=generator, dtype=torch.float64)  # noqa: E731
    aircraft = torch.stack(
        (
            u(count) * 16_000 - 8_000,
            u(count) * 16_000 - 8_000,
            u(count) * 5_000,
            100 + 150 * u(count),
            (u(count) * 2 - 1) * math.radians(30),  # flight-path angles up to conf's 30 deg limit
            (u(count) * 2 - 1) * math.pi,
            (u(count) * 2 - 1) * 1.2,
        ),
        dim=-1,
    )
    destination = torch.stack(
        (
            u(count) * 16_000 - 8_000,
            u(count) * 16_000 - 8_000,
            u(count) * 5_000,
            (u(count) * 2 - 1) * math.pi,
        ),
        dim=-1,
    )
    last_action = torch.randint(0, NUM_ACTIONS, (count,), generator=generator)
    return aircraft, destination, last_action


def other_columns(exclude):
    return [i for i in range(OBSERVATION_SIZE) if i not in exclude]


def test_shape_and_finite(observe):
    aircraft, destination, last_action = random_inputs(64, seed=0)
    obs = observe(aircraft, destination, last_action)
    assert obs.shape == (64, OBSERVATION_SIZE)
    assert OBSERVATION_SIZE == len(OBSERVATION_FEATURES) == len(set(OBSERVATION_FEATURES))
    one_hot_names = [f"last_action_{name}" for name in MANEUVER_NAMES]
    assert list(OBSERVATION_FEATURES[-NUM_ACTIONS:]) == one_hot_names
    assert torch.isfinite(obs).all()
    # Batch shapes are preserved.
    obs2 = observe(aircraft.reshape(4, 16, 7), destination.reshape(4, 16, 4), last_action.reshape(4, 16))
    assert obs2.shape == (4, 16, OBSERVATION_SIZE)
    torch.testing.assert_close(obs2.reshape(64, -1), obs)


def test_finite_when_aircraft_is_on_the_destination(observe):
    aircraft = torch.tensor([[0.0, 0.0, 0.0, 100.0, 0.0, 0.0, 0.0]])
    destination = torch.zeros(1, 4)
    obs = observe(aircraft, destination, torch.zeros(1, dtype=torch.int64))
    assert torch.isfinite(obs).all()


def test_invariant_to_horizontal_translation(observe, airspace):
    aircraft, destination, last_action = random_inputs(32, seed=1)
    obs = observe(aircraft, destination, last_action)
    shift = torch.tensor([1_234.5, -2_345.6], dtype=torch.float64)
    moved_aircraft, moved_destination = aircraft.clone(), destination.clone()
    moved_aircraft[:, :2] += shift
    moved_destination[:, :2] += shift
    moved = observe(moved_aircraft, moved_destination, last_action)
    keep = other_columns(ABSOLUTE_XY)
    torch.testing.assert_close(moved[:, keep], obs[:, keep], rtol=0, atol=1e-9)
    # The absolute position features do see the shift (x maps 20 km to 2 units).
    expected_dx = 2 * shift[0] / (airspace.x_max - airspace.x_min)
    torch.testing.assert_close(
        moved[:, INDEX["x"]] - obs[:, INDEX["x"]], expected_dx.expand(32), rtol=0, atol=1e-9
    )


def test_invariant_to_rotation(observe):
    aircraft, destination, last_action = random_inputs(32, seed=2)
    obs = observe(aircraft, destination, last_action)
    for angle in (0.3, -2.0, math.pi):
        c, s = math.cos(angle), math.sin(angle)
        rotated_aircraft, rotated_destination = aircraft.clone(), destination.clone()
        for tensor, heading_index in ((rotated_aircraft, 5), (rotated_destination, 3)):
            x, y = tensor[:, 0].clone(), tensor[:, 1].clone()
            tensor[:, 0] = c * x - s * y
            tensor[:, 1] = s * x + c * y
            tensor[:, heading_index] += angle
        rotated = observe(rotated_aircraft, rotated_destination, last_action)
        keep = other_columns(ABSOLUTE_XY)
        torch.testing.assert_close(rotated[:, keep], obs[:, keep], rtol=0, atol=1e-9)


def test_last_action_one_hot(observe):
    aircraft, destination, _ = random_inputs(NUM_ACTIONS, seed=3)
    last_action = torch.arange(NUM_ACTIONS)
    obs = observe(aircraft, destination, last_action)
    one_hot = obs[:, -NUM_ACTIONS:]
    assert torch.equal(one_hot, torch.eye(NUM_ACTIONS, dtype=obs.dtype))
    for name in MANEUVER_NAMES:
        assert INDEX[f"last_action_{name}"] >= OBSERVATION_SIZE - NUM_ACTIONS


def test_geometry_features(observe):
    # Destination 3 km straight ahead (aircraft heading +y), same altitude and heading, aircraft behind it.
    aircraft = torch.tensor([[0.0, -3_000.0, 1_000.0, 175.0, 0.0, math.pi / 2, 0.0]], dtype=torch.float64)
    destination = torch.tensor([[0.0, 0.0, 1_000.0, math.pi / 2]], dtype=torch.float64)
    obs = observe(aircraft, destination, torch.zeros(1, dtype=torch.int64))[0]
    half_width = 10_000.0
    assert float(obs[INDEX["horizontal_distance"]]) == pytest.approx(3_000.0 / half_width)
    assert float(obs[INDEX["bearing_sin"]]) == pytest.approx(0.0, abs=1e-9)
    assert float(obs[INDEX["bearing_cos"]]) == pytest.approx(1.0)
    assert float(obs[INDEX["heading_difference_cos"]]) == pytest.approx(1.0)
    assert float(obs[INDEX["altitude_difference"]]) == pytest.approx(0.0, abs=1e-12)
    assert float(obs[INDEX["speed"]]) == pytest.approx(0.0, abs=1e-12)  # mid-range speed
    assert float(obs[INDEX["altitude"]]) == pytest.approx(-0.6)  # 1000 m of [0, 5000]
    # Heading +y: a destination at -x lies to the left (the +psi side), one at +x to the right.
    right = torch.tensor([[1_000.0, 0.0, 1_000.0, math.pi / 2]], dtype=torch.float64)
    left = torch.tensor([[-1_000.0, 0.0, 1_000.0, math.pi / 2]], dtype=torch.float64)
    at_origin = torch.tensor([[0.0, 0.0, 1_000.0, 175.0, 0.0, math.pi / 2, 0.0]], dtype=torch.float64)
    zero_action = torch.zeros(1, dtype=torch.int64)
    assert float(observe(at_origin, left, zero_action)[0, INDEX["bearing_sin"]]) == pytest.approx(1.0)
    assert float(observe(at_origin, right, zero_action)[0, INDEX["bearing_sin"]]) == pytest.approx(-1.0)


# ---------------------------------------------------------------------------- equation 4 as it stands
ABSOLUTE = {name: i for i, name in enumerate(ABSOLUTE_OBSERVATION_FEATURES)}


def test_absolute_observation_is_equation_4_normalised(paper_parameters):
    simulation = paper_parameters.simulation
    aircraft = torch.tensor([[5_000.0, -2_500.0, 1_000.0, 175.0, math.radians(15), math.pi / 2, 0.45 * math.pi]],
                            dtype=torch.float64)
    destination = torch.tensor([[0.0, 10_000.0, 5_000.0, math.pi]], dtype=torch.float64)
    obs = absolute_observation(aircraft, destination, torch.tensor([3]), simulation.airspace, simulation.limits)[0]
    assert obs.shape == (observation_size("absolute"),) == (len(ABSOLUTE_OBSERVATION_FEATURES),) == (26,)
    expected = {
        "x": 0.5, "y": -0.25, "altitude": -0.6, "speed": 0.0, "flight_path_angle": 0.5,  # 15 of conf's 30 deg
        "heading_sin": 1.0, "heading_cos": 0.0, "bank": 0.9,
        "destination_x": 0.0, "destination_y": 1.0, "destination_altitude": 1.0,
        "destination_heading_sin": 0.0, "destination_heading_cos": -1.0,
        "x_near": math.tanh(2.5), "y_near": math.tanh(-1.25), "altitude_near": math.tanh(2.0),
        "destination_x_near": 0.0, "destination_y_near": math.tanh(5.0), "destination_altitude_near": math.tanh(10.0),
    }
    for name, value in expected.items():
        assert float(obs[ABSOLUTE[name]]) == pytest.approx(value, abs=1e-12), name
    assert obs[-NUM_ACTIONS:].tolist() == [0, 0, 0, 1, 0, 0, 0]


def test_the_destination_frame_keeps_every_relative_feature_and_puts_the_destination_at_the_origin(observe):
    aircraft, destination, last_action = random_inputs(64, seed=4)
    moved, origin = in_destination_frame(aircraft, destination)
    assert torch.equal(origin, torch.zeros_like(destination))
    keep = other_columns([*ABSOLUTE_XY, INDEX["altitude"]])  # the aircraft's place in the airspace moves with it
    torch.testing.assert_close(observe(moved, origin, last_action)[:, keep],
                               observe(aircraft, destination, last_action)[:, keep], rtol=0, atol=1e-9)
    # Speed, flight-path angle and bank are the aircraft's own.
    assert torch.equal(moved[:, [3, 4, 6]], aircraft[:, [3, 4, 6]])


def test_the_destination_frame_is_the_papers_shift_for_a_destination_heading_0():
    aircraft, destination, _ = random_inputs(16, seed=5)
    destination[:, 3] = 0.0
    moved, _ = in_destination_frame(aircraft, destination)
    shifted = aircraft.clone()
    shifted[:, :3] -= destination[:, :3]  # section 5.1: (x_a - x_d, y_a - y_d, z_a - z_d, psi_a - psi_d)
    shifted[:, 5] = torch.atan2(torch.sin(aircraft[:, 5]), torch.cos(aircraft[:, 5]))
    torch.testing.assert_close(moved, shifted, rtol=0, atol=1e-9)


def test_an_unknown_observation_kind_is_one_line():
    with pytest.raises(ValueError, match=r"^observation='polar' is not allowed: one of relative, absolute$"):
        observation_size("polar")


def test_held_target_features_are_what_is_left_to_fly(paper_parameters):
    from agrl.core.observation import HELD_TARGET_FEATURES, held_target_features

    simulation = paper_parameters.simulation
    aircraft = torch.tensor([[0.0, 0.0, 2_000.0, 200.0, 0.0, 0.5, 0.0]] * 2)
    targets = torch.tensor([[0.5, 2_000.0, 200.0], [0.5 + math.pi / 2, 3_000.0, 250.0]])
    features = held_target_features(aircraft, targets, simulation.airspace, simulation.limits)
    assert features.shape == (2, len(HELD_TARGET_FEATURES))
    torch.testing.assert_close(features[0], torch.tensor([0.0, 1.0, 0.0, 0.0]))
    height = simulation.airspace.z_max - simulation.airspace.z_min
    speeds = simulation.limits.max_speed - simulation.limits.min_speed
    torch.testing.assert_close(features[1], torch.tensor([1.0, 0.0, 1_000.0 / height, 50.0 / speeds]))
