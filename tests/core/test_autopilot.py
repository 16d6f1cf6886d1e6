"""The autopilot (agrl.core.autopilot) against derivations made by hand from its law and equation 3: a 90-degree
turn, a 1 000 m and a 3 000 m climb, a small altitude step, a speed change (times and end states), and the action
set."""

from __future__ import annotations

import math

import pytest
import torch

from agrl.core.aircraft import GRAVITY, AircraftState, wrap_angle
from agrl.core.autopilot import (
    AutopilotParameters,
    HeldTargets,
    TargetKind,
    apply_target_action,
    autopilot_loads,
    autopilot_step,
    target_action_table,
)

DT = 0.02  # s: the paper's integration step
SPEED = 200.0  # m/s: the training starts' cruise speed
#: Time constants (s) for these tests (tau_z = 4 tau_theta: the critically damped altitude loop) and the share of
#: the load factors' vertical acceleration an altitude capture plans with.
TIME_CONSTANTS = {"heading_time_constant": 2.0, "altitude_time_constant": 4.0, "flight_path_time_constant": 1.0,
                  "speed_time_constant": 5.0, "capture_fraction": 0.5}


@pytest.fixture(scope="module")
def setup(compose_parameters):
    params = compose_parameters("task=fixed")
    loads = params.maneuvers
    autopilot = AutopilotParameters(turn_load_factor=loads.turn, pull_up_load_factor=loads.pull_up,
                                    push_over_load_factor=loads.push_over,
                                    acceleration_load_factor=loads.acceleration,
                                    deceleration_load_factor=loads.deceleration, **TIME_CONSTANTS)
    return params.simulation.limits, autopilot


def _level(z: float = 2_000.0, speed: float = SPEED, heading: float = 0.0) -> AircraftState:
    value = lambda v: torch.tensor([v], dtype=torch.float64)  # noqa: E731
    return AircraftState(value(0.0), value(0.0), value(z), value(speed), value(0.0), value(heading), value(0.0))


def _fly(aircraft, targets, seconds, limits, autopilot):
    """Every integration step's state and loads for ``seconds``."""
    states, loads = [], []
    for _ in range(round(seconds / DT)):
        loads.append(autopilot_loads(aircraft, targets, limits, autopilot))
        aircraft = autopilot_step(aircraft, targets, DT, limits, autopilot)
        states.append(aircraft)
    return states, loads


def _first_time(states, condition) -> float:
    for step, state in enumerate(states):
        if condition(state):
            return (step + 1) * DT
    raise AssertionError("never")


def test_a_90_degree_turn_at_the_turn_load_factor_then_captured(setup):
    """Heading rate min(e / tau, omega): at most omega = g sqrt(n^2 - 1) / v (a level coordinated turn at n), until
    the error is omega tau, then e(t) decays as exp(-t / tau). Time to 0.01 degree from the derivation."""
    limits, autopilot = setup
    n, tau = autopilot.turn_load_factor, autopilot.heading_time_constant
    omega = GRAVITY * math.sqrt(n * n - 1.0) / SPEED
    tolerance = math.radians(0.01)
    expected = (math.pi / 2 - omega * tau) / omega + tau * math.log(omega * tau / tolerance)
    start = _level()
    states, loads = _fly(start, HeldTargets(torch.tensor([math.pi / 2], dtype=torch.float64), start.z, start.speed),
                         expected + 20.0, limits, autopilot)
    reached = _first_time(states, lambda s: abs(float(wrap_angle(s.heading - math.pi / 2))) < tolerance)
    assert reached == pytest.approx(expected, abs=0.1)
    # Equation 3's sign: a positive bank turns towards smaller psi, so a turn to +90 degrees banks negative (left).
    banks = torch.cat([load.bank for load in loads])
    assert float(banks.min()) == pytest.approx(-math.acos(1.0 / n), abs=1e-6)  # 60 degrees at 2 g
    assert float(banks.max()) <= 1e-9
    assert max(float(load.normal_load) for load in loads) <= n + 1e-9
    end = states[-1]
    assert float(end.z) == pytest.approx(float(start.z), abs=0.5)  # the vertical channel holds the altitude
    assert float(end.speed) == pytest.approx(SPEED, abs=1e-6)
    assert abs(float(end.bank)) < 1e-4


