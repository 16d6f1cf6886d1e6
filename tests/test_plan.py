"""agrl.plan: a trained agent's instructions from a start, checked against a replay in the single gymnasium env."""

from __future__ import annotations

import dataclasses
import json
import re
import subprocess
import sys

import numpy as np
import pytest

from agrl.core.aircraft import MANEUVER_NAMES
from agrl.envs.gym import GuidanceGymEnv
from agrl.guide import Guide
from agrl.plan import PlanError, maneuver_text, plan, task_parameters
from agrl.plan.__main__ import main

START = ["-6000", "3000", "2500", "200", "0", "0", "0"]


@pytest.fixture(scope="module")
def guide():
    return Guide.load("baseline")


def replay(env: GuidanceGymEnv, guide: Guide, info: dict) -> dict:
    """Fly the guide's maneuvers through the gym env; the env counts the instructions (the evaluation's count)."""
    last, maneuvers, instruction_times, aircraft, destination = 0, [], [], [info["aircraft_state"]], []
    destination.append(info["destination_state"])
    terminated = False
    while not terminated:
        action = guide.instruct(info["aircraft_state"], info["destination_state"], last)
        count = info["instruction_count"]
        _, _, terminated, truncated, info = env.step(action)
        assert not truncated
        if info["instruction_count"] > count:
            instruction_times.append(env.params.simulation.decision_period * (info["step_count"] - 1))
        maneuvers.append(action)
        aircraft.append(info["aircraft_state"])
        destination.append(info["destination_state"])
        last = action
    return {"info": info, "maneuvers": maneuvers, "times": instruction_times, "aircraft": np.array(aircraft),
            "destination": np.array(destination)}


def assert_same_flight(result, replayed) -> None:
    info = replayed["info"]
    assert result.outcome == info["outcome"]
    assert result.decisions == info["step_count"] == len(replayed["maneuvers"])
    assert len(result.instructions) == info["instruction_count"]
    assert [instruction.time_s for instruction in result.instructions] == replayed["times"]
    assert result.trajectory.maneuvers == replayed["maneuvers"]
    np.testing.assert_allclose(np.array(result.trajectory.aircraft), replayed["aircraft"], atol=1e-6)
    np.testing.assert_allclose(np.array(result.trajectory.destination), replayed["destination"], atol=1e-6)
    # Each instruction is given where the aircraft is at its decision, and names its maneuver.
    for instruction in result.instructions:
        index = round(instruction.time_s / 3.0)
        assert instruction.maneuver == result.trajectory.maneuvers[index]
        assert instruction.name == MANEUVER_NAMES[instruction.maneuver]
        np.testing.assert_allclose(instruction.position, replayed["aircraft"][index][:3], atol=1e-6)
    assert 3.0 * (result.decisions - 1) < result.flight_time_s <= 3.0 * result.decisions + 1e-9


@pytest.mark.parametrize("seed", [0, 1])
def test_a_plan_of_the_baseline_is_what_the_gym_env_flies(guide, seed):
    params = task_parameters(guide)
    env = GuidanceGymEnv(task="fixed")
    for field in ("simulation", "maneuvers", "max_decisions", "destination"):
        assert getattr(env.params, field) == getattr(params, field), field  # the same task, so the same flight
    _, info = env.reset(seed=seed)
    result = plan(guide, params, info["aircraft_state"])
    assert result.outcome == "success"
    assert len(result.instructions) >= 1  # the start is 2 km or more away: the baseline has to say something
    assert_same_flight(result, replay(env, guide, info))


class ScriptedGuide:
    """A guide that answers a fixed list of maneuvers, one per decision."""

    def __init__(self, maneuvers: list[int]):
        self.maneuvers, self.asked = maneuvers, 0

    def instruct(self, aircraft_state, destination_state, last_action) -> int:
        self.asked += 1
        return self.maneuvers[self.asked - 1]


def test_instructions_are_the_evaluations_changes_of_maneuver():
    """Steady flight first is no instruction (the aircraft starts in it); each change of maneuver is one."""
    script = [0, 0, 1, 1, 0, 3, 3, 5, 6, 6]
    params = dataclasses.replace(task_parameters(Guide.load("baseline")), max_decisions=len(script))
    start = [float(value) for value in START]
    result = plan(ScriptedGuide(script), params, start)
    env = GuidanceGymEnv(task="fixed", max_decisions=len(script))
    _, info = env.reset(options={"aircraft_state": start})
    assert_same_flight(result, replay(env, ScriptedGuide(script), info))
    assert result.outcome == "budget_exhausted"
    assert [(instruction.time_s, instruction.name) for instruction in result.instructions] == [
        (6.0, "left_turn"), (12.0, "steady_flight"), (15.0, "accelerate"), (21.0, "pull_up"), (24.0, "push_over")]


