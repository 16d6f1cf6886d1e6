"""The candidate search (``agrl.rl.reuse.search``): the grid of t_n, its waves, and the batched search for the
earliest or latest successful t_n against one independent rollout per candidate."""

from __future__ import annotations

import pytest
import torch
from reuse_scenarios import (
    BUDGET,
    PUSH_OVER,
    STEP,
    ConstantLogits,
    SkittishLogits,
    as_actor,
    brute_force_search,
    kept_candidates,
    starts_of,
)

from agrl.envs import GuidanceEnv
from agrl.rl.reuse import BaselinePolicy, candidate_steps, candidate_waves, search_candidates


# ---------------------------------------------------------------------------- the candidate grid
@pytest.mark.parametrize(
    ("budget", "stride", "cap"),
    [(20, 1, 64), (20, 1, 4), (20, 3, 64), (200, 1, 64), (200, 7, 10), (200, 1, 2), (5, 5, 3), (201, 4, 50)],
)
def test_candidate_steps_grid(budget, stride, cap):
    grid = candidate_steps(budget, stride, cap)
    full = list(range(stride, budget + 1, stride))
    assert grid.dtype == torch.int64
    assert grid.numel() == min(cap, len(full))
    assert bool((grid % stride == 0).all()), "candidates lie on the stride"
    assert bool((grid >= stride).all()) and bool((grid <= budget).all()), "within [stride, budget]"
    assert bool((grid[1:] > grid[:-1]).all()), "strictly increasing, no duplicates"
    assert int(grid[0]) == full[0] and int(grid[-1]) == full[-1], "the grid spans the whole budget"
    if cap >= len(full):
        assert grid.tolist() == full
    else:  # evenly spread: no gap is more than one stride wider than another
        gaps = grid.diff()
        assert int(gaps.max() - gaps.min()) <= stride


@pytest.mark.parametrize(("budget", "stride", "cap"), [(20, 0, 4), (20, 21, 4), (20, 1, 0)])
def test_candidate_steps_rejects_a_stride_or_cap_out_of_range(budget, stride, cap):
    with pytest.raises(ValueError, match="candidate_stride" if cap else "max_candidates"):
        candidate_steps(budget, stride, cap)


def test_transform_uses_the_grid_of_its_env(uniform):
    transform = uniform.transform(candidate_stride=3, max_candidates=4)
    assert transform.candidates.tolist() == candidate_steps(BUDGET, 3, 4).tolist()


@pytest.mark.parametrize("keep", ["earliest", "latest"])
@pytest.mark.parametrize("candidates", [1, 2, 3, 4, 5, 8, 9, 16, 17, 40])
def test_waves_run_every_candidate_once_in_the_order_they_would_be_kept(candidates, keep):
    waves = candidate_waves(candidates, keep)
    order = list(range(candidates)) if keep == "earliest" else list(range(candidates))[::-1]
    assert torch.cat(waves).tolist() == order, "each candidate once, earliest (or latest) first"
    sizes = [wave.numel() for wave in waves]
    # Two waves of 2, then each wave twice the one before (the last one holds what is left).
    expected, size = [], 2
    while sum(expected) < candidates:
        expected.append(min(size, candidates - sum(expected)))
        if sum(expected) >= 4:
            size *= 2
    assert sizes == expected


# ---------------------------------------------------------------------------- which candidate is kept
def hand_built_starts(uniform) -> tuple[torch.Tensor, object, torch.Tensor, torch.Tensor]:
    """Three episodes 6, 5 and 4 km behind the uniform destination, with its exact trajectory and motion."""
    aircraft = torch.tensor([[x, 0.0, 100.0, 200.0, 0.0, 0.0, 0.0] for x in (-6_000.0, -5_000.0, -4_000.0)])
    env = GuidanceEnv(uniform.env.params, num_envs=aircraft.shape[0], seed=0)
    start_rows = env.reset(env.scenario(aircraft_state=aircraft))
    trajectory = torch.zeros(aircraft.shape[0], BUDGET + 1, 4)
    trajectory[..., 0] = STEP * torch.arange(BUDGET + 1, dtype=torch.float32)
    motion = torch.tensor([50.0, 0.0]).expand(aircraft.shape[0], BUDGET, 2)
    return aircraft, start_rows, trajectory, motion