def _critically_damped_time(error: float, tolerance: float, tau: float) -> float:
    """t where e0 (1 + t / tau) exp(-t / tau) falls to ``tolerance`` (bisection)."""
    low, high = 0.0, 100.0 * tau
    for _ in range(100):
        middle = (low + high) / 2
        above = error * (1 + middle / tau) * math.exp(-middle / tau) > tolerance
        low, high = (middle, high) if above else (low, middle)
    return high


def _climb(setup, height: float):
    limits, autopilot = setup
    start = _level(z=1_000.0)
    target = HeldTargets(start.heading, torch.tensor([1_000.0 + height], dtype=torch.float64), start.speed)
    states, loads = _fly(start, target, 120.0, limits, autopilot)
    return limits, autopilot, states, loads


def test_a_1000_m_climb_is_bracketed_by_its_derivations_and_levels_off_at_the_target(setup):
    """At least 1 000 m at the flight-path limit's 100 m/s (30 degrees at 200 m/s) plus one rotation to that limit at
    the pull-up rate (no climb in half of each rotation). At most the commanded profile (sqrt(2 a e) down to
    e1 = 2 a tau_z^2, then the critically damped loop, to 1 m) plus one rotation of lag. Never above the target,
    within the vertical load factors, speed and heading held."""
    limits, autopilot, states, loads = _climb(setup, 1_000.0)
    theta_max = limits.max_flight_path_angle
    rotation = theta_max / (GRAVITY * (autopilot.pull_up_load_factor - 1.0) / SPEED)  # s at the pull-up rate
    least = 1_000.0 / (SPEED * math.sin(theta_max)) + rotation
    a, tau_z = autopilot.capture_vertical_acceleration(), autopilot.altitude_time_constant
    switch = 2 * a * tau_z ** 2
    profile = (math.sqrt(2 * 1_000.0 / a) - math.sqrt(2 * switch / a)
               + _critically_damped_time(switch, 1.0, 2 * autopilot.flight_path_time_constant))
    reached = _first_time(states, lambda s: abs(float(s.z) - 2_000.0) < 1.0)
    assert least <= reached <= profile + rotation
    vertical = torch.cat([load.normal_load * load.cos_bank for load in loads])
    assert float(vertical.min()) >= autopilot.push_over_load_factor - 1e-9
    assert float(vertical.max()) <= autopilot.pull_up_load_factor + 1e-9
    assert float(torch.cat([s.z for s in states]).max()) <= 2_000.0 + 1e-6
    end = states[-1]
    assert float(end.z) == pytest.approx(2_000.0, abs=0.01)
    assert abs(float(end.flight_path_angle)) < math.radians(0.01)
    assert float(end.speed) == pytest.approx(SPEED, abs=0.01)  # the speed channel holds the speed in the climb
    assert float(end.heading) == 0.0


def test_a_3000_m_climb_is_flown_at_the_flight_path_limit(setup):
    """sqrt(2 a e) is above the limit's 100 m/s for most of 3 000 m: the climb reaches 30 degrees, not beyond."""
    limits, _, states, _ = _climb(setup, 3_000.0)
    angles = torch.cat([s.flight_path_angle for s in states])
    assert float(angles.max()) == pytest.approx(limits.max_flight_path_angle, abs=1e-6)
    assert float(torch.cat([s.z for s in states]).max()) <= 4_000.0 + 1e-6
    assert float(states[-1].z) == pytest.approx(4_000.0, abs=0.01)