def test_a_moving_destination_moves_as_its_motion_model_says(guide):
    params = task_parameters(guide, ["task=uniform", "speed=50"])
    assert params.destination.speed == 50.0
    aircraft = [float(value) for value in START]
    result = plan(guide, params, aircraft)
    times = np.array(result.trajectory.time_s)
    destination = np.array(result.trajectory.destination)
    np.testing.assert_allclose(destination[:, 0], 50.0 * times, atol=1e-6)  # straight along psi = 0 at 50 m/s
    np.testing.assert_allclose(destination[:, 1:], 0.0, atol=1e-9)
    env = GuidanceGymEnv(task="uniform", speed=50.0)
    _, info = env.reset(options={"aircraft_state": aircraft})
    assert_same_flight(result, replay(env, guide, info))

    curved = task_parameters(guide, ["task=curved", "radius=1000"])
    path = np.array(plan(guide, curved, aircraft).trajectory.destination)
    assert np.ptp(path[:, 0]) > 100.0  # it moved
    # Counter-clockwise from the origin heading +x: a circle of radius 1000 m about (0, 1000).
    np.testing.assert_allclose(np.hypot(path[:, 0], path[:, 1] - 1000.0), 1000.0, atol=1e-6)


def test_guide_plan_is_plan_on_the_guides_own_task_with_the_overrides(guide):
    start = [float(value) for value in START]
    for task in ((), ("task=uniform", "speed=50")):
        assert guide.plan(start, task=task).as_dict() == plan(guide, task_parameters(guide, task), start).as_dict()


def test_the_texts_name_the_load_factors_of_the_params(guide):
    params = task_parameters(guide)
    loads = dataclasses.replace(params.maneuvers, turn=3.5, pull_up=2.5, push_over=-0.5, acceleration=0.25,
                                deceleration=0.2)
    expected = {"steady_flight": "steady flight", "left_turn": "left turn (3.5 g)", "right_turn": "right turn (3.5 g)",
                "accelerate": "accelerate (0.25 g)", "decelerate": "decelerate (0.2 g)", "pull_up": "pull up (2.5 g)",
                "push_over": "push over (-0.5 g)"}
    assert [maneuver_text(index, loads) for index in range(7)] == [expected[name] for name in MANEUVER_NAMES]
    result = plan(guide, dataclasses.replace(params, maneuvers=loads), [float(value) for value in START])
    assert result.instructions
    assert [instruction.text for instruction in result.instructions] == [
        expected[instruction.name] for instruction in result.instructions]


def test_budget_and_airspace_endings(guide):
    params = task_parameters(guide)
    short = plan(guide, dataclasses.replace(params, max_decisions=2), [float(value) for value in START])
    assert (short.outcome, short.decisions, short.flight_time_s) == ("budget_exhausted", 2, pytest.approx(6.0))
    out = plan(guide, params, [9_900.0, 0.0, 2_500.0, 250.0, 0.0, 0.0, 0.0])  # 100 m from the wall, flying at it
    assert out.outcome == "out_of_airspace" and out.decisions == 1 and out.flight_time_s < 1.0
    assert out.trajectory.aircraft[-1][0] > 10_000.0
    with pytest.raises(PlanError, match=r"^aircraft_state V=300 is not allowed: the aircraft's speed limits"):
        plan(guide, params, [0.0, 0.0, 2_500.0, 300.0, 0.0, 0.0, 0.0])


def test_the_command_prints_one_line_per_instruction_and_the_outcome(guide):
    command = [sys.executable, "-m", "agrl.plan", "--aircraft", *START, "task=uniform", "speed=50"]
    completed = subprocess.run(command, capture_output=True, text=True, timeout=300, check=True)
    lines = completed.stdout.splitlines()
    expected = plan(guide, task_parameters(guide, ["task=uniform", "speed=50"]), [float(value) for value in START])
    assert len(lines) == len(expected.instructions) + 1
    for line, instruction in zip(lines, expected.instructions, strict=False):
        assert re.fullmatch(r"t=\s*\d+ s  .+", line) and line == f"t={instruction.time_s:4.0f} s  {instruction.text}"
    assert lines[-1].startswith(f"{expected.outcome.replace('_', ' ')} after ")


def test_json_and_figure(guide, tmp_path, capsys):
    figure = tmp_path / "new" / "plan.png"
    assert main(["--aircraft", *START, "--destination", "1000", "-500", "300", "0.5", "--json",
                 "--figure", str(figure)]) == 0
    printed = json.loads(capsys.readouterr().out)
    expected = plan(guide, task_parameters(guide), [float(value) for value in START], (1000.0, -500.0, 300.0, 0.5))
    assert printed == json.loads(expected.to_json())
    assert printed["trajectory"]["destination"][0] == [1000.0, -500.0, 300.0, 0.5]
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


