"""Physics checks of the point-mass aircraft (equation 3) and the seven maneuvers.

Expected values are computed independently (``math`` / closed-form kinematics),
never copied from a run of the code under test.
"""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch

from agrl.core.aircraft import (
    GRAVITY,
    MANEUVER_NAMES,
    AircraftState,
    integrate_aircraft,
    load_factors_and_bank,
    maneuver_table,
    point_mass_derivatives,
    wrap_angle,
)
from agrl.core.simulation import DecisionSimulator
from agrl.core.termination import Airspace, Outcome

F64 = torch.float64
ACTION = {name: index for index, name in enumerate(MANEUVER_NAMES)}
# A large airspace so that long straight flights never reach a wall.
BIG_AIRSPACE = Airspace(x_min=-1e6, x_max=1e6, y_min=-1e6, y_max=1e6, z_min=-1e6, z_max=1e6)


@pytest.fixture(scope="module")
def load_factors(paper_parameters):
    return paper_parameters.maneuvers


@pytest.fixture(scope="module")
def limits(paper_parameters):
    return paper_parameters.simulation.limits


@pytest.fixture(scope="module")
def table(load_factors):
    """The maneuvers' control law in float64."""
    lf = load_factors
    return maneuver_table(lf.turn, lf.pull_up, lf.push_over, lf.acceleration, lf.deceleration, dtype=F64)


@pytest.fixture
def simulator(paper_parameters, table) -> DecisionSimulator:
    """conf's simulation in :data:`BIG_AIRSPACE`, float64 controls, eager."""
    return DecisionSimulator(dataclasses.replace(paper_parameters.simulation, airspace=BIG_AIRSPACE), table,
                             compile=False)


def fly(simulator, aircraft, actions, decisions):
    """Fly ``decisions`` decisions; return the list of states (including the start) and the outcomes."""
    count = aircraft.shape[0]
    # Destination far below every aircraft: never a success.
    destination = torch.tensor([0.0, 0.0, -5e5, 0.0], dtype=F64).expand(count, 4).clone()
    zeros = torch.zeros(count, dtype=F64)
    states, outcomes = [aircraft], []
    for _ in range(decisions):
        result = simulator(states[-1], destination, zeros, zeros, actions)
        states.append(result.aircraft_state)
        outcomes.append(result.outcome)
    return states, torch.stack(outcomes)


def state(x, y, z, v, theta, psi, phi=0.0):
    return [x, y, z, v, theta, psi, phi]


def test_maneuver_table_rows():
    table = maneuver_table(2.5, 3.0, -0.5, 0.2, 0.4)
    assert table.axial_excess.tolist() == pytest.approx([0, 0, 0, 0.2, -0.4, 0, 0])
    normal = table.normal_load
    assert torch.isnan(normal[[0, 3, 4]]).all()  # balanced rows
    assert normal[[1, 2, 5, 6]].tolist() == pytest.approx([2.5, 2.5, 3.0, -0.5])
    assert table.turn_direction.tolist() == [0, -1, 1, 0, 0, 0, 0]


def test_point_mass_derivatives_match_equation_3():
    generator = torch.Generator().manual_seed(1)
    count = 32
    v = 100 + 150 * torch.rand(count, generator=generator, dtype=F64)
    theta = (torch.rand(count, generator=generator, dtype=F64) - 0.5) * 1.2
    psi = (torch.rand(count, generator=generator, dtype=F64) - 0.5) * 2 * math.pi
    phi = (torch.rand(count, generator=generator, dtype=F64) - 0.5) * 2.0
    n_x = (torch.rand(count, generator=generator, dtype=F64) - 0.5) * 2.0
    n_z = torch.rand(count, generator=generator, dtype=F64) * 4.0 - 1.0
    got = torch.stack(point_mass_derivatives(v, theta, psi, torch.cos(phi), torch.sin(phi), n_x, n_z), dim=-1)
    g = GRAVITY
    for i in range(count):
        vi, th, ps, ph, nx, nz = (float(t[i]) for t in (v, theta, psi, phi, n_x, n_z))
        expected = [
            vi * math.cos(th) * math.cos(ps),
            vi * math.cos(th) * math.sin(ps),
            vi * math.sin(th),
            g * (nx - math.sin(th)),
            g / vi * (nz * math.cos(ph) - math.cos(th)),
            -g / (vi * math.cos(th)) * nz * math.sin(ph),
        ]
        assert got[i].tolist() == pytest.approx(expected, rel=1e-9, abs=1e-9)


