"""The decision simulator: compiled vs eager, frozen rows, substep count."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch

from agrl.core.aircraft import AircraftLimits
from agrl.core.simulation import DecisionSimulator
from agrl.core.termination import Outcome


@pytest.fixture(scope="module")
def simulation(paper_parameters):
    """conf/simulation/paper.yaml's simulation (20 ms steps, 3 s decisions)."""
    return paper_parameters.simulation


@pytest.fixture(scope="module")
def controls(paper_parameters):
    return paper_parameters.maneuvers.controls()


def random_batch(count: int, seed: int, limits: AircraftLimits, near: int = 4):
    generator = torch.Generator().manual_seed(seed)
    u = lambda *shape: torch.rand(*shape, generator=generator)  # noqa: E731
    aircraft = torch.stack(
        (
            u(count) * 18_000 - 9_000,
            u(count) * 18_000 - 9_000,
            500 + u(count) * 4_000,
            limits.min_speed + (limits.max_speed - limits.min_speed) * u(count),
            (u(count) * 2 - 1) * 0.4,
            (u(count) * 2 - 1) * math.pi,
            torch.zeros(count),
        ),
        dim=-1,
    )
    destination = torch.stack(
        (
            u(count) * 18_000 - 9_000,
            u(count) * 18_000 - 9_000,
            u(count) * 5_000,
            (u(count) * 2 - 1) * math.pi,
        ),
        dim=-1,
    )
    # Put the first `near` aircraft right behind their destination so that they succeed mid-decision.
    destination[:near, :2] = aircraft[:near, :2] + 300 * torch.stack(
        (torch.cos(aircraft[:near, 5]), torch.sin(aircraft[:near, 5])), dim=-1
    )
    destination[:near, 2] = aircraft[:near, 2]
    destination[:near, 3] = aircraft[:near, 5]
    speed = 50 * u(count)
    turn_rate = (u(count) * 2 - 1) * 0.05
    return aircraft, destination, speed, turn_rate, generator


def run(simulator, aircraft, destination, speed, turn_rate, actions_per_decision):
    outcomes = []
    for actions in actions_per_decision:
        result = simulator(aircraft, destination, speed, turn_rate, actions)
        aircraft, destination = result.aircraft_state, result.destination_state
        outcomes.append(result.outcome)
    return aircraft, destination, torch.stack(outcomes)


def test_substeps_from_decision_period(simulation):
    assert simulation.substeps == 150
    assert dataclasses.replace(simulation, integration_step=0.05, decision_period=1.0).substeps == 20
    with pytest.raises(ValueError, match="whole multiple"):
        _ = dataclasses.replace(simulation, integration_step=0.07, decision_period=3.0).substeps


@pytest.mark.slow
def test_compiled_matches_eager(simulation, controls):
    """The fused step as training compiles it (ten integration steps per call) against the eager one over three
    decisions. Tolerances: float32 sums of 150 steps in another order differ by at most 1e-2 m in position and
    1e-4 in speed (m/s) and angles (rad); outcomes exactly. Slow: its cold compilation takes about half a minute
    on one core; the fast suite compares a two-step kernel, below."""
    compiled_simulator = DecisionSimulator(simulation, controls, compile=True)
    assert compiled_simulator.substeps_per_call == 10
    _assert_compiled_matches_eager(compiled_simulator, simulation, controls, counts=(16,), decisions=3)


