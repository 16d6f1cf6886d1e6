"""The pure-Python reference (agrl/reference.py) computes what the torch simulator computes.

A correctness test, not a timing test: it makes ``python -m benchmarks.bench`` compare like with like.
In float64 the two agree to rounding; in float32 (what training runs) to float32 accuracy.
"""

from __future__ import annotations

import math
import random

import pytest
import torch

from agrl.core.aircraft import maneuver_table
from agrl.core.destinations import curved_turn_rate
from agrl.core.parameters import GuidanceParameters
from agrl.core.simulation import DecisionSimulator
from agrl.core.termination import Outcome
from agrl.reference import maneuver_rows, reference_decision, wrap_angle

# (aircraft x, y, z, v, theta, psi, phi), (destination x, y, z, psi), destination speed, turn rate
SCENARIOS = {
    "fixed": ((-6_000.0, 3_000.0, 2_500.0, 200.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), 0.0, 0.0),
    "uniform": ((4_000.0, -5_000.0, 1_000.0, 180.0, 0.1, 2.0, 0.0), (0.0, 0.0, 0.0, 0.0), 50.0, 0.0),
    "curved": ((-2_000.0, -7_000.0, 4_000.0, 230.0, -0.2, -1.0, 0.0), (500.0, 0.0, 0.0, 1.5), 20.0,
               curved_turn_rate(20.0, 500.0, -1.0)),
    "irregular": ((0.0, 8_000.0, 3_000.0, 120.0, 0.0, -3.0, 0.0), (-3_000.0, 2_000.0, 0.0, -0.5), 37.0, 0.03),
    # the destination crosses the +x wall during the first decision and is reflected
    "wall": ((-5_000.0, 0.0, 2_000.0, 200.0, 0.0, 3.0, 0.0), (9_990.0, 9_995.0, 0.0, 0.7), 100.0, 0.0),
}


def _torch_decisions(scenario, actions, dtype, params: GuidanceParameters):
    """One row's decisions: :func:`_torch_rows` of one scenario."""
    return _torch_rows([scenario], [actions], dtype, params)[0]


def _torch_rows(scenarios, action_rows, dtype, params: GuidanceParameters):
    """Each scenario flown with its own actions, all as rows of one batch (the simulator's cost is per
    operation, not per row): per row, its decisions' results up to the first that ends the episode."""
    maneuvers = params.maneuvers
    controls = maneuver_table(maneuvers.turn, maneuvers.pull_up, maneuvers.push_over,
                              maneuvers.acceleration, maneuvers.deceleration, dtype=dtype)
    simulator = DecisionSimulator(params.simulation, controls, compile=False)
    aircraft, destination, speed, turn_rate = (torch.tensor(list(field), dtype=dtype)
                                               for field in zip(*scenarios, strict=True))
    results = [[] for _ in scenarios]
    for actions in zip(*action_rows, strict=True):
        running = [not rows or rows[-1][2] == Outcome.RUNNING for rows in results]
        if not any(running):
            break
        # A row that has ended is frozen (active=False) and read no more, as a row flown alone stops there.
        result = simulator(aircraft, destination, speed, turn_rate, torch.tensor(actions),
                           active=torch.tensor(running))
        for row, rows in enumerate(results):
            if running[row]:
                rows.append((result.aircraft_state[row].tolist(), result.destination_state[row].tolist(),
                             int(result.outcome[row])))
        aircraft, destination = result.aircraft_state, result.destination_state
    return results


def _reference_decisions(scenario, actions, params: GuidanceParameters):
    aircraft, destination, speed, turn_rate = scenario
    results = []
    for action in actions:
        result = reference_decision(aircraft, destination, speed, turn_rate, action, params.simulation,
                                    params.maneuvers)
        results.append((list(result.aircraft_state), list(result.destination_state), result.outcome))
        aircraft, destination = result.aircraft_state, result.destination_state
        if result.outcome != Outcome.RUNNING:
            break
    return results