@pytest.mark.parametrize(("keep", "stride", "cap"), [("earliest", 1, BUDGET), ("latest", 1, BUDGET),
                                                      ("earliest", 2, 6)])
def test_search_keeps_the_earliest_or_latest_successful_candidate(uniform, keep, stride, cap):
    """The batched search (all episodes and candidates at once, pruned) against one rollout per candidate; the
    kept candidate's recorded rollout is that rollout's."""
    grid = candidate_steps(BUDGET, stride, cap)
    baseline = BaselinePolicy(as_actor(SkittishLogits()), uniform.env.params.simulation)
    aircraft, start_rows, trajectory, motion = hand_built_starts(uniform)
    arrival, winner, record = search_candidates(start_rows, trajectory, motion, candidates=grid, keep=keep,
                                                baseline=baseline, simulator=uniform.env.simulator,
                                                max_decisions=BUDGET)

    brute, actions, states = brute_force_search(grid, aircraft, uniform.env.params)
    for episode in range(aircraft.shape[0]):
        succeeded = (brute[episode] > 0).nonzero().squeeze(-1)
        assert 2 <= succeeded.numel() < grid.numel(), "some candidates succeed, not all"
        expected = succeeded.min() if keep == "earliest" else succeeded.max()
        assert int(winner[episode]) == int(expected), episode
        length = int(brute[episode, expected])
        assert int(arrival[episode]) == length, episode
        # The record holds the kept rollout step by step (the completion reads it instead of simulating again).
        assert record.action[episode, :length].tolist() == actions[episode, expected, :length].tolist()
        torch.testing.assert_close(record.aircraft_state[episode, :length], states[episode, expected, :length],
                                   rtol=0, atol=0)
        # The real destination after each step (success freezes it inside the last decision).
        x = record.destination_state[episode, :length, 0]
        torch.testing.assert_close(x[:-1], STEP * torch.arange(1, length, dtype=torch.float32))
        assert STEP * (length - 1) < float(x[-1]) <= STEP * length + 1e-3


def test_search_without_a_success_keeps_no_candidate(uniform):
    """An episode none of whose candidates arrives has index -1 and arrival 0."""
    baseline = BaselinePolicy(as_actor(ConstantLogits(PUSH_OVER)), uniform.env.params.simulation)
    _, start_rows, trajectory, motion = hand_built_starts(uniform)
    result = search_candidates(start_rows, trajectory, motion, candidates=candidate_steps(BUDGET, 1, BUDGET),
                               keep="earliest", baseline=baseline, simulator=uniform.env.simulator,
                               max_decisions=BUDGET)
    assert result.index.tolist() == [-1] * 3 and result.arrival.tolist() == [0] * 3
    assert not bool(result.record.action.any())


def test_earliest_and_latest_differ_when_every_candidate_succeeds(fixed):
    flat = fixed.flat()
    starts = starts_of(flat)
    results = {}
    for keep in ("earliest", "latest"):
        transform = fixed.transform(keep=keep, max_candidates=4)  # t_n in {1, 7, 14, 20}, spacing 6
        prediction, _, results[keep] = kept_candidates(transform, flat, starts)
        # A fixed destination: the prediction is its position, whatever t_n.
        position = flat["destination_state"][starts][:, None]
        torch.testing.assert_close(prediction, position.expand_as(prediction))
    assert results["earliest"].index.tolist() == [0] * starts.numel()
    assert results["latest"].index.tolist() == [3] * starts.numel()
    # Same arrival (the steered point is the same): the kept re-played episodes are the same too.
    assert torch.equal(results["earliest"].arrival, results["latest"].arrival)
    assert bool((results["earliest"].arrival == 4).all())


def test_search_rejects_an_unknown_keep(uniform):
    _, start_rows, trajectory, motion = hand_built_starts(uniform)
    with pytest.raises(ValueError, match="keep"):
        search_candidates(start_rows, trajectory, motion, candidates=candidate_steps(BUDGET, 1, BUDGET), keep="best",
                          baseline=BaselinePolicy(as_actor(SkittishLogits()), uniform.env.params.simulation),
                          simulator=uniform.env.simulator, max_decisions=BUDGET)
