"""The gymnasium API: ``gymnasium.make("agrl/Guidance-v0", ...)`` (agrl/envs/gym.py).

The gym env steps in Python floats (fast); the one-row TorchRL env it is compared with takes
tens of ms per decision, so the comparisons take few steps.
"""

from __future__ import annotations

import importlib
import math
import subprocess
import sys
import warnings
from importlib.metadata import version
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from hydra import compose, initialize_config_dir

import agrl
from agrl.config import load_config, to_guidance_parameters
from agrl.core.observation import OBSERVATION_SIZE, policy_observation
from agrl.envs.gym import ENV_ID, GuidanceGymEnv, gym_parameters

CONF_DIR = Path(__file__).resolve().parents[2] / "conf"

TASKS = [
    {"task": "uniform", "speed": 50.0},
    {"task": "curved", "radius": 500.0},
    {"task": "fixed"},
    {"task": "irregular"},
]


def _make(**kwargs) -> gymnasium.Env:
    return gymnasium.make(ENV_ID, **kwargs)


# ---------------------------------------------------------------------------- registration
def test_import_registers_the_env_and_is_light():
    assert ENV_ID == agrl.GYM_ENV_ID == "agrl/Guidance-v0"
    assert ENV_ID in gymnasium.registry
    assert agrl.__version__ == version("agrl")
    # Registering again (a second import, a reload) must not fail or warn.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        agrl._register_gym_env()
        importlib.reload(agrl)
    assert ENV_ID in gymnasium.registry
    # `import agrl` does not pull in torch (the env is built lazily by gymnasium.make).
    code = ("import sys, agrl, gymnasium; assert 'torch' not in sys.modules; "
            "print(gymnasium.spec('agrl/Guidance-v0').id)")
    output = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert output.strip() == ENV_ID


# ---------------------------------------------------------------------------- conformance
@pytest.mark.parametrize("kwargs", TASKS, ids=lambda kwargs: kwargs["task"])
def test_spaces_and_env_checker(kwargs):
    env = _make(**kwargs)
    assert env.action_space == gymnasium.spaces.Discrete(7)
    space = env.observation_space
    assert isinstance(space, gymnasium.spaces.Box)
    assert space.dtype == np.float32 and space.shape == (OBSERVATION_SIZE,)
    assert np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))
    unwrapped = env.unwrapped
    assert isinstance(unwrapped, GuidanceGymEnv)
    assert unwrapped.env.batch_size == (1,) and not unwrapped.env.simulator.compiled
    assert unwrapped.params.destination.name.value == kwargs["task"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # gymnasium's checker reports problems as warnings
        check_env(unwrapped)
    env.close()


def test_task_kwargs_reach_the_simulation():
    curved = _make(task="curved", speed=30.0, radius=500.0, turn_direction=-1).unwrapped.params
    assert curved.destination.speed == 30.0 and curved.destination.radius == 500.0
    assert curved.destination.turn_direction == -1.0
    assert _make(task="curved").unwrapped.params.destination.speed == 20.0  # conf/task/curved.yaml
    assert _make(task="uniform").unwrapped.params.destination.speed == 50.0  # conf/task/uniform.yaml
    assert _make(max_decisions=7).unwrapped.params.max_decisions == 7
    plain = _make(reward="none").unwrapped.params.reward
    assert not plain.use_continuous_action and not plain.use_position
    # compile=True is kept in the parameters (the vector env uses it); the single env steps in Python floats.
    compiled = _make(compile=True).unwrapped
    assert compiled.params.compile and not compiled.env.simulator.compiled


@pytest.mark.parametrize("task", ["fixed", "uniform", "curved", "irregular"])
@pytest.mark.parametrize("reward", ["none", "continuous", "position", "both", "switch"])
def test_parameters_equal_the_training_defaults(task, reward):
    """The gym env builds exactly what `python -m agrl.train task=... reward=...` builds (conf/)."""
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = load_config(compose(config_name="config", overrides=[f"task={task}", f"reward={reward}"]))
    expected = to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, compile=False)
    assert gym_parameters(task=task, reward=reward) == expected


