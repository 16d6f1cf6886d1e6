"""Policy reuse with an agent holding targets (``actions=targets``): the search re-flies B's clearances through the
autopilot, and the completed episodes are the environment's own transitions, held targets and instruction counts
included."""

from __future__ import annotations

import dataclasses

import pytest
import torch
from reuse_scenarios import BUDGET, STEP, replay_in_fresh_env

from agrl.core.aircraft import AIRCRAFT_FIELDS
from agrl.core.observation import RELATIVE_FEATURES
from agrl.core.termination import Outcome
from agrl.envs import GuidanceEnv, MotionKind
from agrl.rl.models import load_agent
from agrl.rl.reuse import BaselinePolicy, candidate_steps, relabelled_trajectories, search_candidates

#: One unit in the last place of a float32 near 1, relative: float32's machine epsilon.
ONE_ULP = torch.finfo(torch.float32).eps


@pytest.fixture(scope="module")
def targets_task(task_params, compose_parameters):
    """The reuse tests' uniform task (50 m/s, 0.3 s steps, a budget of BUDGET) with target-holding actions and no
    continuous-action term (refused with targets)."""
    params = task_params(MotionKind.UNIFORM)
    return dataclasses.replace(params, actions=compose_parameters("actions=targets").actions,
                               reward=dataclasses.replace(params.reward, use_continuous_action=False))


def test_completed_target_episodes_are_the_environments_own(targets_task):
    env = GuidanceEnv(targets_task, num_envs=3, seed=0)
    aircraft = torch.tensor([[-6_000.0, y, 2_500.0, 200.0, 0.0, 0.0, 0.0] for y in (-1_500.0, 0.0, 2_000.0)])
    start_rows = env.reset(env.scenario(aircraft_state=aircraft))
    # The destination's trajectory: straight along +x at 50 m/s from the origin (the uniform task's own).
    trajectory = torch.zeros(3, BUDGET + 1, 4)
    trajectory[..., 0] = STEP * torch.arange(BUDGET + 1, dtype=torch.float32)
    motion = torch.tensor([50.0, 0.0]).expand(3, BUDGET, 2)
    actor, _, _ = load_agent("baseline-targets")  # a real agent holding targets, trained on the fixed destination
    baseline = BaselinePolicy(actor, targets_task.simulation, "relative", holds_targets=True)
    result = search_candidates(start_rows, trajectory, motion, candidates=candidate_steps(BUDGET, 1, BUDGET),
                               keep="earliest", baseline=baseline, simulator=env.simulator, max_decisions=BUDGET,
                               targets=env.target_table)
    assert bool((result.index >= 0).all()), "B reaches every destination it is steered to"
    trajectories, valid = relabelled_trajectories(start_rows, motion, result.arrival, result.record, env)
    real = replay_in_fresh_env(start_rows, trajectories["action"], targets_task)
    changed_any = False
    bank, seen_bank = AIRCRAFT_FIELDS.index("bank"), RELATIVE_FEATURES.index("bank")  # state's, observation's
    for episode, length in enumerate(result.arrival.tolist()):
        got, want = trajectories[episode, :length], real[episode, :length]
        assert torch.equal(got["action"], result.record.action[episode, :length]), "B's recorded actions"
        for prefix in ((), ("next",)):
            name = " ".join(prefix)
            exact = ["held_targets", "step_count", "instruction_count"]
            if prefix:  # what only the transition has
                exact += ["reward", "reward_switch_cost", "outcome"]
            for key in exact:
                torch.testing.assert_close(got[(*prefix, key)], want[(*prefix, key)], rtol=0, atol=0,
                                           msg=f"{name} {key}")
            # Bitwise but for the autopilot's bank, atan2 of its loads: a record (the dynamics fly its sine and
            # cosine, exact divisions), which a processor's vectorised and scalar atan2 can round one unit in the
            # last place apart for rows the batch puts in different lanes (seen on an AVX2 AMD EPYC).
            state, replayed = got[(*prefix, "aircraft_state")], want[(*prefix, "aircraft_state")]
            flown = [field for field in range(state.shape[-1]) if field != bank]
            torch.testing.assert_close(state[..., flown], replayed[..., flown], rtol=0, atol=0,
                                       msg=f"{name} aircraft_state")
            torch.testing.assert_close(state[..., bank], replayed[..., bank], rtol=ONE_ULP, atol=0, msg=f"{name} bank")
            seen, replayed = got[(*prefix, "observation")], want[(*prefix, "observation")]
            others = [feature for feature in range(seen.shape[-1]) if feature != seen_bank]
            torch.testing.assert_close(seen[..., others], replayed[..., others], rtol=0, atol=0,
                                       msg=f"{name} observation")
            torch.testing.assert_close(seen[..., seen_bank], replayed[..., seen_bank], rtol=2 * ONE_ULP, atol=0,
                                       msg=f"{name} observed bank")
        assert int(got["next", "outcome"][-1]) == Outcome.SUCCESS
        changed_any |= bool((got["next", "held_targets"] != got["held_targets"]).any())
        # An instruction is a change of a held target, not a change of action index.
        changes = (got["next", "held_targets"] != got["held_targets"]).any(-1)
        assert int(got["next", "instruction_count"][-1]) == int(changes.sum())
    assert changed_any, "B gave clearances (the held targets changed)"


def test_an_absolute_baseline_reads_its_held_targets_in_the_predicted_destinations_frame(targets_task):
    """B trained on equation 4 at the origin sees the state moved into the predicted destination's frame (section
    5.1); the targets it holds move with it, so what is left to turn, climb and gain is the same as in the world."""
    from agrl.core.observation import held_target_features

    simulation = targets_task.simulation
    generator = torch.Generator().manual_seed(4)
    aircraft = torch.tensor([[-4_000.0, 2_000.0, 3_000.0, 180.0, 0.1, 2.5, 0.2], [1_000.0, -500.0, 800.0, 220.0,
                                                                                  -0.05, -1.0, 0.0]])
    held = torch.stack((torch.rand(2, generator=generator) * 6 - 3, torch.tensor([100.0, 4_500.0]),
                        torch.tensor([100.0, 250.0])), dim=-1)
    predicted = torch.tensor([[3_000.0, -2_000.0, 400.0, 1.2], [-500.0, 700.0, 0.0, -2.8]])
    baseline = BaselinePolicy(torch.nn.Identity(), simulation, "absolute", holds_targets=True)
    observation = baseline.observation(aircraft, predicted, held)
    torch.testing.assert_close(observation[:, -4:], held_target_features(aircraft, held, simulation.airspace,
                                                                         simulation.limits))
