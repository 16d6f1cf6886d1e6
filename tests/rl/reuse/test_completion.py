"""Completing the re-played episodes (``agrl.rl.reuse.completion``): the environment's own transitions with the
real destination, PPO's targets on them, and the rows the buffer stores."""

from __future__ import annotations

import math

import torch
from reuse_scenarios import (
    BUDGET,
    NUM_ENVS,
    STEP,
    PursuitLogits,
    as_actor,
    baseline_argmax,
    kept_candidates,
    replay_in_fresh_env,
)

from agrl.core.observation import policy_observation
from agrl.core.reward import step_reward
from agrl.core.termination import Outcome
from agrl.envs import GuidanceEnv
from agrl.rl.reuse import (
    PPO_KEYS,
    BaselinePolicy,
    candidate_steps,
    fitting_episodes,
    relabelled_ppo_targets,
    relabelled_rows,
    relabelled_trajectories,
    search_candidates,
    stored_rows,
)


# ---------------------------------------------------------------------------- through the transform
def test_relabelled_tuples_carry_the_real_destination_trajectory(relabelled):
    flat, out, trajectories = relabelled.flat, relabelled.out, relabelled.trajectories
    starts = relabelled.starts
    assert (flat == relabelled.input).all(), "relabel does not write into its input"
    assert trajectories.shape[0] == starts.numel(), "every episode starting in the batch was relabelled"
    assert starts.numel() > NUM_ENVS, "some episodes start mid-batch (after the agent's own failures)"
    lengths = relabelled.lengths
    steps = int(lengths.max())
    actions = trajectories["action"][:, :steps]

    real = replay_in_fresh_env(flat[starts], actions, relabelled.collected.env.params)
    for episode in range(starts.numel()):
        length = int(lengths[episode])
        got, want = trajectories[episode, :length], real[episode, :length]
        for key in ("aircraft_state", "destination_state", "observation", "last_action", "step_count"):
            torch.testing.assert_close(got[key], want[key], rtol=0, atol=0, msg=key)
        for key in ("aircraft_state", "destination_state", "observation", "reward", "done", "terminated",
                    "outcome", "episode_return"):
            torch.testing.assert_close(got["next", key], want["next", key], rtol=0, atol=0, msg=f"next {key}")
        # (Bitwise: the re-simulation is the environment's own transition.)
        # The destination fields are the destination's own trajectory: straight along +x at 50 m/s, not the
        # predicted (fixed) point the baseline was steered by. Success freezes it inside the last decision.
        x = torch.cat((got["destination_state"][:, 0], got["next", "destination_state"][-1:, 0]))
        torch.testing.assert_close(x[:-1], STEP * torch.arange(length, dtype=torch.float32))
        assert 0 < float(x[-1] - x[-2]) <= STEP + 1e-3
        torch.testing.assert_close(got["destination_state"][:, 1:], torch.zeros(length, 3))

    # What the buffer receives for those rows is exactly these transitions, episode after episode.
    relabelled = out[out["relabelled"]]
    valid = torch.arange(trajectories.shape[1])[None, :] < lengths[:, None]
    torch.testing.assert_close(relabelled["observation"], trajectories["observation"][valid])
    assert torch.equal(relabelled["action"], trajectories["action"][valid])


def test_actions_are_the_baselines_on_the_predicted_destination(relabelled):
    flat, trajectories, lengths = relabelled.flat, relabelled.trajectories, relabelled.lengths
    uniform, transform, starts = relabelled.collected, relabelled.transform, relabelled.starts
    # The kept termination step t_n of each episode (the transform's own search; deterministic).
    prediction, _, (_, winner, _) = kept_candidates(transform, flat, starts)
    assert bool((winner >= 0).all())
    target_step = transform.candidates[winner]
    # The prediction at t_n is where the destination really is at t_n (equation 19: it ignores the aircraft).
    expected_target = torch.zeros(starts.numel(), 4)
    expected_target[:, 0] = STEP * target_step.float()
    torch.testing.assert_close(prediction[torch.arange(starts.numel()), target_step], expected_target)

    simulation = uniform.env.params.simulation
    differs = 0
    for episode in range(starts.numel()):
        rows = trajectories[episode, : int(lengths[episode])]
        # Equation 20: the destination fields replaced by the destination state at t_n.
        target = expected_target[episode].expand(rows.shape[0], 4)
        observed = policy_observation(rows["aircraft_state"], target, rows["last_action"],
                                      simulation.airspace, simulation.limits)
        assert torch.equal(rows["action"], baseline_argmax(observed))
        differs += int((baseline_argmax(rows["observation"]) != rows["action"]).sum())
    assert differs > 0, "the scenario must tell the predicted destination from the real one"



