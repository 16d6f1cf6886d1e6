"""The replay-buffer transform (``agrl.rl.reuse.transform``): what it stores, the selection factor e, episodes
across batches, its checkpoint state and the shortcuts, checked against brute-force searches."""

from __future__ import annotations

import pytest
import torch
from reuse_scenarios import (
    ACCELERATE,
    BUDGET,
    NUM_ENVS,
    OWN_KEYS,
    PUSH_OVER,
    ConstantLogits,
    as_actor,
    brute_force_search,
    ended_in,
    own_rows,
    starts_of,
)
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement

from agrl.core.termination import Outcome
from agrl.rl.reuse import PPO_KEYS, TRAJECTORY_KEY


# ---------------------------------------------------------------------------- what is kept
def test_own_rows_of_untouched_episodes_are_kept_verbatim(uniform):
    flat = uniform.flat()
    transform = uniform.transform(initial_selection_factor=0.5, seed=3)
    out = transform.relabel(flat)
    stats = transform.last_statistics()
    starts = starts_of(flat)
    assert 0 < stats["train/reuse_episodes_relabelled"] < starts.numel(), "a mixed batch"
    own = out[~out["relabelled"]]
    assert bool(out["relabelled"][own.numel():].all()), "own rows first, then the re-played ones"
    # Match each own row to its collector row (observations are continuous: exact matches are unique).
    same = (own["observation"][:, None] == flat["observation"][None]).all(-1) & (
        own["action"][:, None] == flat["action"][None])
    assert bool((same.sum(-1) == 1).all())
    source = same.long().argmax(-1)
    assert bool((source.diff() > 0).all()), "in the collector's order"
    for key in OWN_KEYS:
        assert torch.equal(own[key], flat[key][source]), key
    # Whole episodes are dropped, exactly the relabelled ones, each starting in this batch.
    traj_ids = flat.get(TRAJECTORY_KEY)
    dropped = set(traj_ids.tolist()) - set(traj_ids[source].tolist())
    assert len(dropped) == stats["train/reuse_episodes_relabelled"]
    assert dropped <= set(traj_ids[starts].tolist())
    assert set(traj_ids[source].tolist()).isdisjoint(dropped)
    kept_ids = torch.tensor(sorted(set(traj_ids.tolist()) - dropped))
    assert source.numel() == int(torch.isin(traj_ids, kept_ids).sum())


def test_a_baseline_that_never_succeeds_leaves_the_batch_unchanged(uniform):
    flat = uniform.flat()
    transform = uniform.transform(as_actor(ConstantLogits(PUSH_OVER)))  # dives into the ground
    out = transform.relabel(flat)
    stats = transform.last_statistics()
    assert stats["train/reuse_episodes_selected"] == starts_of(flat).numel()
    assert stats["train/reuse_episodes_relabelled"] == 0 and stats["train/reuse_fraction"] == 0.0
    assert (out == own_rows(flat)).all()


# ---------------------------------------------------------------------------- the selection factor e
def test_with_e_zero_nothing_is_relabelled(uniform):
    flat = uniform.flat()
    uniform.received.clear()
    transform = uniform.transform(initial_selection_factor=0.0, selection_decay=0.1)
    out = transform.relabel(flat)
    expected = own_rows(flat)
    assert out.batch_size == flat.batch_size
    assert set(out.keys()) == set(PPO_KEYS)
    assert (out == expected).all()
    assert uniform.received == [], "no episode was re-played"
    assert transform.last_statistics()["train/e"] == 0.0
    assert transform.last_statistics()["train/reuse_fraction"] == 0.0
    assert transform.last_statistics()["train/reuse_episodes_selected"] == 0


def test_e_drops_by_k_per_selected_episode_and_stops_at_zero(uniform):
    flat = uniform.flat()
    episodes = starts_of(flat).numel()
    never = as_actor(ConstantLogits(PUSH_OVER))  # cheap: its candidates end after a decision or two
    transform = uniform.transform(never, initial_selection_factor=1.0, selection_decay=0.05)
    transform.relabel(flat)
    stats = transform.last_statistics()
    assert stats["train/reuse_episodes_selected"] == episodes, "e = 1 selects every episode"
    assert stats["train/e"] == pytest.approx(1.0 - 0.05 * episodes)
    assert transform.selection_factor == pytest.approx(1.0 - 0.05 * episodes)

    # Fractional e: the decay counts the episodes actually selected (u < e), whether or not they succeed.
    for _ in range(3):
        before = transform.selection_factor
        transform.relabel(flat)
        stats = transform.last_statistics()
        assert 0 <= stats["train/reuse_episodes_selected"] <= episodes
        selected = stats["train/reuse_episodes_selected"]
        assert stats["train/e"] == pytest.approx(max(0.0, before - 0.05 * selected))

    floor = uniform.transform(never, initial_selection_factor=1.0, selection_decay=0.3)
    assert floor.selection_factor == 1.0, "e starts at initial_selection_factor"
    floor.relabel(flat)  # 1 - 0.3 * episodes < 0
    assert floor.selection_factor == 0.0 and floor.last_statistics()["train/e"] == 0.0
    floor.relabel(flat)
    assert floor.last_statistics()["train/reuse_episodes_selected"] == 0
    assert floor.selection_factor == 0.0