def test_a_small_altitude_step_follows_the_critically_damped_response(setup):
    """Below every limit (2 m: under e1 = 2 a tau_z^2) the loop is linear: e' = -v theta,
    theta' = (e / (tau_z v) - theta) / tau_theta; with tau_z = 4 tau_theta,
    e(t) = e0 (1 + t / (2 tau_theta)) exp(-t / (2 tau_theta))."""
    limits, autopilot = setup
    tau = 2 * autopilot.flight_path_time_constant
    assert autopilot.altitude_time_constant == pytest.approx(4 * autopilot.flight_path_time_constant)
    start = _level(z=1_000.0)
    states, _ = _fly(start, HeldTargets(start.heading, torch.tensor([1_002.0], dtype=torch.float64), start.speed),
                     20.0, limits, autopilot)
    for step in range(0, len(states), 25):
        t = (step + 1) * DT
        expected = 2.0 * (1 + t / tau) * math.exp(-t / tau)
        assert 1_002.0 - float(states[step].z) == pytest.approx(expected, abs=0.02), t


def test_a_speed_change_at_the_acceleration_load_factor_then_captured(setup):
    """Speed rate min((v* - v) / tau_v, g a): at the acceleration load factor until the error is g a tau_v, then
    exponential. 200 -> 240 m/s, time to 0.01 m/s from the derivation."""
    limits, autopilot = setup
    rate, tau = GRAVITY * autopilot.acceleration_load_factor, autopilot.speed_time_constant
    expected = (40.0 - rate * tau) / rate + tau * math.log(rate * tau / 0.01)
    start = _level()
    states, _ = _fly(start, HeldTargets(start.heading, start.z, torch.tensor([240.0], dtype=torch.float64)),
                     expected + 10.0, limits, autopilot)
    reached = _first_time(states, lambda s: abs(float(s.speed) - 240.0) < 0.01)
    assert reached == pytest.approx(expected, abs=0.1)
    end = states[-1]
    assert float(end.z) == pytest.approx(float(start.z), abs=1e-6)
    assert float(end.heading) == 0.0


def test_held_targets_are_held(setup):
    """Targets equal to the state: straight and level, nothing moves but the position."""
    limits, autopilot = setup
    start = _level(heading=1.0)
    states, _ = _fly(start, HeldTargets.of(start), 10.0, limits, autopilot)
    end = states[-1]
    for field in ("z", "speed", "flight_path_angle", "heading", "bank"):
        assert float(getattr(end, field)) == pytest.approx(float(getattr(start, field)), abs=1e-9), field
    assert float(end.x) == pytest.approx(10.0 * SPEED * math.cos(1.0), rel=1e-9)


def test_the_action_set(compose_parameters):
    params = compose_parameters("task=fixed")
    airspace, limits = params.simulation.airspace, params.simulation.limits
    table = target_action_table((airspace.z_min, airspace.z_max), limits, cruise_speed=200.0)
    kinds = table.kind.tolist()
    assert kinds.count(TargetKind.HOLD) == 1 and kinds[0] == TargetKind.HOLD
    headings = table.value[table.kind == TargetKind.HEADING]
    assert len(headings) == 12
    assert torch.allclose(torch.diff(torch.sort(headings).values), torch.full((11,), math.pi / 6))
    altitudes = table.value[table.kind == TargetKind.ALTITUDE].tolist()
    assert altitudes == [500.0 * k for k in range(1, 10)]  # every 500 m strictly inside 0-5000 m
    assert table.value[table.kind == TargetKind.SPEED].tolist() == [limits.min_speed, 200.0, limits.max_speed]
    assert len(table) == 1 + 12 + 9 + 3


def test_an_action_sets_one_target_and_an_instruction_changes_one(compose_parameters):
    params = compose_parameters("task=fixed")
    table = target_action_table((0.0, 5_000.0), params.simulation.limits, cruise_speed=200.0)
    kinds = table.kind
    hold = 0
    heading_90 = int(((kinds == TargetKind.HEADING) & torch.isclose(table.value, torch.tensor(math.pi / 2)))
                     .nonzero())
    altitude_2000 = int(((kinds == TargetKind.ALTITUDE) & (table.value == 2_000.0)).nonzero())
    targets = HeldTargets(torch.tensor([0.0, 0.0, 0.0]), torch.tensor([2_000.0, 2_000.0, 1_000.0]),
                          torch.tensor([200.0, 200.0, 200.0]))
    after, changed = apply_target_action(targets, torch.tensor([hold, heading_90, altitude_2000]), table)
    assert changed.tolist() == [False, True, True]
    assert after.heading.tolist() == pytest.approx([0.0, math.pi / 2, 0.0])
    assert after.altitude.tolist() == [2_000.0, 2_000.0, 2_000.0]
    assert after.speed.tolist() == [200.0, 200.0, 200.0]
    again, changed = apply_target_action(after, torch.tensor([heading_90, heading_90, altitude_2000]), table)
    assert changed.tolist() == [True, False, False]  # the same clearance again is no instruction


