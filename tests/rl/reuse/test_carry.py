"""Episodes across collector batches (``agrl.rl.reuse.carry``): each env's running episode, kept since its start
and put in front of the env's rows of the next batch, checked against the collector's own episode ids."""

from __future__ import annotations

import pytest
import torch
from reuse_scenarios import BUDGET, NUM_ENVS, SPANNING_STEPS, ended_in

from agrl.core.termination import Outcome
from agrl.rl.reuse import CARRY_KEYS, TRAJECTORY_KEY, EpisodeCarrier, searchable_episodes


def episode_of_known_rows(known, batches: list, number: int) -> torch.Tensor:
    """The collector's episode id of every known row when ``batches[number]`` is joined: each env's known rows are
    its last ones in batches 0..number (its rows of this batch, behind its kept rows)."""
    ids = torch.stack([batch.get(TRAJECTORY_KEY).reshape(NUM_ENVS, SPANNING_STEPS) for batch in batches[: number + 1]])
    per_env = ids.permute(1, 0, 2).reshape(NUM_ENVS, -1)  # each env's rows of batches 0..number, in order
    return torch.cat([per_env[env, per_env.shape[1] - int(known.per_env[env]):] for env in range(NUM_ENVS)])


def test_join_puts_each_envs_running_episode_since_its_start_in_front_of_its_rows(spanning):
    carrier = EpisodeCarrier(NUM_ENVS, "cpu")
    assert carrier.rows is None and carrier.lengths is None and carrier.state_dict() is None
    selected_ids: dict[int, bool] = {}
    kept_some = False
    for number, batch in enumerate(spanning.batches):
        known = carrier.join(batch)
        rows, in_batch = known.rows, known.in_batch
        # This batch's rows, in order, behind each env's kept rows (the entries the search and prediction read).
        assert int(in_batch.sum()) == batch.numel() and set(rows.keys(True, True)) == set(CARRY_KEYS)
        assert (rows[in_batch] == batch.select(*CARRY_KEYS)).all()
        assert known.per_env.shape == (NUM_ENVS,) and int(known.per_env.sum()) == rows.numel()
        # Each env's rows begin at its episode's start: the first batch starts every env afresh.
        first = torch.cumsum(known.per_env, 0) - known.per_env
        assert bool((rows["step_count"][first] == 0).all())
        kept_some |= bool((~in_batch).any())
        # The known rows of each env are its rows of the batches so far, and its episodes are the collector's.
        ids = episode_of_known_rows(known, spanning.batches, number)
        runs = torch.cat([torch.ones(1, dtype=torch.bool), ids[1:] != ids[:-1]])
        assert torch.equal(known.episode_ids, torch.cumsum(runs.long(), 0) - 1), "one id per collector episode"
        assert bool((known.episode_ids.diff() >= 0).all())
        # Kept rows are those of episodes that started in an earlier batch and are still running.
        for env in range(NUM_ENVS):
            env_rows = slice(int(first[env]), int(first[env] + known.per_env[env]))
            kept = ~in_batch[env_rows]
            if bool(kept.any()):
                assert len(set(ids[env_rows][kept].tolist())) == 1
                assert int(ids[env_rows][kept][0]) == int(batch.get(TRAJECTORY_KEY)[env * SPANNING_STEPS])
        starts = known.starts()
        assert torch.equal(starts, (rows["step_count"] == 0).nonzero().squeeze(-1))
        # Carried: a kept row whose episode was selected when it started (here: every other episode).
        assert known.carried.tolist() == [bool(not here and selected_ids[int(t)])
                                          for here, t in zip(in_batch.tolist(), ids.tolist(), strict=True)]
        selected = torch.tensor([int(ids[s]) % 2 == 0 for s in starts.tolist()], dtype=torch.bool)
        for start, choice in zip(starts.tolist(), selected.tolist(), strict=True):
            selected_ids.setdefault(int(ids[start]), choice)
        carrier.keep(known, starts, selected)
        # After keep: each env's unfinished episode, from its start, under the decision budget.
        assert carrier.lengths.shape == (NUM_ENVS,) and int(carrier.lengths.max()) < BUDGET
        assert carrier.rows.batch_size.numel() == int(carrier.lengths.sum())
        last = torch.cumsum(known.per_env, 0) - 1
        done = rows["next", "done"].reshape(-1)[last]
        assert bool((carrier.lengths[done] == 0).all()), "an ended episode is not kept"
        offset = 0
        for env in range(NUM_ENVS):
            length = int(carrier.lengths[env])
            if length:
                kept_rows = carrier.rows[offset:offset + length]
                assert int(kept_rows["step_count"][0]) == 0 and (kept_rows == rows[int(last[env]) - length + 1:
                                                                                    int(last[env]) + 1]).all()
                assert bool(carrier.selected[env]) == selected_ids[int(ids[last[env]])]
            else:
                assert not bool(carrier.selected[env])
            offset += length
    assert kept_some, "episodes were carried from one batch to the next"