def test_selection_is_seeded_and_restored_from_state_dict(uniform):
    flat = uniform.flat()
    never = as_actor(ConstantLogits(PUSH_OVER))
    a = uniform.transform(never, initial_selection_factor=0.6, selection_decay=0.01, seed=7)
    a.relabel(flat)
    saved = a.state_dict()
    a.relabel(flat)
    b = uniform.transform(never, initial_selection_factor=1.0, selection_decay=0.01, seed=0)
    b.load_state_dict(saved)
    b.relabel(flat)
    assert a.last_statistics()["train/reuse_episodes_selected"] == b.last_statistics()[
        "train/reuse_episodes_selected"]
    assert a.selection_factor == b.selection_factor


@pytest.mark.parametrize("max_rows", [None, 40])
def test_reuse_fraction_is_the_share_of_relabelled_rows_in_the_output(relabelled, max_rows):
    if max_rows is None:
        transform, out = relabelled.transform, relabelled.out
    else:  # the buffer's cap cuts re-played rows: the statistic describes what is stored
        transform = relabelled.collected.transform(max_rows=max_rows)
        out = transform.relabel(relabelled.flat)
    stats = transform.last_statistics()
    assert stats["train/reuse_episodes_relabelled"] > 0
    assert max_rows is None or out.numel() == max_rows
    assert stats["train/reuse_fraction"] == pytest.approx(float(out["relabelled"].float().mean()))
    assert 0.0 < stats["train/reuse_fraction"] <= 1.0


def test_episodes_past_max_rows_are_not_replayed_and_the_output_is_the_cut_one(relabelled):
    """Not re-playing episodes that would fall past ``max_rows`` saves work and changes nothing stored."""
    uncut = relabelled.out
    relabelled.collected.received.clear()
    transform = relabelled.collected.transform(max_rows=40)
    cut = transform.relabel(relabelled.flat)
    assert cut.numel() == 40 < uncut.numel()
    assert (cut == uncut[:40]).all()
    replayed = relabelled.collected.received[0].batch_size[0]
    assert replayed < relabelled.trajectories.batch_size[0], "fewer episodes were re-played"
    assert transform.last_statistics()["train/reuse_episodes_relabelled"] == replayed


def test_keep_changes_the_relabelled_actions_on_a_moving_destination(relabelled):
    latest_out = relabelled.collected.transform(keep="latest").relabel(relabelled.flat)
    outs = {"earliest": relabelled.out, "latest": latest_out}
    earliest, latest = (outs[k][outs[k]["relabelled"]] for k in ("earliest", "latest"))
    # Steered at a farther predicted point, the latest candidate accelerates for longer.
    assert int((latest["action"] == ACCELERATE).sum()) > int((earliest["action"] == ACCELERATE).sum())


def test_rejects_an_unknown_keep(uniform):
    with pytest.raises(ValueError, match="keep"):
        uniform.transform(keep="best")