# ---------------------------------------------------------------------------- other libraries can train on it
def test_random_policy_loop_through_gymnasium_make():
    """What any gymnasium-based library does: make, reset(seed), step until done, reset again."""
    env = _make(task="uniform", speed=50.0, max_decisions=4)
    check_env(env.unwrapped)
    env.action_space.seed(0)
    observation, info = env.reset(seed=0)
    episodes, steps, episode_return = 0, 0, 0.0
    while episodes < 3:
        action = env.action_space.sample()
        observation, reward, terminated, truncated, info = env.step(action)
        steps += 1
        assert observation in env.observation_space
        assert isinstance(reward, float) and math.isfinite(reward)
        assert isinstance(terminated, bool) and truncated is False
        assert set(info) >= {"outcome", "aircraft_state", "destination_state"}
        assert info["aircraft_state"].shape == (7,) and info["destination_state"].shape == (4,)
        episode_return += reward
        if terminated:
            assert info["outcome"] in ("success", "out_of_airspace", "budget_exhausted")
            assert info["episode_return"] == pytest.approx(episode_return, rel=1e-4, abs=1e-4)
            episodes, episode_return = episodes + 1, 0.0
            observation, info = env.reset()
            assert info["outcome"] == "running" and info["step_count"] == 0
        else:
            assert info["outcome"] == "running"
    assert steps <= 12
    env.close()


def test_vector_env_and_wrappers():
    envs = gymnasium.make_vec(ENV_ID, num_envs=2, vectorization_mode="sync", task="fixed", max_decisions=2)
    envs = gymnasium.wrappers.vector.RecordEpisodeStatistics(envs)
    observations, _ = envs.reset(seed=3)
    assert observations.shape == (2, OBSERVATION_SIZE) and observations.dtype == np.float32
    envs.action_space.seed(3)
    finished = 0
    for _ in range(3):
        observations, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())
        assert observations.shape == (2, OBSERVATION_SIZE) and rewards.shape == (2,)
        assert not truncated.any()
        finished += int(terminated.sum())
    assert finished == 2  # both end at the 2-decision budget (or earlier)
    envs.close()


# ---------------------------------------------------------------------------- same episodes as GuidanceEnv
#: Float tolerance of the comparison: the TorchRL env runs float32, the gym env float64 (agrl/reference.py).
POSITION_TOLERANCE_M = 1.0
ANGLE_TOLERANCE_RAD = 1e-3
SPEED_TOLERANCE_MS = 1e-2
OBSERVATION_TOLERANCE = 1e-3
REWARD_TOLERANCE = 1e-4


def _compare_with_torchrl(gym_env, seed: int, actions, scenario: dict | None = None) -> tuple[int, str]:
    """Step the gym env and a one-row GuidanceEnv (same seed or scenario, same actions); assert they agree."""
    import torch

    from agrl.core.termination import Outcome
    from agrl.envs.guidance import GuidanceEnv

    reference = GuidanceEnv(gym_env.params, num_envs=1, seed=0)
    reference.set_seed(seed)
    observation, info = gym_env.reset(seed=seed, options=scenario)
    state = reference.reset(reference.scenario(**{k: torch.tensor(v) for k, v in scenario.items()})
                            if scenario else None)
    np.testing.assert_allclose(info["aircraft_state"], state["aircraft_state"][0].double().numpy(), rtol=0, atol=0)
    np.testing.assert_allclose(observation, state["observation"][0].numpy(), rtol=0, atol=1e-6)
    tolerance = np.array([POSITION_TOLERANCE_M] * 3 + [SPEED_TOLERANCE_MS] + [ANGLE_TOLERANCE_RAD] * 3)
    for decision, action in enumerate(actions, start=1):
        observation, reward, terminated, truncated, info = gym_env.step(action)
        state["action"] = torch.tensor([action])
        following = reference.step(state)["next"]
        expected = following["aircraft_state"][0].double().numpy()
        difference = info["aircraft_state"] - expected
        difference[5] = (difference[5] + math.pi) % (2 * math.pi) - math.pi  # heading wraps
        assert np.all(np.abs(difference) <= tolerance), (decision, info["aircraft_state"], expected)
        destination = following["destination_state"][0].double().numpy()
        assert np.abs(info["destination_state"][:3] - destination[:3]).max() <= POSITION_TOLERANCE_M
        np.testing.assert_allclose(observation, following["observation"][0].numpy(), rtol=0,
                                   atol=OBSERVATION_TOLERANCE)
        assert reward == pytest.approx(float(following["reward"][0, 0]), abs=REWARD_TOLERANCE)
        assert info["outcome"] == Outcome(int(following["outcome"][0])).name.lower()
        assert info["step_count"] == int(following["step_count"][0])
        assert info["instruction_count"] == int(following["instruction_count"][0])
        assert terminated == bool(following["terminated"][0, 0]) and truncated is False
        if terminated:
            return decision, info["outcome"]
        state = following
    return len(actions), info["outcome"]