def test_bank_cosine_and_sine_are_those_of_the_bank(table):
    # The control law gives cos(phi) and sin(phi) without trigonometry; they must be those of phi itself.
    theta = torch.linspace(-0.5, 0.5, 41, dtype=F64)
    for action in range(len(MANEUVER_NAMES)):
        loads = load_factors_and_bank(theta, table.axial_excess[action], table.normal_load[action],
                                      table.turn_direction[action])
        torch.testing.assert_close(loads.cos_bank, torch.cos(loads.bank), rtol=0, atol=1e-12)
        torch.testing.assert_close(loads.sin_bank, torch.sin(loads.bank), rtol=0, atol=1e-12)
        turning = bool(table.turn_direction[action] != 0)
        # A coordinated turn balances gravity's vertical component: n_z cos(phi) = cos(theta).
        if turning:
            torch.testing.assert_close(loads.normal_load * loads.cos_bank, torch.cos(theta), rtol=0, atol=1e-12)
            assert torch.all(loads.bank * table.turn_direction[action] > 0)
        else:
            assert torch.all(loads.bank == 0)


@pytest.mark.parametrize("maneuver", ["steady_flight", "accelerate", "decelerate"])
def test_wings_level_maneuvers_hold_flight_path_angle(maneuver, table, limits):
    # The balanced normal load n_z = cos(theta) makes theta' = 0 exactly at zero bank.
    theta = torch.tensor([-0.3, 0.0, 0.25], dtype=F64)
    aircraft = AircraftState(
        *(torch.tensor(v, dtype=F64).expand(3) for v in (0.0, 0.0, 1000.0, 180.0)),
        flight_path_angle=theta,
        heading=torch.zeros(3, dtype=F64),
        bank=torch.full((3,), 0.4, dtype=F64),
    )
    a = ACTION[maneuver]
    moved = integrate_aircraft(
        aircraft, table.axial_excess[a], table.normal_load[a], table.turn_direction[a], 0.02, limits
    )
    torch.testing.assert_close(moved.flight_path_angle, theta, rtol=0, atol=1e-12)
    assert torch.all(moved.bank == 0)


def test_steady_flight_holds_altitude_speed_heading_and_flight_path_angle(simulator):
    start = torch.tensor(
        [
            state(-5_000.0, 2_000.0, 2_000.0, 150.0, 0.0, 0.7),  # level
            state(3_000.0, -1_000.0, 500.0, 220.0, 0.2, -2.0),  # climbing
            state(0.0, 0.0, 4_500.0, 120.0, -0.15, 3.0),  # descending
        ],
        dtype=F64,
    )
    decisions = 20  # 60 s, 3000 integration steps
    states, outcomes = fly(simulator, start, torch.zeros(3, dtype=torch.int64), decisions)
    assert torch.all(outcomes == Outcome.RUNNING)
    elapsed = decisions * 3.0
    end = states[-1]
    v, theta, psi = start[:, 3], start[:, 4], start[:, 5]
    expected_x = start[:, 0] + v * torch.cos(theta) * torch.cos(psi) * elapsed
    expected_y = start[:, 1] + v * torch.cos(theta) * torch.sin(psi) * elapsed
    expected_z = start[:, 2] + v * torch.sin(theta) * elapsed
    torch.testing.assert_close(end[:, 0], expected_x, rtol=0, atol=1e-6)
    torch.testing.assert_close(end[:, 1], expected_y, rtol=0, atol=1e-6)
    torch.testing.assert_close(end[:, 2], expected_z, rtol=0, atol=1e-6)
    for s in states:
        torch.testing.assert_close(s[:, 3], v, rtol=0, atol=1e-9)  # speed
        torch.testing.assert_close(s[:, 4], theta, rtol=0, atol=1e-9)  # flight-path angle
        torch.testing.assert_close(s[:, 5], psi, rtol=0, atol=1e-9)  # heading
    # Level flight keeps its altitude exactly (to rounding) at every decision.
    assert max(abs(float(s[0, 2]) - 2_000.0) for s in states) < 1e-6


def fit_circle(x: torch.Tensor, y: torch.Tensor) -> tuple[float, float, float]:
    """Algebraic least-squares circle fit: x^2 + y^2 + D x + E y + F = 0."""
    a = torch.stack((x, y, torch.ones_like(x)), dim=-1)
    b = -(x * x + y * y)
    d, e, f = torch.linalg.lstsq(a, b.unsqueeze(-1)).solution.squeeze(-1).tolist()
    cx, cy = -d / 2, -e / 2
    return cx, cy, math.sqrt(cx * cx + cy * cy - f)