def test_success_ends_each_relabelled_episode_and_gae_does_not_look_past_it(relabelled):
    out, trajectories, lengths = relabelled.out, relabelled.trajectories, relabelled.lengths
    index = torch.arange(trajectories.shape[0])
    last = trajectories[index, lengths - 1]
    assert bool((last["next", "outcome"] == Outcome.SUCCESS).all()), "the stored episode ends at a success"
    before = torch.arange(trajectories.shape[1])[None, :] < (lengths - 1)[:, None]
    assert not bool(trajectories["next", "done"].squeeze(-1)[before].any()), "nothing terminal before it"
    rows = out[out["relabelled"]]
    assert rows.numel() == int(lengths.sum()), "no row after the success is stored"
    # Episode by episode the last stored row is the success step: its target is the reward, no bootstrap.
    ends = lengths.cumsum(0) - 1
    torch.testing.assert_close(rows["value_target"][ends], last["next", "reward"])
    torch.testing.assert_close(rows["advantage"][ends], last["next", "reward"] - rows["state_value"][ends])
    # The behaviour log-probability is the current actor's for B's action (PPO's ratio starts at 1).
    expected = relabelled.collected.actor.get_dist(rows).log_prob(rows["action"])
    torch.testing.assert_close(rows["action_log_prob"], expected)


def test_ppo_targets_on_valid_rows_equal_gae_on_the_whole_table(relabelled):
    """The critic runs on the valid rows only; the advantages equal TorchRL's GAE run on the padded table."""
    collected = relabelled.collected
    trajectories, valid = relabelled.trajectories.clone(), relabelled.valid
    assert bool(valid.any()) and not bool(valid.all()), "the table holds padding"
    masked = relabelled_ppo_targets(trajectories.clone(), valid, critic=collected.critic,
                                    advantage=collected.replay_gae)
    with torch.no_grad():
        full = collected.gae(trajectories.clone())
    for key in ("state_value", ("next", "state_value"), "advantage", "value_target"):
        torch.testing.assert_close(masked[key][valid], full[key][valid])
    # Without an actor the behaviour log-probability is B's own.
    torch.testing.assert_close(masked["action_log_prob"], trajectories["baseline_log_prob"])


def test_rewards_are_the_environments_for_the_real_destination(relabelled):
    """Equation 5 on the real destination fields (the independent env replay checks the same numbers)."""
    trajectories, lengths = relabelled.trajectories, relabelled.lengths
    reward_params = relabelled.collected.env.params.reward

    for episode in range(trajectories.shape[0]):
        rows = trajectories[episode, : int(lengths[episode])]
        expected, _ = step_reward(rows["next", "outcome"], rows["aircraft_state"], rows["destination_state"],
                                  rows["last_action"], rows["action_before_last"], rows["action"],
                                  rows["next", "aircraft_state"], rows["next", "destination_state"], reward_params,
                                  rows["action"] != rows["last_action"])
        torch.testing.assert_close(rows["next", "reward"].squeeze(-1), expected)
        assert float(rows["next", "reward"][-1]) > 10.0, "the success pays c1"


def test_baseline_log_prob_is_the_baselines_on_the_predicted_destination(relabelled):
    """``method.behaviour_log_prob=baseline`` uses B's log-probability of its own action on the observation
    with the predicted destination (equation 20), here recomputed from B's logits directly."""
    trajectories, lengths, starts = relabelled.trajectories, relabelled.lengths, relabelled.starts
    flat, transform = relabelled.flat, relabelled.transform
    prediction, _, (_, winner, _) = kept_candidates(transform, flat, starts)
    target = prediction[torch.arange(starts.numel()), transform.candidates[winner]]
    simulation = relabelled.collected.env.params.simulation
    for episode in range(starts.numel()):
        rows = trajectories[episode, : int(lengths[episode])]
        observed = policy_observation(rows["aircraft_state"], target[episode].expand(rows.shape[0], 4),
                                      rows["last_action"], simulation.airspace, simulation.limits)
        log_probs = torch.log_softmax(PursuitLogits()(observed), -1)
        expected = log_probs.gather(-1, rows["action"][:, None]).squeeze(-1)
        torch.testing.assert_close(rows["baseline_log_prob"], expected)
        # A confident baseline: its argmax log-probability, 10 - log(e^10 + 6), not a uniform -log 7.
        torch.testing.assert_close(expected, torch.full_like(expected, 10.0 - math.log(math.exp(10.0) + 6.0)))


