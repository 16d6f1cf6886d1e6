"""The start-box curriculum's promotion rule and start box (agrl.rl.curriculum)."""

from __future__ import annotations

import dataclasses

import pytest

from agrl.core.initial_states import scale_distribution
from agrl.rl.curriculum import SharedScaleGuidanceEnv, promoted_scale, shared_scale, start_distribution


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


def test_an_env_on_a_shared_scale_starts_its_next_episodes_in_the_new_box(paper_parameters):
    """What each collector worker's env does: it reads the scale tensor at every reset (the trainer writes it)."""
    scale = shared_scale(0.15)
    assert scale.is_shared()
    env = SharedScaleGuidanceEnv(paper_parameters, scale, num_envs=64, seed=0)
    assert env.params.initial_state == start_distribution(paper_parameters, 0.15)
    scale.fill_(0.65)
    assert env.params.initial_state == start_distribution(paper_parameters, 0.15)  # nothing happens until a reset
    starts = env.reset()["aircraft_state"]
    box = start_distribution(paper_parameters, 0.65)
    assert env.params.initial_state == box
    for column, (low, high) in enumerate((box.x_range, box.y_range, box.z_range)):
        assert bool(((starts[:, column] >= low - 0.01) & (starts[:, column] <= high + 0.01)).all())
    small = start_distribution(paper_parameters, 0.15)
    outside_small = (starts[:, 0] < small.x_range[0]) | (starts[:, 0] > small.x_range[1])
    assert bool(outside_small.any())
    # The full box at scale 1, the same as a plain env's.
    scale.fill_(1.0)
    env.reset()
    assert env.params == paper_parameters


def test_a_collectors_partial_reset_follows_the_shared_scale_too(paper_parameters):
    """The rows a partial reset restarts are drawn from the box of the scale in force: the draws of an env whose box
    is that scale's, from the same generator state."""
    import torch

    from agrl.envs import GuidanceEnv

    scale = shared_scale(0.15)
    env = SharedScaleGuidanceEnv(paper_parameters, scale, num_envs=64, seed=0)
    state = env.step_mdp(env.rand_step(env.reset()))
    scale.fill_(0.65)
    state["done"][:8] = True  # some rows end, not all
    reference = GuidanceEnv(paper_parameters, num_envs=64, seed=0)
    reference.set_initial_state_distribution(start_distribution(paper_parameters, 0.65))
    reference.set_generator_state(env.generator_state())
    starts = env.maybe_reset(state)["aircraft_state"][:8]
    assert torch.equal(starts, reference.draw_starts(64)[0][:8])