@pytest.mark.parametrize(("changes", "message"), [
    ({"heading_time_constant": 0.0}, "heading_time_constant=0.0 must be > 0"),
    ({"push_over_load_factor": 1.5}, "push_over < 1 g < pull_up <= turn"),
])
def test_bad_parameters_are_named(setup, changes, message):
    _, autopilot = setup
    import dataclasses

    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        dataclasses.replace(autopilot, **changes)


def test_rows_of_a_batch_are_flown_independently(setup):
    """A turn, a climb and a speed change in one float32 batch: each row as when flown alone."""
    limits, autopilot = setup
    rows = torch.arange(3)
    start = AircraftState(*(torch.tensor(value, dtype=torch.float32) for value in
                            ([0.0] * 3, [0.0] * 3, [1_000.0] * 3, [SPEED] * 3, [0.0] * 3, [0.0] * 3, [0.0] * 3)))
    targets = HeldTargets(torch.tensor([2.0, 0.0, 0.0]), torch.tensor([1_000.0, 1_500.0, 1_000.0]),
                          torch.tensor([SPEED, SPEED, 120.0]))
    batch, alone = start, [AircraftState(*(field[row:row + 1] for field in start)) for row in rows]
    for _ in range(500):
        batch = autopilot_step(batch, targets, DT, limits, autopilot)
        alone = [autopilot_step(state, HeldTargets(*(field[row:row + 1] for field in targets)), DT, limits, autopilot)
                 for row, state in zip(rows, alone, strict=True)]
    for row, state in zip(rows, alone, strict=True):
        for field, value in zip(batch, state, strict=True):
            torch.testing.assert_close(field[row:row + 1], value)
    assert float(batch.heading[0]) > 0.8 and float(batch.z[1]) > 1_100.0 and float(batch.speed[2]) < 175.0


def test_instruction_texts_read_as_a_controller_says_them():
    from agrl.core.autopilot import compass_heading_deg, target_instruction_text

    assert compass_heading_deg(0.0) == pytest.approx(90.0)  # +x is east
    assert compass_heading_deg(math.pi / 2) == pytest.approx(0.0)  # +y is north
    assert compass_heading_deg(math.pi) == pytest.approx(270.0)
    flying_east = _level(z=2_000.0, heading=0.0)
    one_row = AircraftState(*(float(field) for field in flying_east))
    # A reversal turns the way the autopilot does: wrap_angle(pi) = -pi, towards smaller psi, to the right.
    assert target_instruction_text(TargetKind.HEADING, math.pi, one_row) == "turn right heading 270"
    assert target_instruction_text(TargetKind.HEADING, math.pi / 2, one_row) == "turn left heading 000"
    assert target_instruction_text(TargetKind.HEADING, -math.pi / 6, one_row) == "turn right heading 120"
    assert target_instruction_text(TargetKind.ALTITUDE, 3_000.0, one_row) == "climb to 3 000 m"
    assert target_instruction_text(TargetKind.ALTITUDE, 500.0, one_row) == "descend to 500 m"
    assert target_instruction_text(TargetKind.SPEED, 100.0, one_row) == "reduce speed to 100 m/s"
    assert target_instruction_text(TargetKind.SPEED, 250.0, one_row) == "increase speed to 250 m/s"
    assert target_instruction_text(TargetKind.HOLD, 0.0, one_row) == "maintain"
