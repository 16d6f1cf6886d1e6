"""Initial aircraft states (Table 1: random position, theta = psi = phi = 0)."""

from __future__ import annotations

import pytest
import torch

from agrl.core.initial_states import InitialStateDistribution, sample_initial_aircraft

DISTRIBUTION = InitialStateDistribution(
    x_range=(-9_000.0, 6_000.0),
    y_range=(-8_000.0, 9_000.0),
    z_range=(100.0, 4_900.0),
    speed_range=(150.0, 220.0),
    min_horizontal_distance=3_000.0,
)


def destinations(count: int, x: float = 0.0, y: float = 0.0) -> torch.Tensor:
    return torch.tensor([x, y, 0.0, 0.0]).expand(count, 4).clone()


def sample(count=4_000, seed=0, distribution=DISTRIBUTION, dest=None):
    generator = torch.Generator().manual_seed(seed)
    dest = destinations(count) if dest is None else dest
    return sample_initial_aircraft(count, distribution, dest, generator)


def test_within_the_box_with_zero_angles():
    states = sample()
    assert states.shape == (4_000, 7)
    for column, (low, high) in enumerate(
        (DISTRIBUTION.x_range, DISTRIBUTION.y_range, DISTRIBUTION.z_range, DISTRIBUTION.speed_range)
    ):
        values = states[:, column]
        assert float(values.min()) >= low and float(values.max()) <= high
        # Uniform over the range, not squeezed into part of it.
        span = high - low
        assert float(values.min()) < low + 0.05 * span and float(values.max()) > high - 0.05 * span
    assert torch.all(states[:, 4:] == 0)  # theta = psi = phi = 0


def test_min_distance_to_the_destination_start():
    dest = destinations(4_000, x=-2_000.0, y=1_000.0)
    states = sample(dest=dest)
    distance = torch.hypot(states[:, 0] - dest[:, 0], states[:, 1] - dest[:, 1])
    assert float(distance.min()) >= DISTRIBUTION.min_horizontal_distance
    # The disc is excluded, not the whole neighbourhood: starts just outside it exist.
    assert float(distance.min()) < DISTRIBUTION.min_horizontal_distance + 300.0


def test_per_row_destinations_are_respected():
    count = 1_000
    dest = torch.zeros(count, 4)
    dest[: count // 2, 0] = -5_000.0
    dest[count // 2 :, 0] = 3_000.0
    states = sample(count, dest=dest)
    distance = torch.hypot(states[:, 0] - dest[:, 0], states[:, 1] - dest[:, 1])
    assert float(distance.min()) >= DISTRIBUTION.min_horizontal_distance


def test_seeded_reproducibility():
    assert torch.equal(sample(500, seed=3), sample(500, seed=3))
    assert not torch.equal(sample(500, seed=3), sample(500, seed=4))


def test_fixed_speed_range():
    distribution = InitialStateDistribution()  # speed_range (200, 200)
    states = sample(100, distribution=distribution)
    assert torch.all(states[:, 3] == 200.0)


def test_impossible_exclusion_raises():
    distribution = InitialStateDistribution(
        x_range=(-100.0, 100.0), y_range=(-100.0, 100.0), min_horizontal_distance=1_000.0
    )
    with pytest.raises(ValueError, match="min_horizontal_distance"):
        sample(10, distribution=distribution)
