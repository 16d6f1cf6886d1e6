"""Destination motion: uniform, curved (exact arcs), wall reflection, irregular redraws."""

from __future__ import annotations

import math

import pytest
import torch

from agrl.core.aircraft import wrap_angle
from agrl.core.destinations import (
    DestinationState,
    curved_turn_rate,
    move_destination,
    redraw_irregular_motion,
)
from agrl.core.termination import Airspace

# A 20 km x 20 km box, the paper's (Table 1): the wall tests below mirror at x, y = +-10 km.
AIRSPACE = Airspace(x_min=-10_000.0, x_max=10_000.0, y_min=-10_000.0, y_max=10_000.0, z_min=0.0, z_max=5_000.0)
X_BOUNDS = (AIRSPACE.x_min, AIRSPACE.x_max)
Y_BOUNDS = (AIRSPACE.y_min, AIRSPACE.y_max)
DT = 0.02


def destination(x, y, z, heading) -> DestinationState:
    """Columns may be scalars (one destination) or equal-length lists (a batch)."""
    columns = torch.tensor([x, y, z, heading], dtype=torch.float32)
    return DestinationState.from_tensor(columns.reshape(4, -1).T.contiguous())


def advance(state, speed, turn_rate, seconds, x_bounds=X_BOUNDS, y_bounds=Y_BOUNDS, dt=DT):
    steps = round(seconds / dt)
    track = [state]
    for _ in range(steps):
        state = move_destination(state, speed, turn_rate, dt, x_bounds, y_bounds)
        track.append(state)
    return state, track


def test_uniform_destination_moves_speed_times_time():
    heading = 0.6
    start = destination([100.0, 0.0], [-200.0, 0.0], [0.0, 300.0], [heading, -2.5])
    speed = torch.tensor([20.0, 20.0])
    end, _ = advance(start, speed, torch.zeros(2), 30.0)
    for row, psi in enumerate((heading, -2.5)):
        x0, y0 = float(start.x[row]), float(start.y[row])
        assert float(end.x[row]) == pytest.approx(x0 + 600.0 * math.cos(psi), abs=0.05)
        assert float(end.y[row]) == pytest.approx(y0 + 600.0 * math.sin(psi), abs=0.05)
        assert float(end.heading[row]) == pytest.approx(psi, abs=1e-6)
    assert end.z.tolist() == start.z.tolist()  # constant altitude


def test_fixed_destination_does_not_move():
    start = destination(1234.0, -567.0, 89.0, 1.0)
    end, _ = advance(start, torch.zeros(1), torch.zeros(1), 3.0)
    assert end.to_tensor().tolist() == start.to_tensor().tolist()


def test_curved_turn_rate():
    assert curved_turn_rate(20.0, 500.0) == pytest.approx(0.04)
    assert curved_turn_rate(20.0, 500.0, -1.0) == pytest.approx(-0.04)
    with pytest.raises(ValueError, match="radius"):
        curved_turn_rate(20.0, 0.0)


def test_curved_destination_stays_on_its_circle():
    speed = 20.0
    # Both radii, both turn directions, in one batch (300 s of 20 ms steps is 15000 steps).
    cases = [(500.0, 1.0), (5_000.0, 1.0), (500.0, -1.0), (5_000.0, -1.0)]
    count = len(cases)
    start = destination([0.0] * count, [0.0] * count, [0.0] * count, [0.0] * count)
    turn_rate = torch.tensor([curved_turn_rate(speed, r, d) for r, d in cases])
    _, track = advance(start, torch.full((count,), speed), turn_rate, 300.0)
    xs = torch.stack([s.x for s in track]).double()  # (steps + 1, count)
    ys = torch.stack([s.y for s in track]).double()
    for column, (radius, direction) in enumerate(cases):
        # From the origin heading +x the centre is (0, +radius) turning towards +psi, else (0, -radius).
        distance = torch.hypot(xs[:, column], ys[:, column] - direction * radius)
        assert float((distance - radius).abs().max()) / radius < 0.005
        # Travelled the right way round: towards +y for direction +1.
        assert direction * float(ys[-1, column]) > 0
    # The heading grows at the turn rate (300 s; float32 accumulation of 15000 increments).
    headings = torch.stack([s.heading for s in track])
    expected = wrap_angle(turn_rate.double() * 300.0)
    assert wrap_angle(headings[-1].double() - expected).abs().max() < 1e-2
    # And the destination really went round: 300 s at 20 m/s on r = 500 m is ~1.9 turns.
    assert float(xs[:, 0].min()) < -490 and float(xs[:, 0].max()) > 490