@pytest.mark.parametrize("kwargs", TASKS, ids=lambda kwargs: kwargs["task"])
def test_same_episodes_as_the_torchrl_env_from_the_same_seed(kwargs):
    """Same starts, destination motion (the irregular redraws too), rewards and outcomes, to float tolerance."""
    env = _make(max_decisions=25, **kwargs).unwrapped
    rng = np.random.default_rng(0)
    for seed in (0, 1):
        # Mostly a left turn (circling keeps the aircraft in the airspace: long episodes), sometimes anything.
        actions = [int(rng.integers(7)) if rng.random() < 0.3 else 1 for _ in range(25)]
        decisions, _ = _compare_with_torchrl(env, seed, actions)
        assert decisions >= 3


def test_same_episode_as_the_torchrl_env_from_a_scenario_ending_in_success():
    env = _make(task="uniform", speed=20.0).unwrapped
    # 2.5 km behind the destination (20 m/s along +x), 150 m above it, 200 m/s the same way: the gap closes
    # at 180 m/s, to the 1 km tolerance after 1.5 km / 180 m/s = 8.3 s, in the 3rd decision (6-9 s).
    scenario = {"aircraft_state": [-2_500.0, 100.0, 150.0, 200.0, 0.0, 0.0, 0.0],
                "destination_state": [0.0, 0.0, 0.0, 0.0], "destination_speed": 20.0}
    decisions, outcome = _compare_with_torchrl(env, 0, [0] * 5, scenario)
    assert outcome == "success" and decisions == 3


def test_reset_options_start_from_a_scenario():
    env = _make(task="curved").unwrapped
    aircraft = [1_000.0, -2_000.0, 3_000.0, 150.0, 0.1, 0.5, 0.0]
    _, info = env.reset(options={"aircraft_state": aircraft})
    np.testing.assert_allclose(info["aircraft_state"], aircraft, rtol=1e-7)
    np.testing.assert_allclose(info["destination_state"], env.params.destination.start)
    with pytest.raises(ValueError, match="options=.* is not allowed: a dict with aircraft_state"):
        env.reset(options={"aircraft": aircraft})
    for options, message in (
            ({"aircraft_state": (0.0, 0.0, 1_000.0)},
             r"aircraft_state=\(0\.0, 0\.0, 1000\.0\) is not allowed: 7 finite"),
            ({"aircraft_state": "abc"}, r"aircraft_state='abc' is not allowed: 7 finite numbers"),
            ({"aircraft_state": [*aircraft[:6], float("nan")]}, r"aircraft_state=\[.*nan\] is not allowed"),
            ({"aircraft_state": aircraft, "destination_state": [0.0, 0.0]}, r"destination_state=\[0\.0, 0\.0\] is not "
             r"allowed: 4 finite numbers"),
            ({"aircraft_state": aircraft, "destination_speed": "fast"}, r"destination_speed='fast' is not allowed")):
        with pytest.raises(ValueError, match=rf"^{message}"):
            env.reset(options=options)


# ---------------------------------------------------------------------------- the MDP
def test_budget_terminates_with_c3(paper_parameters):
    env = _make(task="fixed", max_decisions=3, reward="none")
    env.reset(seed=5)
    rewards = []
    for _ in range(3):
        _, reward, terminated, truncated, info = env.step(0)  # steady flight
        rewards.append(reward)
    assert terminated and not truncated
    assert info["outcome"] == "budget_exhausted" and info["step_count"] == 3
    assert rewards == [0.0, 0.0, paper_parameters.reward.budget_exhausted]  # equation 6's c3, no shaping
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)  # the episode is over