BAD = [
    (["--aircraft", "1", "2", "3"], "--aircraft of 3 numbers is not allowed: 7 finite numbers"),
    (["--aircraft", *START[:2], "nan", *START[3:]], "--aircraft Z=nan is not allowed"),
    (["--aircraft", *START[:4], "-inf", *START[5:]], "--aircraft THETA=-inf is not allowed"),
    (["--aircraft", *START[:2], "6000", *START[3:]], "--aircraft Z=6000 is not allowed: inside the airspace"),
    (["--aircraft", *START[:3], "300", *START[4:]], "--aircraft V=300 is not allowed: the aircraft's speed limits"),
    (["--aircraft", *START[:4], "0.7", *START[5:]], "--aircraft THETA=0.7 is not allowed: the aircraft's flight-path"),
    (["--aircraft", *START, "--destination", "0", "20000", "0", "0"], "--destination Y=20000 is not allowed"),
    (["--aircraft", *START, "--destination", "0", "0", "0"], "--destination of 3 numbers is not allowed"),
    (["--aircraft", "a", *START[1:]], "--aircraft=['a', "),
    (["--aircraft", *START, "task=irregular"], "task=irregular is not allowed: a plan needs"),
    (["--aircraft", *START, "episodes=5"], "episodes=5 is not allowed: a task override"),
    (["--aircraft", *START, "task=uniform", "speed=-1"], "speed=-1"),
    (["--aircraft", *START, "--checkpoint", "nowhere.pt"], "nowhere.pt: no such checkpoint"),
    (["--aircraft", *START, "--figure", "plan.jpg"], "--figure=plan.jpg is not allowed: a .png file"),
    (["--destination", "0", "0", "0", "0"], "the following arguments are required: --aircraft"),
]


@pytest.mark.parametrize(("argv", "message"), BAD, ids=[message[:40] for _, message in BAD])
def test_bad_input_is_one_line_naming_the_value_and_writes_nothing(tmp_path, capsys, argv, message):
    figure = tmp_path / "out" / "plan.png"
    if "--figure" in argv:
        argv = [str(tmp_path / "out" / value) if value == "plan.jpg" else value for value in argv]
        message = message.replace("plan.jpg", str(tmp_path / "out" / "plan.jpg"))
    else:
        argv = [*argv, "--figure", str(figure)]
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and captured.err.startswith("agrl.plan: error: ")
    assert message in captured.err
    assert list(tmp_path.iterdir()) == []



# ---------------------------------------------------------------------------- an agent holding targets
def replay_targets(guide: Guide, params, aircraft: list[float]) -> dict:
    """Fly the guide's actions through a one-row GuidanceEnv (the training env); it counts the instructions."""
    import torch

    from agrl.envs import GuidanceEnv

    env = GuidanceEnv(params, num_envs=1, seed=0)
    state = env.reset(env.scenario(aircraft_state=torch.tensor(aircraft)))
    actions, path, counts = [], [state["aircraft_state"][0].tolist()], []
    while not bool(state["done"].any()):
        action = guide.instruct(state["aircraft_state"][0].tolist(), state["destination_state"][0].tolist(),
                                state["held_targets"][0].tolist())
        state["action"] = torch.tensor([action])
        state = env.step(state)["next"]
        actions.append(action)
        path.append(state["aircraft_state"][0].tolist())
        counts.append(int(state["instruction_count"][0]))
    return {"actions": actions, "aircraft": np.array(path), "instructions": counts[-1],
            "outcome": ("running", "success", "out_of_airspace", "budget_exhausted")[int(state["outcome"][0])]}


def test_a_plan_of_an_agent_holding_targets_is_what_the_training_env_flies(tiny_targets_run):
    guide = Guide.load(tiny_targets_run.run_dir)
    params = task_parameters(guide)
    assert params.actions.holds_targets
    start = [float(value) for value in START]
    result = plan(guide, params, start)
    replayed = replay_targets(guide, params, start)
    assert result.trajectory.maneuvers == replayed["actions"] and result.outcome == replayed["outcome"]
    assert len(result.instructions) == replayed["instructions"]
    np.testing.assert_allclose(np.array(result.trajectory.aircraft), replayed["aircraft"], atol=1e-3)
    assert result.flight_time_s == pytest.approx(3.0 * result.decisions)


class ScriptedTargetGuide(ScriptedGuide):
    holds_targets = True


def test_target_instructions_are_changes_of_a_target_in_a_controllers_words(tiny_targets_run):
    guide = Guide.load(tiny_targets_run.run_dir)
    table = guide.target_table
    index = {(int(kind), round(float(value), 3)): row for row, (kind, value) in
             enumerate(zip(table.kind.tolist(), table.value.tolist(), strict=True))}
    hold, heading_90, heading_0 = 0, index[(1, round(np.pi / 2, 3))], index[(1, 0.0)]
    climb, descend, slow = index[(2, 3500.0)], index[(2, 100.0)], index[(3, 100.0)]
    script = [hold, heading_0, climb, climb, heading_90, hold, slow, descend]
    params = dataclasses.replace(task_parameters(guide), max_decisions=len(script))
    result = plan(ScriptedTargetGuide(script), params, [float(value) for value in START])
    assert result.outcome == "budget_exhausted" and result.trajectory.maneuvers == script
    # hold and heading 0 (already flown) and the same climb again are no instructions; +x east, +y north
    assert [(instruction.time_s, instruction.name, instruction.text) for instruction in result.instructions] == [
        (6.0, "altitude", "climb to 3 500 m"), (12.0, "heading", "turn left heading 000"),
        (18.0, "speed", "reduce speed to 100 m/s"), (21.0, "altitude", "descend to 100 m")]
