"""The gymnasium vector env (agrl/envs/gym_vector.py): make_vec, next-step autoreset, same episodes as one env."""

from __future__ import annotations

import math

import gymnasium
import numpy as np
import pytest

from agrl.core.observation import OBSERVATION_SIZE
from agrl.envs.gym import ENV_ID
from agrl.envs.gym_vector import GuidanceVectorEnv

#: The vector env runs float32 (GuidanceEnv), the single env float64: the tolerances of tests/envs/test_gym.py.
POSITION_TOLERANCE_M = 1.0
ANGLE_TOLERANCE_RAD = 1e-3
SPEED_TOLERANCE_MS = 1e-2
OBSERVATION_TOLERANCE = 1e-3
REWARD_TOLERANCE = 1e-4
STATE_TOLERANCE = np.array([POSITION_TOLERANCE_M] * 3 + [SPEED_TOLERANCE_MS] + [ANGLE_TOLERANCE_RAD] * 3)


def _make_vec(num_envs: int, **kwargs) -> gymnasium.vector.VectorEnv:
    return gymnasium.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def _assert_same_row(vector_out, row: int, single_out) -> None:
    """One row of a vector step (obs, reward, terminated, truncated, info) against one single-env step."""
    observations, rewards, terminated, truncated, infos = vector_out
    observation, reward, single_terminated, single_truncated, info = single_out
    np.testing.assert_allclose(observations[row], observation, rtol=0, atol=OBSERVATION_TOLERANCE)
    assert rewards[row] == pytest.approx(reward, abs=REWARD_TOLERANCE)
    assert bool(terminated[row]) == single_terminated and bool(truncated[row]) == single_truncated
    difference = infos["aircraft_state"][row] - info["aircraft_state"]
    difference[5] = (difference[5] + math.pi) % (2 * math.pi) - math.pi  # heading wraps
    assert np.all(np.abs(difference) <= STATE_TOLERANCE), (infos["aircraft_state"][row], info["aircraft_state"])
    assert np.abs(infos["destination_state"][row, :3] - info["destination_state"][:3]).max() <= POSITION_TOLERANCE_M
    for key in ("outcome", "step_count", "instruction_count"):
        assert infos[key][row] == info[key], key


def test_make_vec_builds_the_batched_env():
    envs = _make_vec(5, task="curved", radius=500.0)
    assert isinstance(envs, GuidanceVectorEnv) and envs.num_envs == 5
    assert envs.env.batch_size == (5,) and envs.params.destination.radius == 500.0
    assert envs.metadata["autoreset_mode"] is gymnasium.vector.AutoresetMode.NEXT_STEP
    assert envs.single_action_space == gymnasium.spaces.Discrete(7)
    assert envs.action_space == gymnasium.spaces.MultiDiscrete([7] * 5)
    observations, infos = envs.reset(seed=0)
    assert observations.shape == (5, OBSERVATION_SIZE) and observations.dtype == np.float32
    assert observations in envs.observation_space
    assert infos["aircraft_state"].shape == (5, 7) and infos["_aircraft_state"].all()
    envs.action_space.seed(0)
    observations, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())
    assert observations in envs.observation_space
    assert rewards.shape == (5,) and rewards.dtype == np.float64
    assert terminated.dtype == bool and not truncated.any()
    envs.close()


@pytest.mark.parametrize("task", ["irregular", "fixed"])
def test_one_row_flies_the_single_env_episodes_from_the_same_seed_resets_included(task):
    """num_envs=1: the same generator draws in the same order, so the same starts and destination motion."""
    envs = _make_vec(1, task=task, max_decisions=4)
    single = gymnasium.make(ENV_ID, task=task, max_decisions=4)
    observations, infos = envs.reset(seed=3)
    observation, info = single.reset(seed=3)
    np.testing.assert_allclose(observations[0], observation, rtol=0, atol=1e-6)
    rng = np.random.default_rng(1)
    episodes, ended = 0, False
    for _ in range(14):
        action = int(rng.integers(7))
        vector_out = envs.step(np.array([action]))
        if ended:  # next-step autoreset: this step is the reset, its action is ignored
            observation, info = single.reset()
            single_out = (observation, 0.0, False, False, info)
            episodes += 1
        else:
            single_out = single.step(action)
        _assert_same_row(vector_out, 0, single_out)
        ended = bool(vector_out[2][0])
    assert episodes >= 2