def test_inactive_rows_are_frozen(simulation, controls):
    count = 8
    aircraft, destination, speed, turn_rate, generator = random_batch(count, seed=1, limits=simulation.limits, near=0)
    active = torch.tensor([True, False] * 4)
    actions = torch.randint(0, 7, (count,), generator=generator)
    simulator = DecisionSimulator(simulation, controls, compile=False)
    result = simulator(aircraft, destination, speed + 20, turn_rate, actions, active=active)
    frozen = ~active
    # Inactive rows: every field unchanged (headings were already wrapped: wrapping again may round) and no
    # outcome; the other fields exactly (a frozen row takes zero-length steps).
    torch.testing.assert_close(result.aircraft_state[frozen], aircraft[frozen], rtol=0, atol=1e-6)
    unwrapped = [0, 1, 2, 3, 4, 6]
    assert torch.equal(result.aircraft_state[frozen][:, unwrapped], aircraft[frozen][:, unwrapped])
    assert torch.equal(result.destination_state[frozen][:, :3], destination[frozen][:, :3])
    torch.testing.assert_close(result.destination_state[frozen], destination[frozen], rtol=0, atol=1e-6)
    assert torch.all(result.outcome[frozen] == Outcome.RUNNING)
    # Active rows moved (aircraft always, destination at >= 20 m/s).
    moved = (result.aircraft_state[active, :2] - aircraft[active, :2]).norm(dim=-1)
    assert torch.all(moved > 250)
    dest_moved = (result.destination_state[active, :2] - destination[active, :2]).norm(dim=-1)
    assert torch.all(dest_moved > 50)


def test_finished_row_freezes_aircraft_and_destination_together(simulation, controls):
    tolerance = dataclasses.replace(simulation.tolerance, distance=300.0)
    simulator = DecisionSimulator(dataclasses.replace(simulation, tolerance=tolerance), controls, compile=False)
    aircraft = torch.tensor(
        [[-400.0, 0.0, 1_000.0, 250.0, 0.0, 0.0, 0.0], [-4_000.0, 0.0, 1_000.0, 250.0, 0.0, 0.0, 0.0]]
    )
    destination = torch.tensor([[0.0, 0.0, 1_000.0, 0.0], [0.0, 3_000.0, 1_000.0, 0.0]])
    speed = torch.tensor([20.0, 20.0])  # destinations fly along +x too
    result = simulator(aircraft, destination, speed, torch.zeros(2), torch.zeros(2, dtype=torch.int64))
    assert result.outcome.tolist() == [Outcome.SUCCESS, Outcome.RUNNING]
    # Closing speed 230 m/s from 400 m: inside 300 m after ceil(100 / 4.6) = 22 steps of 20 ms.
    steps = math.ceil(100.0 / (230.0 * 0.02))
    assert float(result.aircraft_state[0, 0]) == pytest.approx(-400.0 + 250.0 * 0.02 * steps, abs=1e-3)
    assert float(result.destination_state[0, 0]) == pytest.approx(20.0 * 0.02 * steps, abs=1e-3)
    # The running row flew the whole decision.
    assert float(result.aircraft_state[1, 0]) == pytest.approx(-4_000.0 + 750.0, abs=1e-2)
    assert float(result.destination_state[1, 0]) == pytest.approx(60.0, abs=1e-3)


def test_headings_are_wrapped(simulation, controls):
    simulator = DecisionSimulator(simulation, controls, compile=False)
    aircraft = torch.tensor([[0.0, 0.0, 2_000.0, 100.0, 0.0, math.pi - 0.01, 0.0]])
    destination = torch.tensor([[5_000.0, 5_000.0, 0.0, math.pi - 0.01]])
    result = simulator(aircraft, destination, torch.tensor([20.0]), torch.tensor([0.05]), torch.tensor([1]))
    for heading in (result.aircraft_state[0, 5], result.destination_state[0, 3]):
        assert -math.pi <= float(heading) < math.pi
        assert float(heading) < 0  # crossed +pi and came back as a negative angle


def test_compiled_matches_eager_on_shrinking_batches(simulation, controls):
    """One compiled simulator fed batches of decreasing size, as the reuse replay does when it drops finished
    episodes: the second size recompiles for dynamic sizes, one row specialises again. Two integration steps per
    compiled call (the same step function and inductor options as training's ten, whose kernel the slow test above
    compares): a short kernel compiles in a third of the time. Tolerances as above."""
    compiled_simulator = DecisionSimulator(simulation, controls, compile=True, substeps_per_call=2)
    _assert_compiled_matches_eager(compiled_simulator, simulation, controls, counts=(64, 37, 5, 1), decisions=2)