def test_leaving_the_airspace_is_terminal_and_the_last_observation_is_in_bounds(paper_parameters):
    env = _make(task="fixed", reward="none").unwrapped
    seed = next(s for s in range(100) if env.reset(seed=s)[1]["aircraft_state"][2] < 1_200.0)  # low start
    observation, info = env.reset(seed=seed)
    for _ in range(12):
        observation, reward, terminated, _, info = env.step(6)  # push over into the ground
        assert observation in env.observation_space
        if terminated:
            break
    assert terminated and info["outcome"] == "out_of_airspace"
    assert reward == paper_parameters.reward.out_of_airspace  # equation 6's c2, no shaping
    assert info["aircraft_state"][2] < 0.0


def test_observation_is_the_torchrl_observation_of_the_info_state():
    env = _make(task="curved", radius=500.0).unwrapped
    env.reset(seed=11)
    observation, _, _, _, info = env.step(2)
    import torch

    simulation = env.params.simulation
    expected = policy_observation(
        torch.from_numpy(info["aircraft_state"]), torch.from_numpy(info["destination_state"]),
        torch.tensor(2), simulation.airspace, simulation.limits,
    )
    np.testing.assert_allclose(observation, expected.numpy(), rtol=1e-6, atol=1e-6)


def test_seeding_is_reproducible():
    def trajectory(seed: int, task: str = "irregular") -> list[np.ndarray]:
        env = _make(task=task)
        observation, _ = env.reset(seed=seed)
        observations = [observation]
        for action in (1, 3, 5):
            observations.append(env.step(action)[0])
        return observations

    first, second = trajectory(7), trajectory(7)
    for a, b in zip(first, second, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(trajectory(8)[0], first[0])


def test_returned_data_is_fresh():
    env = _make(task="fixed")
    observation, info = env.reset(seed=0)
    following, _, _, _, next_info = env.step(0)
    assert not np.shares_memory(observation, following)
    assert not np.shares_memory(info["aircraft_state"], next_info["aircraft_state"])


# ---------------------------------------------------------------------------- errors
@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"task": "circle"}, "task='circle' is not allowed: one of curved, fixed, irregular, uniform"),
        ({"task": "uniform", "speed": -5.0}, "speed=-5.0 is not allowed"),
        ({"task": "uniform", "speed": "fast"}, "speed='fast' is not allowed"),
        ({"task": "uniform", "speed": float("nan")}, "speed=nan is not allowed"),
        ({"task": "curved", "radius": 0.0}, "radius=0.0 is not allowed"),
        ({"task": "fixed", "speed": 50.0}, "speed=50.0 is not allowed: task=fixed has no destination speed"),
        ({"task": "uniform", "radius": 500.0}, "radius=500.0 is not allowed: task=uniform"),
        ({"task": "curved", "turn_direction": 2}, "turn_direction=2 is not allowed: +1"),
        ({"max_decisions": 0}, "max_decisions=0 is not allowed: an integer >= 1"),
        ({"max_decisions": 2.5}, "max_decisions=2.5 is not allowed"),
        ({"reward": "shaped"}, "reward='shaped' is not allowed: one of both, continuous, none, position, switch"),
        ({"compile": "yes"}, "compile='yes' is not allowed"),
    ],
)
def test_bad_kwargs_raise_one_line_value_errors(kwargs, fragment):
    with pytest.raises(ValueError) as error:
        _make(**kwargs)
    message = str(error.value)
    assert fragment in message and "\n" not in message


def test_bad_calls():
    env = _make(task="fixed").unwrapped
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action=7 is not allowed: an integer maneuver index in \[0, 6\]"):
        env.step(7)
    _, _, _, _, info = env.step(np.int64(1))  # numpy integers (what spaces sample) are fine
    assert info["step_count"] == 1
    for action in ("a", 2.5, None):  # named as given; a fraction is no maneuver (not truncated to one)
        with pytest.raises(ValueError, match=rf"^action={action!r} is not allowed: an integer maneuver index"):
            env.step(action)
    _, _, _, _, info = env.step(np.array(2.0))  # a whole number, e.g. from an array, is that maneuver
    assert info["step_count"] == 2 and info["instruction_count"] == 2  # 0 -> 1 -> 2: two changes of maneuver


def test_the_single_env_refuses_target_holding_actions_in_one_line():
    with pytest.raises(ValueError) as error:
        gymnasium.make(ENV_ID, actions="targets")
    assert str(error.value).startswith("actions='targets' is not allowed: None or 'maneuvers' for the single env; "
                                       "targets: gymnasium.make_vec(")
    assert gymnasium.make(ENV_ID, actions="maneuvers").unwrapped.action_space.n == 7