def test_rows_from_scenarios_fly_the_single_env_episodes_and_autoreset_on_the_next_step():
    """Three rows ending at different decisions: each row equals the single env from its scenario."""
    scenarios = {
        "aircraft_state": np.array([[-2_500.0, 100.0, 150.0, 200.0, 0.0, 0.0, 0.0],  # success in decision 3
                                    [9_000.0, 0.0, 1_000.0, 200.0, 0.0, 0.0, 0.0],  # out of the airspace: 2
                                    [-6_000.0, 3_000.0, 2_500.0, 200.0, 0.0, 0.0, 0.0]]),  # budget: 5
        "destination_state": np.zeros((3, 4)),
        "destination_speed": np.array([20.0, 20.0, 20.0]),
        "destination_turn_rate": np.zeros(3),
    }
    envs = _make_vec(3, task="uniform", speed=20.0, max_decisions=5)
    envs.reset(seed=0, options=scenarios)
    singles = [gymnasium.make(ENV_ID, task="uniform", speed=20.0, max_decisions=5) for _ in range(3)]
    for row, single in enumerate(singles):
        single.reset(options={key: value[row] for key, value in scenarios.items()})
    actions = [[0, 0, 1], [0, 0, 2], [0, 0, 1], [5, 5, 0], [1, 1, 1]]
    finished_at, restarted = {}, set()
    for decision, action in enumerate(actions, start=1):
        sent = np.array(action)
        vector_out = envs.step(sent)
        assert sent.tolist() == action  # the restart must not write into the caller's action array
        for row, single in enumerate(singles):
            if row in finished_at and finished_at[row] == decision - 1:  # the autoreset step of this row
                assert vector_out[1][row] == 0.0 and not vector_out[2][row]
                assert vector_out[4]["step_count"][row] == 0 and vector_out[4]["outcome"][row] == "running"
                restarted.add(row)
            elif row not in finished_at:
                single_out = single.step(action[row])
                _assert_same_row(vector_out, row, single_out)
                if single_out[2]:
                    finished_at[row] = decision
    assert finished_at == {0: 3, 1: 2, 2: 5}
    assert restarted == {0, 1}
    assert [singles[row].unwrapped._outcome for row in range(3)] == [1, 2, 3]  # success, out, budget