# ---------------------------------------------------------------------------- episodes across batches
def test_episodes_spanning_two_and_three_batches_are_relabelled_like_a_brute_force_search(spanning):
    transform = spanning.transform()
    first_batch = spanning.batch_of()
    spans = {}
    for batch in spanning.batches:
        for trajectory in set(batch.get(TRAJECTORY_KEY).tolist()):
            spans[trajectory] = spans.get(trajectory, 0) + 1
    assert {2, 3} <= set(spans.values()), "the batches hold episodes spanning two and three batches"
    checked_spans = set()
    for number, batch in enumerate(spanning.batches):
        spanning.received.clear()
        out = transform.relabel(batch)
        traj_ids = batch.get(TRAJECTORY_KEY)
        # Every episode with rows in this batch has a known start (the first batch starts every env afresh).
        episodes = sorted(set(traj_ids.tolist()), key=lambda t: int((traj_ids == t).nonzero()[0, 0]))
        starts = torch.stack([spanning.start_of(t)["aircraft_state"] for t in episodes])
        arrival, actions, _ = brute_force_search(transform.candidates, starts, spanning.env.params)
        success = arrival > 0
        assert bool(success.any(-1).any()) and not bool(success.all()), "some candidates succeed, not all"
        # Brute force: the earliest successful t_n per episode, its arrival step and B's actions.
        expected_ids = [t for t, ok in zip(episodes, success.any(-1).tolist(), strict=True) if ok]
        winner = torch.where(success, torch.arange(success.shape[1]), success.shape[1]).min(-1).values
        assert transform.last_statistics()["train/reuse_episodes_relabelled"] == len(expected_ids)
        assert len(spanning.received) == 1
        trajectories, valid = spanning.received[0]
        assert trajectories.shape[0] == len(expected_ids)
        for row, trajectory in enumerate(expected_ids):
            episode = episodes.index(trajectory)
            length = int(arrival[episode, winner[episode]])
            got = trajectories[row]
            assert int(valid[row].sum()) == length, (number, trajectory)
            start = spanning.start_of(trajectory)
            assert torch.equal(got["aircraft_state"][0], start["aircraft_state"]), "re-played from the real S_0"
            assert torch.equal(got["destination_state"][0], start["destination_state"])
            assert got["action"][:length].tolist() == actions[episode, winner[episode], :length].tolist()
            assert int(got["next", "outcome"][length - 1]) == Outcome.SUCCESS
            checked_spans.add(number - first_batch[trajectory])
        # Stored: this batch's rows of the episodes left alone, then the re-played episodes.
        own_expected = int((~torch.isin(traj_ids, torch.tensor(expected_ids))).sum())
        assert int((~out["relabelled"]).sum()) == own_expected
        assert int(out["relabelled"].sum()) == int(valid.sum())
        # The rows kept for the next batch: each env's unfinished episode since its start, under the budget.
        carrier = transform.carrier
        assert carrier.lengths.shape == (NUM_ENVS,)
        assert int(carrier.lengths.max()) < BUDGET
        assert carrier.rows.numel() == int(carrier.lengths.sum())
    assert {0, 1, 2} <= checked_spans, "relabelled: episodes starting in this batch, one and two batches before"


def test_kept_rows_are_in_the_state_dict_and_resume_is_exact(spanning, tmp_path):
    first, second, third = spanning.batches[:3]
    running = spanning.transform(initial_selection_factor=0.7, seed=4)
    running.relabel(first)
    running.relabel(second)
    path = tmp_path / "reuse.pt"
    state = running.state_dict()
    # The checkpoint's entries (a checkpoint written before must resume): e, the draws, the kept rows.
    assert set(state) == {"selection_factor", "generator", "carry"}
    assert set(state["carry"]) == {"rows", "lengths", "selected"}
    torch.save(state, path)
    resumed = spanning.transform(seed=99)
    resumed.load_state_dict(torch.load(path, weights_only=True))
    expected, got = running.relabel(third), resumed.relabel(third)
    assert (expected == got).all()
    assert {k: v for k, v in running.last_statistics().items() if not k.startswith("time/")} == {
        k: v for k, v in resumed.last_statistics().items() if not k.startswith("time/")}
    assert running.last_statistics()["train/reuse_episodes_carried"] > 0
    # Without the kept rows the episodes that started earlier are left alone: the state is what differs.
    fresh = spanning.transform()
    fresh.load_state_dict({k: v for k, v in torch.load(path, weights_only=True).items() if k != "carry"})
    fewer = fresh.relabel(third)  # the same draws for the episodes starting in this batch
    assert int(fewer["relabelled"].sum()) < int(expected["relabelled"].sum())
    assert fresh.last_statistics()["train/reuse_episodes_carried"] == 0



