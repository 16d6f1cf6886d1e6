"""A pure-Python, one-row form of one decision step (``math`` and floats, no torch): a deliberate second copy.

It implements the same equations, in the same order, as :mod:`agrl.core`
(:class:`agrl.core.simulation.DecisionSimulator`):

- the seven maneuvers' control law (:func:`agrl.core.aircraft.load_factors_and_bank`);
- equation 3 with the same semi-implicit Euler step and clamps
  (:func:`agrl.core.aircraft.integrate_aircraft`);
- the destination's exact-arc unicycle motion with wall reflection
  (:func:`agrl.core.destinations.move_destination`);
- success (equation 2) and leaving the airspace (equation 1) after every
  integration step; the decision stops at the first terminal integration step.

It is both the test oracle of :mod:`agrl.core` and the engine of the single gymnasium env:

- ``tests/test_reference.py`` checks that the batched torch simulator computes the same numbers
  (equal to rounding in float64);
- :class:`agrl.envs.gym.GuidanceGymEnv` flies every decision with :func:`reference_decision`, because
  the batched simulator at batch 1 is dominated by torch's per-operation cost: one decision took 0.13 ms
  here against 46 ms for the eager :class:`agrl.core.simulation.DecisionSimulator` at batch 1 (about 350x;
  measured once on 2026-12-04 on the shared 2-core development machine under load, the command and the
  observation's and reward's figures in :mod:`agrl.rows`' docstring);
- ``python -m benchmarks.bench`` times it as the scalar baseline the batched simulator is compared with.

With :mod:`agrl.rows` (the one-row observation and reward, beside it) it is the only second copy of the
model; they import only :mod:`agrl.core` (and :mod:`agrl.rows` this module), never the environments.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

from agrl.core.aircraft import MANEUVER_NAMES
from agrl.core.parameters import ManeuverLoadFactors
from agrl.core.simulation import SimulationParameters
from agrl.core.termination import Outcome

Aircraft = tuple[float, float, float, float, float, float, float]  # x, y, z, v, theta, psi, phi
Destination = tuple[float, float, float, float]  # x, y, z, psi


class ReferenceResult(NamedTuple):
    aircraft_state: Aircraft  # heading wrapped to [-pi, pi)
    destination_state: Destination  # heading wrapped
    outcome: int  # Outcome.RUNNING, SUCCESS or OUT_OF_AIRSPACE
    substeps: int  # integration steps simulated (fewer than the decision's when it ended early)


def wrap_angle(angle: float) -> float:
    """To [-pi, pi), as :func:`agrl.core.aircraft.wrap_angle` (Python's % takes the divisor's sign)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


@functools.lru_cache(maxsize=64)
def maneuver_rows(maneuvers: ManeuverLoadFactors) -> tuple[tuple[float, float | None, float], ...]:
    """(axial excess g, normal load g or None for "balanced", turn direction) per action index."""
    rows = {
        "steady_flight": (0.0, None, 0.0),
        "left_turn": (0.0, maneuvers.turn, -1.0),
        "right_turn": (0.0, maneuvers.turn, 1.0),
        "accelerate": (maneuvers.acceleration, None, 0.0),
        "decelerate": (-maneuvers.deceleration, None, 0.0),
        "pull_up": (0.0, maneuvers.pull_up, 0.0),
        "push_over": (0.0, maneuvers.push_over, 0.0),
    }
    return tuple(rows[name] for name in MANEUVER_NAMES)