def _assert_compiled_matches_eager(compiled_simulator, simulation, controls, counts, decisions):
    eager_simulator = DecisionSimulator(simulation, controls, compile=False)
    for count in counts:
        aircraft, destination, speed, turn_rate, generator = random_batch(count, seed=count, limits=simulation.limits,
                                                                          near=min(4, count))
        actions = [torch.randint(0, 7, (count,), generator=generator) for _ in range(decisions)]
        eager = run(eager_simulator, aircraft, destination, speed, turn_rate, actions)
        compiled = run(compiled_simulator, aircraft, destination, speed, turn_rate, actions)
        assert compiled_simulator.compiled, f"torch.compile fell back to eager at {count} rows"
        assert compiled[0].shape == (count, 7)
        assert torch.equal(compiled[2], eager[2]), count  # outcomes
        assert bool((eager[2] == Outcome.SUCCESS).any()), count  # frozen rows are compared too
        torch.testing.assert_close(compiled[0], eager[0], rtol=1e-5, atol=1e-2, msg=f"aircraft, {count} rows")
        torch.testing.assert_close(compiled[1], eager[1], rtol=1e-5, atol=1e-2, msg=f"destination, {count} rows")
        torch.testing.assert_close(compiled[0][:, 3:], eager[0][:, 3:], rtol=1e-5, atol=1e-4,
                                   msg=f"speeds and angles, {count} rows")


class _FailingCompile:
    """What ``torch.compile`` returns on a machine without a C++ compiler, as far as compiling is concerned."""

    def __init__(self, function, *args, **kwargs):
        pass

    def aot_compile(self, example_inputs):
        raise RuntimeError("no C++ compiler")


def test_a_simulator_whose_compilation_fails_warns_once_and_runs_eagerly(monkeypatch, tmp_path, paper_parameters):
    params = paper_parameters.simulation
    controls = paper_parameters.maneuvers.controls("cpu")
    aircraft, destination, speed, turn_rate, generator = random_batch(8, seed=2, limits=params.limits)
    actions = [torch.randint(0, 7, (8,), generator=generator) for _ in range(2)]
    eager = run(DecisionSimulator(params, controls), aircraft, destination, speed, turn_rate, actions)

    monkeypatch.setenv("AGRL_COMPILE_CACHE", str(tmp_path))  # nothing kept from an earlier compilation
    monkeypatch.setattr(torch, "compile", _FailingCompile)
    simulator = DecisionSimulator(params, controls, compile=True)
    assert simulator.compiled
    failure = "torch.compile of the simulation step failed.*no C\\+\\+ compiler"
    with pytest.warns(RuntimeWarning, match=failure) as caught:
        fallen_back = run(simulator, aircraft, destination, speed, turn_rate, actions)  # 2 decisions, 30 calls
    assert sum("simulation step failed" in str(warning.message) for warning in caught) == 1  # once, not per call
    assert not simulator.compiled
    for result, expected in zip(fallen_back, eager, strict=True):
        torch.testing.assert_close(result, expected)


# ---------------------------------------------------------------------- held targets (agrl.core.autopilot)
@pytest.fixture(scope="module")
def autopilot(paper_parameters):
    from agrl.core.autopilot import AutopilotParameters

    loads = paper_parameters.maneuvers
    return AutopilotParameters(turn_load_factor=loads.turn, pull_up_load_factor=loads.pull_up,
                               push_over_load_factor=loads.push_over, acceleration_load_factor=loads.acceleration,
                               deceleration_load_factor=loads.deceleration, heading_time_constant=2.0,
                               altitude_time_constant=4.0, flight_path_time_constant=1.0, speed_time_constant=5.0,
                               capture_fraction=0.5)


def _held_targets(count: int, generator: torch.Generator) -> torch.Tensor:
    u = lambda: torch.rand(count, generator=generator)  # noqa: E731
    return torch.stack(((u() * 2 - 1) * math.pi, 500 + u() * 4_000, 100 + u() * 150), dim=-1)


