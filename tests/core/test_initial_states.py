"""Initial aircraft states (Table 1: random position, theta = psi = phi = 0)."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from agrl.core.initial_states import InitialStateDistribution, sample_initial_aircraft, scale_distribution
from agrl.core.termination import is_success

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


def test_fixed_speed_range(paper_start):
    distribution = paper_start  # speed_range (200, 200)
    states = sample(100, distribution=distribution)
    assert torch.all(states[:, 3] == 200.0)


def test_impossible_exclusion_raises():
    distribution = dataclasses.replace(
        DISTRIBUTION, x_range=(-100.0, 100.0), y_range=(-100.0, 100.0), min_horizontal_distance=1_000.0
    )
    with pytest.raises(ValueError, match="min_horizontal_distance"):
        sample(10, distribution=distribution)


# ---------------------------------------------------------------------------- the start-box curriculum
@pytest.fixture(scope="module")
def paper_start(paper_parameters):
    """conf/simulation/paper.yaml's start box."""
    return paper_parameters.initial_state


@pytest.fixture(scope="module")
def tolerance(paper_parameters):
    """conf's equation 2 tolerances: d_e = 1 km, z_e = 200 m, psi_e = 30 deg."""
    return paper_parameters.simulation.tolerance


#: The scales the trainer visits with conf/config.yaml's curriculum (0.15, then +0.1 per promotion, capped at 1).
CURRICULUM_SCALES = [0.15 + 0.1 * step for step in range(9)] + [1.0]


@pytest.mark.parametrize("scale", CURRICULUM_SCALES)
def test_no_curriculum_start_satisfies_equation_2(scale, paper_start, tolerance):
    destination_start = (0.0, 0.0, 0.0)
    distribution = scale_distribution(paper_start, scale, destination_start, success_distance=tolerance.distance)
    count = 20_000
    dest = destinations(count)
    states = sample(count, seed=int(scale * 100), distribution=distribution, dest=dest)
    solved = is_success(states[:, 0], states[:, 1], states[:, 2], states[:, 5],
                        dest[:, 0], dest[:, 1], dest[:, 2], dest[:, 3], tolerance)
    assert int(solved.sum()) == 0
    # The starts really do crowd the destination at small scales (the curriculum is not a no-op).
    distance = torch.hypot(states[:, 0], states[:, 1])
    assert float(distance.min()) < tolerance.distance + 50.0 + 2_000.0 * scale


def test_unfloored_exclusion_disc_would_start_solved(paper_start, tolerance):
    # The scale-0.15 box with the exclusion disc scaled as before the floor (300 m): about a tenth
    # of the starts satisfy equation 2 at once, which is what the floor prevents.
    shrunk = scale_distribution(paper_start, 0.15, (0.0, 0.0, 0.0), success_distance=tolerance.distance)
    unfloored = dataclasses.replace(shrunk, min_horizontal_distance=0.15 * paper_start.min_horizontal_distance)
    dest = destinations(20_000)
    states = sample(20_000, distribution=unfloored, dest=dest)
    solved = is_success(states[:, 0], states[:, 1], states[:, 2], states[:, 5],
                        dest[:, 0], dest[:, 1], dest[:, 2], dest[:, 3], tolerance)
    assert 0.05 < float(solved.float().mean()) < 0.2


def test_scale_shrinks_the_box_about_the_destination(paper_start, tolerance):
    destination_start = (-2_000.0, 1_000.0, 0.0)
    scaled = scale_distribution(paper_start, 0.5, destination_start, success_distance=tolerance.distance)
    # Each horizontal bound moves halfway towards the destination; the altitude band halves from its floor.
    assert scaled.x_range == (-2_000.0 + 0.5 * (-9_500.0 + 2_000.0), -2_000.0 + 0.5 * (7_000.0 + 2_000.0))
    assert scaled.y_range == (1_000.0 + 0.5 * (-9_500.0 - 1_000.0), 1_000.0 + 0.5 * (9_500.0 - 1_000.0))
    assert scaled.z_range == (0.0, 2_500.0)
    assert scaled.min_horizontal_distance == 1_000.0  # 0.5 * 2 km, exactly the floor
    assert scale_distribution(paper_start, 1.0, destination_start, tolerance.distance) == paper_start


@pytest.mark.parametrize("scale", [0.0, -0.1, 1.5])
def test_scale_outside_unit_interval_is_refused(scale, paper_start, tolerance):
    with pytest.raises(ValueError, match=f"scale={scale} is not allowed"):
        scale_distribution(paper_start, scale, (0.0, 0.0, 0.0), success_distance=tolerance.distance)
