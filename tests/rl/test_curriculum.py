"""The start-box curriculum's promotion rule and start box (agrl.rl.curriculum)."""

from __future__ import annotations

import dataclasses

import pytest

from agrl.core.initial_states import scale_distribution
from agrl.rl.curriculum import promoted_scale, start_distribution


def test_promotion_steps_up_only_on_enough_success_and_stops_at_one():
    scale, visited = 0.15, []
    for success in (0.5, 0.8, None, 0.79, 0.95, 1.0, 0.9, 0.9, 0.9, 0.9, 0.9, 0.9, 0.9):
        scale = promoted_scale(scale, success, scale_step=0.1, promotion_success=0.8)
        visited.append(scale)
    # 0.5 and 0.79 are below the threshold, None is an iteration in which no episode finished.
    assert visited == [0.15, 0.25, 0.25, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75, 0.85, 0.95, 1.0, 1.0]


@pytest.mark.parametrize("scale", [0.15, 0.55, 1.0, 1.2])
def test_start_distribution_is_the_floored_scaled_box_about_the_destination(scale, paper_parameters):
    destination = dataclasses.replace(paper_parameters.destination, start=(1_500.0, -800.0, 0.0, 0.0))
    params = dataclasses.replace(paper_parameters, destination=destination)
    expected = scale_distribution(params.initial_state, min(scale, 1.0), (1_500.0, -800.0, 0.0),
                                  success_distance=params.simulation.tolerance.distance)
    assert start_distribution(params, scale) == expected
    assert start_distribution(params, scale).min_horizontal_distance >= params.simulation.tolerance.distance
