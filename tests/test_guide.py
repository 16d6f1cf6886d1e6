"""agrl.guide.Guide: the trained actor's deterministic maneuver from the raw state, for one query or a batch."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import ExplorationType, set_exploration_type

from agrl.config import saved_guidance_parameters
from agrl.core.observation import policy_observation
from agrl.guide import Guide, GuideError
from agrl.rl.models import load_agent

STATES = 10_000


def random_raw_states(count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Aircraft anywhere in the airspace at any speed, attitude and heading; destinations anywhere; any last action."""
    rng = np.random.default_rng(seed)
    aircraft = np.stack([rng.uniform(-10_000, 10_000, count), rng.uniform(-10_000, 10_000, count),
                         rng.uniform(0, 5_000, count), rng.uniform(100, 250, count), rng.uniform(-0.5, 0.5, count),
                         rng.uniform(-np.pi, np.pi, count), rng.uniform(-1.1, 1.1, count)], axis=1)
    destination = np.stack([rng.uniform(-10_000, 10_000, count), rng.uniform(-10_000, 10_000, count),
                            rng.uniform(0, 5_000, count), rng.uniform(-np.pi, np.pi, count)], axis=1)
    return aircraft.astype(np.float32), destination.astype(np.float32), rng.integers(0, 7, count)


def actor_maneuvers(reference: str, aircraft, destination, last_action) -> np.ndarray:
    """What the TorchRL actor (make_actor, deterministic mode) answers, the observation from agrl.core."""
    actor, saved, _ = load_agent(reference)
    params = saved_guidance_parameters(saved).simulation
    observation = policy_observation(torch.from_numpy(aircraft), torch.from_numpy(destination),
                                     torch.from_numpy(last_action), params.airspace, params.limits)
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        return actor(TensorDict({"observation": observation}, batch_size=[len(aircraft)]))["action"].numpy()


@pytest.fixture(scope="module")
def states():
    aircraft, destination, last_action = random_raw_states(STATES)
    return aircraft, destination, last_action, actor_maneuvers("baseline", aircraft, destination, last_action)


def test_batch_and_single_queries_answer_what_the_torchrl_actor_answers(states):
    aircraft, destination, last_action, expected = states
    assert len(set(expected.tolist())) >= 3  # the states exercise several maneuvers
    guide = Guide.load("baseline")
    assert guide.kind == "checkpoint" and guide.source.endswith("fixed_baseline.pt")
    batch = guide.instruct_batch(aircraft, destination, last_action)
    assert batch.shape == (STATES,) and batch.dtype == np.int64
    np.testing.assert_array_equal(batch, expected)
    single = [guide.instruct(aircraft[i].tolist(), tuple(destination[i]), int(last_action[i])) for i in range(STATES)]
    assert all(type(answer) is int for answer in single[:10])
    np.testing.assert_array_equal(np.array(single), expected)


def test_a_run_directory_and_a_checkpoint_file_load_the_same_agent(tmp_path):
    from agrl.baselines import BASELINE_FILE

    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "checkpoints" / "latest.pt").write_bytes(BASELINE_FILE.read_bytes())
    aircraft, destination, last_action = random_raw_states(200, seed=1)
    expected = Guide.load("baseline").instruct_batch(aircraft, destination, last_action)
    for reference in (run, run / "checkpoints" / "latest.pt"):
        np.testing.assert_array_equal(Guide.load(reference).instruct_batch(aircraft, destination, last_action),
                                      expected)


def test_bad_questions_raise_one_line_errors():
    guide = Guide.load("baseline")
    aircraft, destination = [0.0, 0.0, 1_000.0, 200.0, 0.0, 0.0, 0.0], [5_000.0, 0.0, 0.0, 0.0]
    assert 0 <= guide.instruct(aircraft, destination, 0) < 7
    cases = [
        ((aircraft[:6], destination, 0), "are not allowed: 7 and 4 finite numbers"),
        ((aircraft, destination + [1.0], 0), "are not allowed: 7 and 4 finite numbers"),
        ((aircraft[:6] + [float("nan")], destination, 0), "finite numbers"),
        ((aircraft, destination, 7), r"last_action=7 is not allowed: an integer in \[0, 6\]"),
        ((aircraft, destination, 1.0), "last_action=1.0 is not allowed"),
        ((aircraft, "north", 0), "destination_state='north'"),
    ]
    for arguments, message in cases:
        with pytest.raises(GuideError, match=message) as error:
            guide.instruct(*arguments)
        assert "\n" not in str(error.value)
    batch = np.zeros((3, 7), np.float32), np.zeros((3, 4), np.float32)
    with pytest.raises(GuideError, match=r"last_action of shape \(2,\)"):
        guide.instruct_batch(*batch, np.zeros(2, np.int64))
    with pytest.raises(GuideError, match=r"aircraft_state of shape \(3, 6\) is not allowed: \(N, 7\)"):
        guide.instruct_batch(np.zeros((3, 6)), batch[1], np.zeros(3, np.int64))
    with pytest.raises(GuideError, match=r"destination_state of shape \(2, 4\) is not allowed: one row per"):
        guide.instruct_batch(batch[0], np.zeros((2, 4)), np.zeros(3, np.int64))


