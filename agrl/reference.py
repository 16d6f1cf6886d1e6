"""A pure-Python, single-environment reference of one decision step (``math`` and floats, no torch).

It implements the same equations, in the same order, as :mod:`agrl.core`
(:class:`agrl.core.simulation.DecisionSimulator`):

- the seven maneuvers' control law (:func:`agrl.core.aircraft.load_factors_and_bank`);
- equation 3 with the same semi-implicit Euler step and clamps
  (:func:`agrl.core.aircraft.integrate_aircraft`);
- the destination's exact-arc unicycle motion with wall reflection
  (:func:`agrl.core.destinations.move_destination`);
- success (equation 2) and leaving the airspace (equation 1) after every
  integration step; the decision stops at the first terminal integration step.

Two uses: ``tests/test_reference.py`` checks that the batched torch simulator
computes the same numbers, and ``python -m agrl.bench`` times it as the scalar
baseline the batched simulator is compared with.
"""

from __future__ import annotations

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


def _clamp(value: float, low: float, high: float) -> float:
    return low if value < low else high if value > high else value


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
    ``maneuvers`` (built from ``conf/``, e.g. by :func:`agrl.config.guidance_parameters`)."""
    axial_excess, normal_command, turn_direction = maneuver_rows(maneuvers)[action]
    dt, gravity, limits = params.integration_step, params.gravity, params.limits
    space, tolerance = params.airspace, params.tolerance
    x, y, z, v, theta, psi, phi = (float(value) for value in aircraft)
    dx_, dy_, dz_, dpsi = (float(value) for value in destination)
    half_turn = 0.5 * destination_turn_rate * dt
    # torch.sinc(t / pi) = sin(t) / t, and 1 at t = 0: the chord of the arc flown in dt.
    chord = destination_speed * dt * (math.sin(half_turn) / half_turn if half_turn != 0.0 else 1.0)
    outcome, steps = Outcome.RUNNING, 0

    for _ in range(params.substeps):
        steps += 1
        # ---- maneuver law: (n_x, n_z, phi) at the current flight-path angle
        cos_theta, sin_theta = math.cos(theta), math.sin(theta)
        axial_load = sin_theta + axial_excess
        normal = cos_theta if normal_command is None else normal_command
        ratio = cos_theta / normal if normal != 0.0 else math.copysign(math.inf, cos_theta)
        phi = turn_direction * math.acos(_clamp(ratio, -1.0, 1.0))
        # ---- equation 3, semi-implicit Euler: rates first, then position with the new v, theta, psi
        speed_rate = gravity * (axial_load - sin_theta)
        theta_rate = gravity / v * (normal * math.cos(phi) - cos_theta)
        psi_rate = -gravity / (v * cos_theta) * normal * math.sin(phi)
        v = _clamp(v + speed_rate * dt, limits.min_speed, limits.max_speed)
        theta = _clamp(theta + theta_rate * dt, -limits.max_flight_path_angle, limits.max_flight_path_angle)
        psi = psi + psi_rate * dt
        horizontal = v * math.cos(theta)
        x += horizontal * math.cos(psi) * dt
        y += horizontal * math.sin(psi) * dt
        z += v * math.sin(theta) * dt
        # ---- destination: exact arc, reflected at the horizontal walls
        mid = dpsi + half_turn
        dx_ += chord * math.cos(mid)
        dy_ += chord * math.sin(mid)
        dpsi += 2 * half_turn
        if dx_ > space.x_max or dx_ < space.x_min:
            dx_ = 2 * space.x_max - dx_ if dx_ > space.x_max else 2 * space.x_min - dx_
            dpsi = math.pi - dpsi
        if dy_ > space.y_max or dy_ < space.y_min:
            dy_ = 2 * space.y_max - dy_ if dy_ > space.y_max else 2 * space.y_min - dy_
            dpsi = -dpsi
        # ---- equation 2 (success), then equation 1 (airspace)
        ex, ey = x - dx_, y - dy_
        if (
            ex * ex + ey * ey <= tolerance.distance**2
            and abs(z - dz_) <= tolerance.altitude
            and abs(wrap_angle(psi - dpsi)) <= tolerance.heading
        ):
            outcome = Outcome.SUCCESS
            break
        if not (space.x_min <= x <= space.x_max and space.y_min <= y <= space.y_max
                and space.z_min <= z <= space.z_max):
            outcome = Outcome.OUT_OF_AIRSPACE
            break

    return ReferenceResult(
        (x, y, z, v, theta, wrap_angle(psi), phi), (dx_, dy_, dz_, wrap_angle(dpsi)), int(outcome), steps
    )