@pytest.mark.parametrize("maneuver,side", [("left_turn", 1.0), ("right_turn", -1.0)])
def test_level_max_load_factor_turn_radius(maneuver, side, simulator, load_factors):
    n = load_factors.turn
    v, g = 200.0, GRAVITY
    phi = math.acos(1.0 / n)
    radius = v * v / (g * math.tan(phi))
    turn_rate = v / radius
    period = 2 * math.pi / turn_rate
    decisions = math.ceil(period / 3.0) + 1  # a little more than one full turn
    x0, y0, z0 = -1_000.0, 500.0, 2_500.0
    start = torch.tensor([state(x0, y0, z0, v, 0.0, 0.0)], dtype=F64)
    states, outcomes = fly(simulator, start, torch.tensor([ACTION[maneuver]]), decisions)
    assert torch.all(outcomes == Outcome.RUNNING)
    track = torch.stack(states)[:, 0]  # (decisions + 1, 7)

    cx, cy, fitted = fit_circle(track[:, 0], track[:, 1])
    assert abs(fitted - radius) / radius < 0.01
    distances = torch.hypot(track[:, 0] - cx, track[:, 1] - cy)
    assert float((distances - radius).abs().max()) / radius < 0.01
    # Heading +x at the start: a left turn circles around a centre on the +y side, a right turn on -y.
    assert abs(cx - x0) / radius < 0.01
    assert abs(cy - (y0 + side * radius)) / radius < 0.01

    # Level turn: altitude, speed and flight-path angle held; bank = -/+ phi (equation 3's sign).
    torch.testing.assert_close(track[:, 2], torch.full_like(track[:, 2], z0), rtol=0, atol=1e-6)
    torch.testing.assert_close(track[:, 3], torch.full_like(track[:, 3], v), rtol=0, atol=1e-9)
    torch.testing.assert_close(track[:, 4], torch.zeros_like(track[:, 4]), rtol=0, atol=1e-9)
    assert float(track[-1, 6]) == pytest.approx(side * -phi, rel=1e-9)
    # Heading changes by the turn rate each decision: a left turn makes psi grow.
    heading_steps = wrap_angle(track[1:, 5] - track[:-1, 5])
    torch.testing.assert_close(
        heading_steps, torch.full_like(heading_steps, side * turn_rate * 3.0), rtol=1e-6, atol=0
    )


def test_left_turn_turns_towards_plus_y(table, limits):
    # psi = 0 flies along +x; a left turn must swing the nose towards +y (psi increasing).
    one = torch.ones(1, dtype=F64)
    aircraft = AircraftState(0 * one, 0 * one, 1000 * one, 200 * one, 0 * one, 0 * one, 0 * one)
    for name, sign in (("left_turn", 1.0), ("right_turn", -1.0)):
        a = ACTION[name]
        moved = aircraft
        for _ in range(50):
            moved = integrate_aircraft(
                moved, table.axial_excess[a], table.normal_load[a], table.turn_direction[a], 0.02, limits
            )
        assert sign * float(moved.heading) > 0
        assert sign * float(moved.y) > 0
        assert sign * float(moved.bank) < 0  # positive bank makes psi decrease (equation 3)


def test_climbing_turn_holds_flight_path_angle(simulator, load_factors):
    start = torch.tensor([state(0.0, 0.0, 1_000.0, 200.0, 0.2, 0.0)] * 2, dtype=F64)
    actions = torch.tensor([ACTION["left_turn"], ACTION["right_turn"]])
    states, _ = fly(simulator, start, actions, 4)
    for s in states:
        torch.testing.assert_close(s[:, 4], torch.full((2,), 0.2, dtype=F64), rtol=0, atol=1e-9)
    # The coordinated bank satisfies n cos(phi) = cos(theta).
    expected_bank = math.acos(math.cos(0.2) / load_factors.turn)
    assert states[-1][:, 6].tolist() == pytest.approx([-expected_bank, expected_bank], rel=1e-9)