def reference_decision(
    aircraft: Aircraft,
    destination: Destination,
    destination_speed: float,
    destination_turn_rate: float,
    action: int,
    params: SimulationParameters,
    maneuvers: ManeuverLoadFactors,
) -> ReferenceResult:
    """Advance one aircraft and its destination by one decision (``params.substeps`` integration steps).

    ``params`` and ``maneuvers`` are a :class:`agrl.core.parameters.GuidanceParameters`' ``simulation`` and
    ``maneuvers`` (built from ``conf/``, e.g. by :func:`agrl.config.guidance_parameters`).

    The loop is the scalar baseline of ``python -m benchmarks.bench``, so it does only the work whose result can
    change: a sine or cosine is recomputed only when its angle changed (the bank law's terms vanish exactly
    for unbanked maneuvers, the destination's heading changes only when it turns or is reflected), and a
    destination at rest inside the walls is not moved. Each remaining expression is the one of the plain
    form, in the same order, so the floats are the same.
    """
    axial_excess, normal_command, turn_direction = maneuver_rows(maneuvers)[action]
    dt, gravity, limits = params.integration_step, params.gravity, params.limits
    space, tolerance = params.airspace, params.tolerance
    min_speed, max_speed = limits.min_speed, limits.max_speed
    max_angle = limits.max_flight_path_angle
    min_angle = -max_angle
    x_min, x_max, y_min, y_max = space.x_min, space.x_max, space.y_min, space.y_max
    z_min, z_max = space.z_min, space.z_max
    distance_squared, altitude_tolerance, heading_tolerance = tolerance.distance**2, tolerance.altitude, \
        tolerance.heading
    cos, sin, acos = math.cos, math.sin, math.acos
    x, y, z, v, theta, psi, phi = map(float, aircraft)
    dx_, dy_, dz_, dpsi = map(float, destination)
    half_turn = 0.5 * destination_turn_rate * dt
    # torch.sinc(t / pi) = sin(t) / t, and 1 at t = 0: the chord of the arc flown in dt.
    chord = destination_speed * dt * (math.sin(half_turn) / half_turn if half_turn != 0.0 else 1.0)
    heading_change = 2 * half_turn
    # Unbanked maneuvers fly phi = 0: sin(phi) = 0 leaves psi unchanged and cos(phi) = 1 (balanced flight
    # then also keeps theta). A destination at rest inside the walls stays where it is.
    banked = turn_direction != 0.0
    balanced = normal_command is None
    destination_moves = not (chord == 0.0 and half_turn == 0.0 and x_min <= dx_ <= x_max and y_min <= dy_ <= y_max)
    destination_turns = half_turn != 0.0
    cos_theta, sin_theta = cos(theta), sin(theta)
    cos_psi, sin_psi = cos(psi), sin(psi)
    chord_cos, chord_sin = chord * cos(dpsi), chord * sin(dpsi)  # the straight-line destination's step
    outcome, steps = Outcome.RUNNING, 0

    for steps in range(1, params.substeps + 1):  # noqa: B007 (read after the loop: the steps simulated)
        # ---- maneuver law: (n_x, n_z, phi) at the current flight-path angle
        speed_rate = gravity * ((sin_theta + axial_excess) - sin_theta)
        if banked:
            normal = cos_theta if balanced else normal_command
            ratio = cos_theta / normal if normal != 0.0 else math.copysign(math.inf, cos_theta)
            phi = turn_direction * acos(-1.0 if ratio < -1.0 else 1.0 if ratio > 1.0 else ratio)
            # ---- equation 3, semi-implicit Euler: rates first, then position with the new v, theta, psi
            theta_rate = gravity / v * (normal * cos(phi) - cos_theta)
            psi_rate = -gravity / (v * cos_theta) * normal * sin(phi)
            psi = psi + psi_rate * dt
            cos_psi, sin_psi = cos(psi), sin(psi)
        else:
            phi = 0.0
            theta_rate = 0.0 if balanced else gravity / v * (normal_command - cos_theta)
        v = v + speed_rate * dt
        v = min_speed if v < min_speed else max_speed if v > max_speed else v
        new_theta = theta + theta_rate * dt
        new_theta = min_angle if new_theta < min_angle else max_angle if new_theta > max_angle else new_theta
        if new_theta != theta:
            theta = new_theta
            cos_theta, sin_theta = cos(theta), sin(theta)
        horizontal = v * cos_theta
        x += horizontal * cos_psi * dt
        y += horizontal * sin_psi * dt
        z += v * sin_theta * dt
        # ---- destination: exact arc, reflected at the horizontal walls
        if destination_moves:
            if destination_turns:
                mid = dpsi + half_turn
                dx_ += chord * cos(mid)
                dy_ += chord * sin(mid)
                dpsi += heading_change
            else:
                dx_ += chord_cos
                dy_ += chord_sin
            if dx_ > x_max or dx_ < x_min:
                dx_ = 2 * x_max - dx_ if dx_ > x_max else 2 * x_min - dx_
                dpsi = math.pi - dpsi
                chord_cos, chord_sin = chord * cos(dpsi), chord * sin(dpsi)
            if dy_ > y_max or dy_ < y_min:
                dy_ = 2 * y_max - dy_ if dy_ > y_max else 2 * y_min - dy_
                dpsi = -dpsi
                chord_cos, chord_sin = chord * cos(dpsi), chord * sin(dpsi)
        # ---- equation 2 (success), then equation 1 (airspace)
        ex, ey = x - dx_, y - dy_
        if (
            ex * ex + ey * ey <= distance_squared
            and abs(z - dz_) <= altitude_tolerance
            and abs(wrap_angle(psi - dpsi)) <= heading_tolerance
        ):
            outcome = Outcome.SUCCESS
            break
        if not (x_min <= x <= x_max and y_min <= y <= y_max and z_min <= z <= z_max):
            outcome = Outcome.OUT_OF_AIRSPACE
            break

    return ReferenceResult(
        (x, y, z, v, theta, wrap_angle(psi), phi), (dx_, dy_, dz_, wrap_angle(dpsi)), int(outcome), steps
    )