def test_without_relabel_unfinished_each_episode_is_searched_once_in_the_batch_where_it_ends(spanning):
    algorithm_1, deferred = spanning.transform(), spanning.transform(relabel_unfinished=False)
    searched = []
    for batch in spanning.batches:
        traj_ids = batch.get(TRAJECTORY_KEY)
        episodes = sorted(set(traj_ids.tolist()), key=lambda t: int((traj_ids == t).nonzero()[0, 0]))
        ended = ended_in(batch)
        starts = torch.stack([spanning.start_of(t)["aircraft_state"] for t in episodes])
        arrival, _, _ = brute_force_search(algorithm_1.candidates, starts, spanning.env.params)
        winners = [t for t, ok in zip(episodes, (arrival > 0).any(-1).tolist(), strict=True) if ok]
        spanning.received.clear()
        algorithm_1.relabel(batch)
        full, full_valid = spanning.received[0]  # Algorithm 1's re-played episodes: the winners, in batch order
        spanning.received.clear()
        out = deferred.relabel(batch)
        stats = deferred.last_statistics()
        assert stats["train/reuse_episodes_selected"] == len(episodes), "the selection itself is unchanged"
        assert stats["train/reuse_episodes_searched"] == len(ended)
        searched += sorted(ended)
        # Relabelled: Algorithm 1's episodes of this batch that end in it, re-played the same way.
        expected = [t for t in winners if t in ended]
        assert stats["train/reuse_episodes_relabelled"] == len(expected)
        assert int((~out["relabelled"]).sum()) == int((~torch.isin(traj_ids, torch.tensor(expected))).sum())
        if not expected:
            assert spanning.received == []
            continue
        got, got_valid = spanning.received[0]
        keep = torch.tensor([t in ended for t in winners])
        length = got_valid.shape[1]
        assert torch.equal(got_valid, full_valid[keep][:, :length])
        for key in ("action", "aircraft_state", "destination_state", ("next", "reward"), ("next", "done")):
            assert torch.equal(got[key], full[key][keep][:, :length]), key
    assert {len(ended_in(batch)) for batch in spanning.batches} != {0}
    assert len(searched) == len(set(searched)), "no episode is searched twice"


def test_without_relabel_own_successes_the_agents_successful_episodes_keep_its_rows(relabelled):
    flat, out = relabelled.input.clone(), relabelled.out  # Algorithm 1's output on this batch
    traj_ids, done = flat.get(TRAJECTORY_KEY), flat["next", "done"].reshape(-1)
    # The episodes Algorithm 1 replaced: those without own rows in its output (observations match uniquely).
    own = out[~out["relabelled"]]
    source = (own["observation"][:, None] == flat["observation"][None]).all(-1).long().argmax(-1)
    replaced = set(traj_ids.tolist()) - set(traj_ids[source].tolist())
    # Two of them that end in this batch are marked as Z's own successes.
    marked = sorted(t for t in replaced if bool(done[(traj_ids == t).nonzero()[-1, 0]]))[:2]
    assert len(marked) == 2
    last_rows = torch.stack([(traj_ids == t).nonzero()[-1, 0] for t in marked])
    flat["next", "outcome"][last_rows] = int(Outcome.SUCCESS)
    outcome = flat["next", "outcome"].reshape(-1)
    successes = {t for t in set(traj_ids.tolist()) if done[(traj_ids == t).nonzero()[-1, 0]]
                 and outcome[(traj_ids == t).nonzero()[-1, 0]] == Outcome.SUCCESS}  # the marked, and Z's own
    transform = relabelled.collected.transform(relabel_own_successes=False)
    shortcut = transform.relabel(flat)
    stats, full = transform.last_statistics(), relabelled.transform.last_statistics()
    assert stats["train/reuse_episodes_selected"] == full["train/reuse_episodes_selected"]
    started = set(traj_ids[starts_of(flat)].tolist())  # every episode with a start here is selected (e = 1)
    assert stats["train/reuse_episodes_searched"] == full["train/reuse_episodes_searched"] - len(successes & started)
    assert stats["train/reuse_episodes_relabelled"] == full["train/reuse_episodes_relabelled"] - len(
        successes & replaced)
    # Z's rows of the marked episodes are stored verbatim, with the other own rows, in the collector's order.
    kept = ~torch.isin(traj_ids, torch.tensor(sorted(replaced - successes)))
    assert (shortcut[~shortcut["relabelled"]] == own_rows(flat[kept])).all()


# ---------------------------------------------------------------------------- as a replay-buffer transform
def test_extend_does_not_write_into_the_collector_batch(uniform):
    data = uniform.data.clone()
    flat = data.reshape(-1)  # as in the trainer: views of the collector's tensors
    before = data.clone()
    transform = uniform.transform()
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(3 * flat.numel()),
                                    sampler=SamplerWithoutReplacement(), batch_size=16, transform=transform)
    buffer.extend(flat)
    assert (data == before).all(), "rb.extend changed the collector's batch in place"
    assert set(data.keys(True, True)) == set(before.keys(True, True))
    stored = buffer[:]
    assert len(buffer) == stored.numel()
    assert bool(stored["relabelled"].any()), "the buffer holds relabelled rows"
    assert transform.last_statistics()["train/reuse_fraction"] == pytest.approx(
        float(stored["relabelled"].float().mean()))
    # Sampling returns stored rows unchanged (forward is the identity).
    sample = buffer.sample()
    assert set(sample.keys()) >= set(PPO_KEYS)


def test_rejects_unflattened_rows(uniform):
    with pytest.raises(ValueError, match="flat rows"):
        uniform.transform().relabel(uniform.data)