@pytest.mark.parametrize("activation", ["tanh", "relu", "elu"])
def test_batched_layers_compute_the_actor_network(activation):
    """The batched guide's layers (addmm into reused buffers, in-place activations) are the actor's network."""
    from agrl.core.observation import OBSERVATION_SIZE
    from agrl.guide import BatchedLayers
    from agrl.rl.models import make_actor

    torch.manual_seed(0)
    actor = make_actor([64, 32], activation)
    network = next(module for module in actor.modules() if isinstance(module, torch.nn.Sequential))
    with torch.no_grad():
        for parameter in network.parameters():  # large enough weights that every activation saturates somewhere
            parameter.normal_(0.0, 1.0)
    layers = BatchedLayers(network, activation)
    for rows in (5, 300, 5):  # a new batch size, then back: the buffers follow
        observation = 3 * torch.randn(rows, OBSERVATION_SIZE)
        with torch.inference_mode():
            torch.testing.assert_close(layers(observation), network(observation), atol=1e-5, rtol=1e-5)


# ---------------------------------------------------------------------------- an agent holding targets
def random_held_targets(aircraft: np.ndarray, seed: int = 0) -> np.ndarray:
    """Held targets near and far from each aircraft's heading, altitude and speed."""
    rng = np.random.default_rng(seed)
    count = len(aircraft)
    return np.stack([rng.uniform(-np.pi, np.pi, count), rng.choice([100.0, 500.0, 2500.0, 4500.0], count),
                     rng.choice([100.0, 200.0, 250.0], count)], axis=1).astype(np.float32)


def actor_target_actions(reference, aircraft, destination, held) -> np.ndarray:
    """What the TorchRL actor of an agent holding targets answers, its observation from agrl.core."""
    from agrl.core.observation import target_observation_function

    actor, saved, _ = load_agent(str(reference))
    simulation = saved_guidance_parameters(saved).simulation
    observation = target_observation_function("relative")(
        torch.from_numpy(aircraft), torch.from_numpy(destination), torch.from_numpy(held), simulation.airspace,
        simulation.limits)
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        return actor(TensorDict({"observation": observation}, batch_size=[len(aircraft)]))["action"].numpy()


def test_a_guide_of_an_agent_holding_targets_answers_what_its_actor_answers(tiny_targets_run):
    guide = Guide.load(tiny_targets_run.run_dir)
    assert guide.holds_targets and guide.num_actions == len(guide.target_table) == 26
    aircraft, destination, _ = random_raw_states(2_000, seed=7)
    held = random_held_targets(aircraft)
    expected = actor_target_actions(tiny_targets_run.run_dir, aircraft, destination, held)
    assert len(set(expected.tolist())) > 1  # the check can tell actions apart
    np.testing.assert_array_equal(guide.instruct_batch(aircraft, destination, held), expected)
    single = [guide.instruct(aircraft[i], destination[i], held[i].tolist()) for i in range(200)]
    np.testing.assert_array_equal(np.array(single), expected[:200])


@pytest.mark.parametrize(("call", "message"), [
    (lambda guide: guide.instruct([0, 0, 1000, 200, 0, 0, 0], [0, 0, 0, 0], 3),
     "held_targets=3 is not allowed: 3 finite numbers (heading rad, altitude m, speed m/s)"),
    (lambda guide: guide.instruct_batch(np.zeros((2, 7)), np.zeros((2, 4)), np.zeros(2, np.int64)),
     "held_targets of shape (2,) is not allowed: (N, 3) finite numbers"),
    (lambda guide: guide.instruct_batch(np.zeros((2, 7)), np.zeros((2, 4)), np.zeros((3, 3))),
     "held_targets of shape (3, 3) is not allowed: one row per aircraft (2)"),
])
def test_an_agent_holding_targets_refuses_a_maneuver_agents_question(tiny_targets_run, call, message):
    with pytest.raises(GuideError) as raised:
        call(Guide.load(tiny_targets_run.run_dir))
    assert str(raised.value) == message