@pytest.mark.parametrize("maneuver", ["pull_up", "push_over"])
def test_pull_up_and_push_over_flight_path_rate(maneuver, load_factors, table, limits):
    load = getattr(load_factors, maneuver)
    generator = torch.Generator().manual_seed(7)
    count = 16
    v = 100 + 150 * torch.rand(count, generator=generator, dtype=F64)
    theta = (torch.rand(count, generator=generator, dtype=F64) - 0.5) * 0.8
    zeros = torch.zeros(count, dtype=F64)
    aircraft = AircraftState(zeros, zeros, zeros + 1000, v, theta, zeros, zeros)
    a = ACTION[maneuver]
    dt = 0.02
    moved = integrate_aircraft(
        aircraft, table.axial_excess[a], table.normal_load[a], table.turn_direction[a], dt, limits
    )
    for i in range(count):
        vi, th = float(v[i]), float(theta[i])
        # Wings level (phi = 0): theta' = g / v (n_z cos(phi) - cos(theta)).
        rate = GRAVITY / vi * (load * math.cos(0.0) - math.cos(th))
        assert float(moved.flight_path_angle[i]) - th == pytest.approx(rate * dt, rel=1e-9)
        assert float(moved.speed[i]) == pytest.approx(vi, rel=1e-12)  # axial excess 0 holds speed
        assert float(moved.bank[i]) == 0.0


@pytest.mark.parametrize("theta", [0.0, 0.2])
def test_accelerate_and_decelerate_rates(theta, simulator, load_factors):
    start = torch.tensor([state(0.0, 0.0, 1_000.0, 150.0, theta, 0.0)] * 2, dtype=F64)
    actions = torch.tensor([ACTION["accelerate"], ACTION["decelerate"]])
    states, _ = fly(simulator, start, actions, 1)
    delta = GRAVITY * 3.0  # per g of excess over one 3 s decision
    expected = [150.0 + load_factors.acceleration * delta, 150.0 - load_factors.deceleration * delta]
    assert states[-1][:, 3].tolist() == pytest.approx(expected, rel=1e-9)
    assert states[-1][:, 4].tolist() == pytest.approx([theta, theta], abs=1e-9)
    # Distance flown: the documented semi-implicit scheme moves with the updated speed,
    # sum_{k=1..N} (v0 + a k dt) dt; it differs from the exact v0 T + a T^2 / 2 by a T dt / 2.
    dt, steps = 0.02, 150
    for row, excess in enumerate((load_factors.acceleration, -load_factors.deceleration)):
        a = GRAVITY * excess
        path = sum((150.0 + a * k * dt) * dt for k in range(1, steps + 1))
        exact = 150.0 * 3.0 + a * 3.0**2 / 2
        assert path == pytest.approx(exact + a * 3.0 * dt / 2, abs=1e-9)
        flown = float(states[-1][row, 0]) / math.cos(theta)
        assert flown == pytest.approx(path, abs=1e-6)


def test_speed_clamps_at_limits(simulator, limits):
    start = torch.tensor(
        [state(0.0, 0.0, 1_000.0, 245.0, 0.0, 0.0), state(0.0, 0.0, 1_000.0, 104.0, 0.0, 0.0)], dtype=F64
    )
    actions = torch.tensor([ACTION["accelerate"], ACTION["decelerate"]])
    states, _ = fly(simulator, start, actions, 3)
    for s in states[1:]:
        assert s[:, 3].tolist() == [limits.max_speed, limits.min_speed]


def test_flight_path_angle_clamps_at_limit(simulator, limits):
    start = torch.tensor(
        [state(0.0, 0.0, 500.0, 200.0, 0.0, 0.0), state(0.0, 0.0, 4_500.0, 200.0, 0.0, 0.0)], dtype=F64
    )
    actions = torch.tensor([ACTION["pull_up"], ACTION["push_over"]])
    states, _ = fly(simulator, start, actions, 6)
    limit = limits.max_flight_path_angle
    thetas = torch.stack([s[:, 4] for s in states])
    assert float(thetas.abs().max()) <= limit
    # Without the clamp theta' >= g / (2 v) would pass 30 deg within about 11 s.
    assert thetas[-1].tolist() == [limit, -limit]
    assert thetas[-2].tolist() == [limit, -limit]
    assert torch.all(torch.diff(torch.stack([s[:, 2] for s in states])[:, 0]) > 0)  # climbing
    assert torch.all(torch.diff(torch.stack([s[:, 2] for s in states])[:, 1]) < 0)  # descending


def test_wrap_angle_range_and_equivalence():
    angles = torch.linspace(-20.0, 20.0, 1001, dtype=F64)
    wrapped = wrap_angle(angles)
    assert float(wrapped.min()) >= -math.pi
    assert float(wrapped.max()) < math.pi
    turns = (angles - wrapped) / (2 * math.pi)
    torch.testing.assert_close(turns, turns.round(), rtol=0, atol=1e-9)