@pytest.mark.parametrize(
    "x,y,heading,expected_heading",
    [
        (9_999.0, 0.0, math.radians(30), math.radians(150)),  # +x wall: psi -> pi - psi
        (-9_999.0, 0.0, math.radians(150), math.radians(30)),  # -x wall
        (0.0, 9_999.0, math.radians(60), math.radians(-60)),  # +y wall: psi -> -psi
        (0.0, -9_999.0, math.radians(-120), math.radians(120)),  # -y wall
    ],
)
def test_reflection_at_walls_mirrors_heading(x, y, heading, expected_heading):
    speed = torch.tensor([100.0])
    start = destination(x, y, 0.0, heading)
    moved = move_destination(start, speed, torch.zeros(1), 0.1, X_BOUNDS, Y_BOUNDS)  # 10 m step
    assert AIRSPACE.x_min <= float(moved.x) <= AIRSPACE.x_max
    assert AIRSPACE.y_min <= float(moved.y) <= AIRSPACE.y_max
    assert float(wrap_angle(moved.heading - expected_heading)) == pytest.approx(0.0, abs=1e-6)
    # Mirror image of the unconstrained position.
    free_x = x + 10.0 * math.cos(heading)
    free_y = y + 10.0 * math.sin(heading)
    if abs(x) > 9_000:
        wall = math.copysign(10_000.0, x)
        assert float(moved.x) == pytest.approx(2 * wall - free_x, abs=1e-2)
        assert float(moved.y) == pytest.approx(free_y, abs=1e-2)
    else:
        wall = math.copysign(10_000.0, y)
        assert float(moved.y) == pytest.approx(2 * wall - free_y, abs=1e-2)
        assert float(moved.x) == pytest.approx(free_x, abs=1e-2)


def test_reflection_keeps_destinations_inside_a_small_box():
    generator = torch.Generator().manual_seed(3)
    count = 64
    bounds = (-100.0, 100.0)
    xy = (torch.rand(count, 2, generator=generator) * 2 - 1) * 90
    heading = (torch.rand(count, generator=generator) * 2 - 1) * math.pi
    state = DestinationState(xy[:, 0], xy[:, 1], torch.zeros(count), heading)
    speed = 20 + 80 * torch.rand(count, generator=generator)
    turn_rate = (torch.rand(count, generator=generator) * 2 - 1) * 0.2
    bounces = torch.zeros(count, dtype=torch.bool)
    for _ in range(500):  # 10 s at up to 100 m/s: several bounces in a 200 m box
        before = state.heading
        state = move_destination(state, speed, turn_rate, DT, bounds, bounds)
        assert float(state.x.min()) >= bounds[0] and float(state.x.max()) <= bounds[1]
        assert float(state.y.min()) >= bounds[0] and float(state.y.max()) <= bounds[1]
        bounces |= wrap_angle(state.heading - before).abs() > 0.01
    assert bool(bounces.all())  # every destination hit a wall at least once


def test_redraw_irregular_motion_bounds_and_probability():
    count = 20_000
    speed = torch.full((count,), -1.0)  # sentinel values outside every bound
    turn_rate = torch.full((count,), 9.0)
    generator = torch.Generator().manual_seed(0)
    new_speed, new_turn_rate = redraw_irregular_motion(speed, turn_rate, 0.3, (10.0, 50.0), 0.04, generator)
    changed = new_speed != -1.0
    assert torch.equal(changed, new_turn_rate != 9.0)  # speed and turn rate change together
    assert abs(changed.float().mean().item() - 0.3) < 0.02
    assert float(new_speed[changed].min()) >= 10.0 and float(new_speed[changed].max()) <= 50.0
    assert float(new_turn_rate[changed].abs().max()) <= 0.04
    # Spread over the whole range, not a constant.
    assert float(new_speed[changed].std()) > 5.0 and float(new_turn_rate[changed].std()) > 0.01

    never = redraw_irregular_motion(speed, turn_rate, 0.0, (10.0, 50.0), 0.04, generator)
    assert torch.equal(never[0], speed) and torch.equal(never[1], turn_rate)
    always = redraw_irregular_motion(speed, turn_rate, 1.0, (10.0, 50.0), 0.04, generator)
    assert bool((always[0] >= 10.0).all()) and bool((always[1].abs() <= 0.04).all())


def test_redraw_irregular_motion_is_reproducible_with_a_seeded_generator():
    speed, turn_rate = torch.full((100,), 30.0), torch.zeros(100)

    def draw(seed):
        generator = torch.Generator().manual_seed(seed)
        return [
            redraw_irregular_motion(speed, turn_rate, 0.5, (10.0, 50.0), 0.04, generator) for _ in range(3)
        ]

    first, second, other = draw(42), draw(42), draw(43)
    for (s1, t1), (s2, t2) in zip(first, second, strict=True):
        assert torch.equal(s1, s2) and torch.equal(t1, t2)
    assert not all(torch.equal(s1, s3) for (s1, _), (s3, _) in zip(first, other, strict=True))