def test_kept_rows_resume_from_the_state_dict(spanning, tmp_path):
    first, second, third = spanning.batches[:3]
    carrier = EpisodeCarrier(NUM_ENVS, "cpu")
    for batch in (first, second):
        known = carrier.join(batch)
        carrier.keep(known, known.starts(), torch.ones(known.starts().numel(), dtype=torch.bool))
    state = carrier.state_dict()
    assert set(state) == {"rows", "lengths", "selected"} and int(state["lengths"].sum()) > 0
    path = tmp_path / "carry.pt"
    torch.save(state, path)
    resumed = EpisodeCarrier(NUM_ENVS, "cpu")
    resumed.load_state_dict(torch.load(path, weights_only=True))
    expected, got = carrier.join(third), resumed.join(third)
    assert (expected.rows == got.rows).all()
    for field in ("per_env", "in_batch", "episode_ids", "carried"):
        assert torch.equal(getattr(expected, field), getattr(got, field)), field
    # Without kept rows, only this batch's rows are known.
    resumed.load_state_dict(None)
    assert resumed.rows is None
    assert bool(resumed.join(third).in_batch.all())


def test_rows_the_batch_does_not_continue_are_not_used(spanning):
    """Kept rows go in front of a batch only if it continues them (next step count, same aircraft state): after
    batch 0, batch 2 does not; nor, then, does batch 1, whose episodes' starts are all unknown."""
    first, second, third = spanning.batches[:3]
    carrier = EpisodeCarrier(NUM_ENVS, "cpu")
    known = carrier.join(first)
    carrier.keep(known, known.starts(), torch.ones(known.starts().numel(), dtype=torch.bool))
    assert int(carrier.lengths.sum()) > 0
    known = carrier.join(third)
    assert bool(known.in_batch.all()) and known.per_env.tolist() == [SPANNING_STEPS] * NUM_ENVS
    carrier.keep(known, known.starts(), torch.ones(known.starts().numel(), dtype=torch.bool))
    assert carrier.lengths.tolist() == [0] * NUM_ENVS, "every env's last episode started before batch 2"
    known = carrier.join(second)  # nothing kept: a batch on its own
    assert bool(known.in_batch.all()) and not bool(known.carried.any())


def test_rejects_a_batch_not_split_evenly_over_the_envs(spanning):
    with pytest.raises(ValueError, match="envs x steps"):
        EpisodeCarrier(NUM_ENVS, "cpu").join(spanning.batches[0][:-1])


def test_searchable_episodes_skip_the_unfinished_and_the_agents_own_successes(spanning):
    carrier = EpisodeCarrier(NUM_ENVS, "cpu")
    checked = {"unfinished": 0, "ended": 0}
    for batch in spanning.batches:
        known = carrier.join(batch)
        starts = known.starts()
        carrier.keep(known, starts, torch.ones(starts.numel(), dtype=torch.bool))
        # The collector's episode of each start: the id of its episode's rows in this batch.
        traj = torch.full((known.rows.numel(),), -1)
        traj[known.in_batch] = batch.get(TRAJECTORY_KEY)
        episode = [int(traj[(known.episode_ids == known.episode_ids[start]) & known.in_batch][0])
                   for start in starts.tolist()]
        ended = ended_in(batch)
        everything = searchable_episodes(known, batch, starts, relabel_unfinished=True, relabel_own_successes=True)
        assert bool(everything.all())
        deferred = searchable_episodes(known, batch, starts, relabel_unfinished=False, relabel_own_successes=True)
        assert deferred.tolist() == [t in ended for t in episode]
        checked["unfinished"] += int((~deferred).sum())
        checked["ended"] += int(deferred.sum())
        # The circling agent never arrives: none of its episodes is its own success ...
        own = searchable_episodes(known, batch, starts, relabel_unfinished=True, relabel_own_successes=False)
        assert bool(own.all())
        # ... unless one that ends here is marked as one.
        if ended:
            marked = batch.clone()
            ids = marked.get(TRAJECTORY_KEY)
            success = min(ended)
            marked["next", "outcome"][(ids == success).nonzero()[-1, 0]] = int(Outcome.SUCCESS)
            own = searchable_episodes(known, marked, starts, relabel_unfinished=True, relabel_own_successes=False)
            assert own.tolist() == [t != success for t in episode]
    assert checked["unfinished"] > 0 and checked["ended"] > 0