def test_seeding_is_reproducible_and_refuses_per_row_seeds():
    def first_steps(seed):
        envs = _make_vec(4, task="irregular")
        outputs = [envs.reset(seed=seed)[0]]
        for action in ([1, 2, 3, 4], [0, 5, 6, 1]):
            outputs.append(envs.step(np.array(action))[0])
        return outputs

    for a, b in zip(first_steps(7), first_steps(7), strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(first_steps(8)[0], first_steps(7)[0])
    with pytest.raises(ValueError, match=r"seed=\[1, 2\] is not allowed: None or one integer"):
        _make_vec(2).reset(seed=[1, 2])


def test_bad_calls_and_arguments():
    envs = _make_vec(2, task="fixed")
    with pytest.raises(RuntimeError, match="reset"):
        envs.step(np.array([0, 0]))
    envs.reset(seed=0)
    for bad in (np.array([0, 7]), np.array([0]), np.array([0.5, 1.0]), [[0, 1]]):
        with pytest.raises(ValueError, match="actions=.* is not allowed: 2 integer action indices in"):
            envs.step(bad)
    envs.step([3, 4])  # plain lists of ints are fine
    many = _make_vec(16, task="fixed")
    many.reset(seed=0)
    actions = np.zeros(16, dtype=np.int64)
    actions[11] = 9
    with pytest.raises(ValueError, match=r"^actions='array of shape \(16,\), dtype int64 with actions\[11\]=9' is not"):
        many.step(actions)  # a long batch is named by its first bad row
    with pytest.raises(ValueError, match="num_envs=0 is not allowed: an integer >= 1"):
        GuidanceVectorEnv(num_envs=0)
    with pytest.raises(ValueError, match="task='circle' is not allowed"):
        _make_vec(2, task="circle")


def test_gymnasium_vector_wrappers_accept_it():
    envs = gymnasium.wrappers.vector.RecordEpisodeStatistics(_make_vec(3, task="fixed", max_decisions=2))
    envs.reset(seed=1)
    finished = 0
    for _ in range(3):
        _, _, terminated, _, infos = envs.step(np.array([0, 1, 2]))
        finished += int(terminated.sum())
        if terminated.any():
            assert np.all(infos["episode"]["l"][terminated] == 2)
    assert finished == 3


def test_same_step_autoreset_returns_the_reset_observation_and_the_final_one_in_info():
    scenarios = {"aircraft_state": np.array([[9_000.0, 0.0, 1_000.0, 200.0, 0.0, 0.0, 0.0],  # out in decision 2
                                             [-6_000.0, 3_000.0, 2_500.0, 200.0, 0.0, 0.0, 0.0]])}
    envs = _make_vec(2, task="fixed", autoreset_mode="SameStep")
    assert envs.metadata["autoreset_mode"] is gymnasium.vector.AutoresetMode.SAME_STEP
    envs.reset(seed=0, options=scenarios)
    single = gymnasium.make(ENV_ID, task="fixed")
    single.reset(options={"aircraft_state": scenarios["aircraft_state"][0]})
    envs.step(np.array([0, 0]))
    single.step(0)
    observations, rewards, terminated, _, infos = envs.step(np.array([0, 0]))
    final_observation, final_reward, _, _, final_info = single.step(0)
    assert terminated.tolist() == [True, False] and infos["_final_obs"].tolist() == [True, False]
    assert infos["final_obs"][1] is None
    np.testing.assert_allclose(infos["final_obs"][0], final_observation, rtol=0, atol=OBSERVATION_TOLERANCE)
    assert infos["final_info"]["outcome"][0] == final_info["outcome"] == "out_of_airspace"
    assert rewards[0] == pytest.approx(final_reward, abs=REWARD_TOLERANCE)
    # the returned row is already a new episode (a random start of the task), the other row goes on
    assert infos["step_count"].tolist() == [0, 2] and infos["outcome"][0] == "running"
    assert not np.allclose(observations[0], final_observation, atol=1e-2)
    with pytest.raises(ValueError, match="autoreset_mode='Disabled' is not allowed: one of NextStep, SameStep"):
        _make_vec(2, autoreset_mode="Disabled")


def test_a_vector_env_of_target_holding_actions_flies_the_training_envs_rows():
    """``actions="targets"``: 26 actions, the held targets in ``info``, observations within the space, and each
    step the TorchRL env's own (GuidanceEnv with the same task, seed and actions)."""
    import torch

    from agrl.config import guidance_parameters
    from agrl.envs import GuidanceEnv

    env = _make_vec(4, actions="targets", task="uniform", speed=50.0, compile=False)
    assert env.single_action_space.n == 26
    observations, info = env.reset(seed=5)
    assert env.single_observation_space.shape == (20,) and env.observation_space.contains(observations)
    np.testing.assert_array_equal(info["held_targets"], info["aircraft_state"][:, [5, 2, 3]])
    reference = GuidanceEnv(guidance_parameters("actions=targets", "task=uniform", "speed=50"), num_envs=4, seed=5)
    state = reference.reset()
    rng = np.random.default_rng(0)
    for _ in range(6):
        actions = rng.integers(0, 26, 4)
        observations, rewards, terminated, _, info = env.step(actions)
        state["action"] = torch.as_tensor(actions)
        state = reference.step(state)["next"]
        np.testing.assert_array_equal(observations, state["observation"].numpy())
        np.testing.assert_array_equal(info["held_targets"], state["held_targets"].numpy())
        np.testing.assert_array_equal(info["instruction_count"], state["instruction_count"].numpy())
        assert env.observation_space.contains(observations)
        if terminated.any():
            break
    with pytest.raises(ValueError, match=r"actions=\[26, 0, 0, 0\] is not allowed: 4 integer action indices in "
                                         r"\[0, 25\]"):
        env.step([26, 0, 0, 0])
    with pytest.raises(ValueError, match="actions='orders' is not allowed: one of maneuvers, targets"):
        _make_vec(2, actions="orders")