def _assert_close(torch_results, reference_results, position_m, angle_rad, speed_ms):
    assert len(torch_results) == len(reference_results)
    for (aircraft, destination, outcome), (ref_aircraft, ref_destination, ref_outcome) in zip(
        torch_results, reference_results, strict=True
    ):
        assert outcome == ref_outcome
        tolerances = (position_m,) * 3 + (speed_ms, angle_rad, angle_rad, angle_rad)
        names = ("x", "y", "z", "v", "θ", "ψ", "φ")
        for name, value, expected, tolerance in zip(names, aircraft, ref_aircraft, tolerances, strict=True):
            difference = wrap_angle(value - expected) if name == "ψ" else value - expected
            assert abs(difference) <= tolerance, (name, value, expected)
        for name, value, expected, tolerance in zip("xyzψ", destination, ref_destination,
                                                    (position_m,) * 3 + (angle_rad,), strict=True):
            difference = wrap_angle(value - expected) if name == "ψ" else value - expected
            assert abs(difference) <= tolerance, ("destination", name, value, expected)


def test_maneuver_rows_match_the_torch_table(paper_parameters):
    table = paper_parameters.maneuvers.controls()
    for index, (axial, normal, direction) in enumerate(maneuver_rows(paper_parameters.maneuvers)):
        assert table.axial_excess[index].item() == pytest.approx(axial)
        assert table.turn_direction[index].item() == direction
        if normal is None:
            assert math.isnan(table.normal_load[index].item())
        else:
            assert table.normal_load[index].item() == pytest.approx(normal)


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_every_maneuver_agrees_in_float64(name, paper_parameters):
    """Four decisions (600 integration steps) per maneuver: equal to rounding error. The seven maneuvers' rows fly
    as one batch of the torch simulator, each compared with its own reference flight."""
    action_rows = [[action, action, (action + 3) % 7, action] for action in range(7)]
    actual = _torch_rows([SCENARIOS[name]] * 7, action_rows, torch.float64, paper_parameters)
    for actions, row in zip(action_rows, actual, strict=True):
        expected = _reference_decisions(SCENARIOS[name], actions, paper_parameters)
        _assert_close(row, expected, position_m=1e-6, angle_rad=1e-9, speed_ms=1e-9)


def test_random_sequences_agree_in_float32(paper_parameters):
    """What training runs: float32 tensors stay within float32 accuracy of the float64 reference (the scenarios
    as rows of one batch)."""
    rng = random.Random(0)
    action_rows = [[rng.randrange(7) for _ in range(5)] for _ in SCENARIOS]
    actual = _torch_rows(list(SCENARIOS.values()), action_rows, torch.float32, paper_parameters)
    for scenario, actions, row in zip(SCENARIOS.values(), action_rows, actual, strict=True):
        expected = _reference_decisions(scenario, actions, paper_parameters)
        _assert_close(row, expected, position_m=1.0, angle_rad=1e-4, speed_ms=1e-2)


def test_the_destination_is_reflected_at_the_wall(paper_parameters):
    result = reference_decision(*SCENARIOS["wall"], 0, paper_parameters.simulation,
                                paper_parameters.maneuvers)
    x, y, _, heading = result.destination_state
    assert x < paper_parameters.simulation.airspace.x_max and y < paper_parameters.simulation.airspace.y_max
    assert math.cos(heading) < 0 and math.sin(heading) < 0  # mirrored in both walls


def test_success_and_leaving_the_airspace_end_the_decision_early(paper_parameters):
    arriving = ((-1_500.0, 0.0, 100.0, 200.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), 0.0, 0.0)
    leaving = ((9_800.0, 0.0, 1_000.0, 200.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), 0.0, 0.0)
    # 500 m to the tolerance disc at 200 m/s: 2.5 s; 200 m to the wall: 1 s (+1 step to be outside).
    cases = ((arriving, Outcome.SUCCESS, 125), (leaving, Outcome.OUT_OF_AIRSPACE, 51))
    for scenario, outcome, substeps in cases:
        result = reference_decision(*scenario, 0, paper_parameters.simulation,
                                paper_parameters.maneuvers)
        assert result.outcome == outcome and result.substeps == substeps
        # The torch simulator freezes the row at the same integration step.
        (aircraft, _, torch_outcome), = _torch_decisions(scenario, [0], torch.float64, paper_parameters)
        assert torch_outcome == outcome
        assert aircraft[0] == pytest.approx(result.aircraft_state[0], abs=1e-6)