# ---------------------------------------------------------------------------- the completion's functions
def test_completed_transitions_are_the_environments_own(uniform):
    """Straight from a search's record: the completed trajectories are a fresh environment's steps with the kept
    actions, bitwise, up to the success; padding after it is terminal."""
    params = uniform.env.params
    aircraft = torch.tensor([[x, 0.0, 100.0, 200.0, 0.0, 0.0, 0.0] for x in (-6_000.0, -5_000.0, -4_000.0)])
    env = GuidanceEnv(params, num_envs=aircraft.shape[0], seed=0)
    start_rows = env.reset(env.scenario(aircraft_state=aircraft))
    trajectory = torch.zeros(aircraft.shape[0], BUDGET + 1, 4)
    trajectory[..., 0] = STEP * torch.arange(BUDGET + 1, dtype=torch.float32)
    motion = torch.tensor([50.0, 0.0]).expand(aircraft.shape[0], BUDGET, 2)
    result = search_candidates(start_rows, trajectory, motion, candidates=candidate_steps(BUDGET, 1, BUDGET),
                               keep="earliest", baseline=BaselinePolicy(as_actor(PursuitLogits()), params.simulation),
                               simulator=uniform.env.simulator, max_decisions=BUDGET)
    assert bool((result.index >= 0).all()) and result.arrival.unique().numel() > 1, "successes of several lengths"

    trajectories, valid = relabelled_trajectories(start_rows, motion, result.arrival, result.record, uniform.env)
    assert trajectories.shape == (aircraft.shape[0], int(result.arrival.max()))
    assert valid.sum(1).tolist() == result.arrival.tolist() and bool(valid[:, 0].all())
    real = replay_in_fresh_env(start_rows, trajectories["action"], params)
    for episode, length in enumerate(result.arrival.tolist()):
        got, want = trajectories[episode, :length], real[episode, :length]
        assert torch.equal(got["action"], result.record.action[episode, :length]), "B's recorded actions"
        for key in ("aircraft_state", "destination_state", "observation", "last_action", "action_before_last",
                    "step_count", "episode_return", "instruction_count"):
            torch.testing.assert_close(got[key], want[key], rtol=0, atol=0, msg=key)
        for key in ("aircraft_state", "destination_state", "observation", "reward", "done", "terminated",
                    "outcome", "episode_return", "instruction_count"):
            torch.testing.assert_close(got["next", key], want["next", key], rtol=0, atol=0, msg=f"next {key}")
        assert int(got["next", "outcome"][-1]) == Outcome.SUCCESS
        torch.testing.assert_close(got["baseline_log_prob"], result.record.baseline_log_prob[episode, :length])
    assert bool(trajectories["next", "done"][~valid].all()) and bool(trajectories["next", "terminated"][~valid].all())

    # The buffer's rows of these episodes: the valid rows, episode after episode, with PPO's keys ...
    rows = relabelled_rows(trajectories.clone(), valid, lambda table, mask: relabelled_ppo_targets(
        table, mask, critic=uniform.critic, advantage=uniform.replay_gae))
    assert rows.numel() == int(valid.sum()) and set(rows.keys()) == set(PPO_KEYS)
    assert bool(rows["relabelled"].all())
    assert torch.equal(rows["observation"], trajectories["observation"][valid])
    assert torch.equal(rows["action"], trajectories["action"][valid])
    assert torch.equal(rows["action_log_prob"], trajectories["baseline_log_prob"][valid]), "no actor: B's"
    # ... stored after the own rows that are kept, in the collector's order, the whole cut at max_rows.
    batch = uniform.flat()
    keep_own = torch.arange(batch.numel()) % 3 != 0
    own = int(keep_own.sum())
    stored = stored_rows(batch, keep_own, rows, None)
    assert stored.numel() == own + rows.numel()
    assert not bool(stored["relabelled"][:own].any())
    for key in PPO_KEYS[:-1]:
        assert torch.equal(stored[key][:own], batch[key][keep_own]), key
        assert torch.equal(stored[key][own:], rows[key]), key
    assert (stored_rows(batch, keep_own, rows, own + 2) == stored[: own + 2]).all()
    assert (stored_rows(batch, keep_own, None, None) == stored[:own]).all()


def test_fitting_episodes_are_those_whose_rows_start_inside_max_rows():
    """Found episodes are completed only if their first re-played row lands before ``max_rows`` (the own rows of
    the untouched episodes come first), checked against a row-by-row count."""
    traj_ids = torch.tensor([0, 0, 0, 1, 1, 2, 2, 2, 2, 3, 4, 4, 4, 4, 5, 5])
    searched = torch.tensor([0, 2, 3, 4, 5])  # the searched episodes' ids (1 was not searched)
    found = torch.tensor([True, False, True, True, True])
    arrival = torch.tensor([5, 0, 3, 7, 2])
    for max_rows in (None, 0, 3, 6, 7, 9, 10, 12, 16, 100):
        index, dropped = fitting_episodes(found, arrival, traj_ids, searched, traj_ids.numel(), max_rows)
        replaced = {int(searched[i]) for i in range(searched.numel()) if found[i]}
        row = sum(int(t) not in replaced for t in traj_ids)  # own rows kept
        expected = []
        for i in range(searched.numel()):
            if found[i]:
                if max_rows is None or row < max_rows:
                    expected.append(i)
                row += int(arrival[i])
        assert index.tolist() == expected, max_rows
        assert dropped.tolist() == [bool(found[i]) and i not in expected for i in range(searched.numel())]