def test_a_decision_with_held_targets_is_150_autopilot_steps(simulation, controls, autopilot):
    """One decision of the simulator with held targets equals 150 steps of agrl.core.autopilot.autopilot_step for
    rows that neither succeed nor leave the airspace, and wraps the heading."""
    from agrl.core.aircraft import AircraftState, wrap_angle
    from agrl.core.autopilot import HeldTargets, autopilot_step

    count = 32
    aircraft, destination, speed, turn_rate, generator = random_batch(count, seed=5, limits=simulation.limits, near=0)
    targets = _held_targets(count, generator)
    simulator = DecisionSimulator(simulation, controls, compile=False, autopilot=autopilot)
    result = simulator.fly_targets(aircraft, destination, speed, turn_rate, targets)
    state = AircraftState.from_tensor(aircraft)
    for _ in range(simulation.substeps):
        state = autopilot_step(state, HeldTargets(*targets.unbind(-1)), simulation.integration_step, simulation.limits,
                            autopilot)
    expected = state._replace(heading=wrap_angle(state.heading)).to_tensor()
    running = result.outcome == Outcome.RUNNING
    assert int(running.sum()) >= count // 2
    torch.testing.assert_close(result.aircraft_state[running], expected[running], rtol=0, atol=0)


def test_held_targets_rows_finish_and_freeze(simulation, controls, autopilot):
    """A row on the destination's track succeeds within the decision and stops there; an inactive row stays."""
    aircraft = torch.tensor([[-1_500.0, 0.0, 0.0, 200.0, 0.0, 0.0, 0.0],
                             [-5_000.0, 0.0, 2_000.0, 200.0, 0.0, 0.0, 0.0]])
    destination = torch.zeros(2, 4)
    targets = torch.tensor([[0.0, 0.0, 200.0], [0.0, 2_000.0, 200.0]])
    simulator = DecisionSimulator(simulation, controls, compile=False, autopilot=autopilot)
    result = simulator.fly_targets(aircraft, destination, torch.zeros(2), torch.zeros(2), targets,
                                   active=torch.tensor([True, False]))
    assert result.outcome.tolist() == [int(Outcome.SUCCESS), int(Outcome.RUNNING)]
    # Stopped where it entered the 1 km tolerance (4 m a step at 200 m/s), 2.5 s into the decision.
    assert -1_000.0 - 4.0 <= float(result.aircraft_state[0, 0]) <= -1_000.0
    torch.testing.assert_close(result.aircraft_state[1], aircraft[1])


def test_held_targets_need_an_autopilot(simulation, controls):
    simulator = DecisionSimulator(simulation, controls, compile=False)
    with pytest.raises(ValueError, match="fly_targets needs a DecisionSimulator built with autopilot="):
        simulator.fly_targets(torch.zeros(1, 7), torch.zeros(1, 4), torch.zeros(1), torch.zeros(1), torch.zeros(1, 3))


@pytest.mark.slow
def test_held_targets_compiled_match_eager(simulation, controls, autopilot):
    """The fused target step (ten integration steps a call, its own compilation) against the eager one, over three
    decisions, with the maneuvers' compiled test's tolerances."""
    count = 16
    aircraft, destination, speed, turn_rate, generator = random_batch(count, seed=6, limits=simulation.limits)
    targets = _held_targets(count, generator)
    eager = DecisionSimulator(simulation, controls, compile=False, autopilot=autopilot)
    fused = DecisionSimulator(simulation, controls, compile=True, autopilot=autopilot)
    states = {"eager": (aircraft, destination), "fused": (aircraft, destination)}
    for _ in range(3):
        results = {}
        for name, simulator in (("eager", eager), ("fused", fused)):
            results[name] = simulator.fly_targets(*states[name], speed, turn_rate, targets)
            states[name] = (results[name].aircraft_state, results[name].destination_state)
        assert fused._targets_step().compiled
        assert torch.equal(results["fused"].outcome, results["eager"].outcome)
        torch.testing.assert_close(results["fused"].aircraft_state[:, :3], results["eager"].aircraft_state[:, :3],
                                   rtol=0, atol=1e-2)
        torch.testing.assert_close(results["fused"].aircraft_state[:, 3:], results["eager"].aircraft_state[:, 3:],
                                   rtol=0, atol=1e-4)
