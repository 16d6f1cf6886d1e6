"""Target-holding flight: held heading, altitude and speed targets, and the autopilot that flies them.

A controller clears an aircraft to a heading, an altitude or a speed, and the aircraft holds each until told
otherwise. Here an autopilot, evaluated at every integration step, flies all three held targets at once through
equation 3 (:func:`agrl.core.aircraft.integrate_loads`), within the load factors the seven maneuvers use. Each of
its three channels asks for a rate proportional to its error and is limited by the aircraft, so a large change is
flown at the limit and the target is captured without overshoot:

- **speed**: the axial load beyond what holds speed, ``(v* - v) / (g tau_v)`` in g, within the acceleration and
  deceleration load factors;
- **altitude**: a vertical speed ``(z* - z) / tau_z``, at most ``sqrt(2 a |z* - z|)`` (what stops in the remaining
  height at the capture's vertical deceleration ``a``) and within the flight-path limit, flown as the flight-path
  angle ``theta* = asin(vertical speed / v)``; the flight-path rate ``(theta* - theta) / tau_theta`` is the vertical
  lift component ``n cos(phi) = cos(theta) + v theta' / g``, kept within the push-over and pull-up load factors;
- **heading**: a heading rate ``wrap(psi* - psi) / tau_psi``, the horizontal lift component
  ``n sin(phi) = -v cos(theta) psi' / g`` (equation 3's sign), kept so that the total load factor ``n`` is at most
  the turn's: the vertical channel is served first, so a turn never costs altitude.

The paper's model has no roll dynamics (its maneuvers command the bank directly), so the autopilot commands the bank
too: ``phi = atan2(n sin(phi), n cos(phi))``. With ``tau_z = 4 tau_theta`` the altitude loop is critically
damped where nothing limits it (small steps follow ``e(t) = e0 (1 + t / (2 tau_theta)) exp(-t / (2 tau_theta))``).

The action set (:func:`target_action_table`): 12 headings 30 degrees apart, an altitude every 500 m inside the
airspace and one low level for a destination on its floor, the minimum, cruise and maximum speeds, and "hold
everything". An action sets one target and keeps the others (:func:`apply_target_action`); an instruction is an
action that changes a target.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple

import torch

from agrl.core.aircraft import GRAVITY, AircraftLimits, AircraftState, ManeuverLoads, integrate_loads, wrap_angle


@dataclass(frozen=True)
class AutopilotParameters:
    """The autopilot's load-factor limits (g; the maneuvers' own, ``conf/simulation/``) and time constants (s)."""

    turn_load_factor: float  # g: the most total load factor (the maneuvers' coordinated turn)
    pull_up_load_factor: float  # g: the most vertical lift component
    push_over_load_factor: float  # g: the least vertical lift component
    acceleration_load_factor: float  # g of axial load beyond what holds speed
    deceleration_load_factor: float  # g
    heading_time_constant: float  # s: tau_psi
    altitude_time_constant: float  # s: tau_z (4 tau_theta: critically damped)
    flight_path_time_constant: float  # s: tau_theta
    speed_time_constant: float  # s: tau_v
    capture_fraction: float  # of the vertical acceleration the load factors allow, planned for a level-off

    def capture_vertical_acceleration(self, gravity: float = GRAVITY) -> float:
        """The vertical deceleration (m/s^2) an altitude capture plans with: ``capture_fraction`` of the least of
        the pull-up's and the push-over's margins from 1 g (the rest absorbs the flight-path loop's lag)."""
        return self.capture_fraction * gravity * min(self.pull_up_load_factor - 1.0, 1.0 - self.push_over_load_factor)

    def __post_init__(self):
        for name in ("heading_time_constant", "altitude_time_constant", "flight_path_time_constant",
                     "speed_time_constant", "turn_load_factor"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}={getattr(self, name)} must be > 0")
        if not 0 < self.capture_fraction <= 1:
            raise ValueError(f"capture_fraction={self.capture_fraction} must be in (0, 1]")
        if not self.push_over_load_factor < 1.0 < self.pull_up_load_factor <= self.turn_load_factor:
            raise ValueError(
                f"the load factors must satisfy push_over < 1 g < pull_up <= turn, got push_over="
                f"{self.push_over_load_factor}, pull_up={self.pull_up_load_factor}, turn={self.turn_load_factor}"
            )


class HeldTargets(NamedTuple):
    """What the aircraft holds: heading (rad, equation 3's convention), altitude (m), speed (m/s); batch shape."""

    heading: torch.Tensor
    altitude: torch.Tensor
    speed: torch.Tensor

    @classmethod
    def of(cls, aircraft: AircraftState) -> HeldTargets:
        """Hold what the aircraft flies now (its heading, altitude and speed)."""
        return cls(aircraft.heading, aircraft.z, aircraft.speed)


def autopilot_loads(
    aircraft: AircraftState,
    targets: HeldTargets,
    limits: AircraftLimits,
    autopilot: AutopilotParameters,
    gravity: float = GRAVITY,
) -> ManeuverLoads:
    """The load factors and bank that fly ``targets`` from ``aircraft`` for the next integration step."""
    speed, flight_path_angle = aircraft.speed, aircraft.flight_path_angle
    cos_theta = torch.cos(flight_path_angle)
    # Speed: axial load beyond what holds speed (n_x = sin(theta) holds it), proportional, limited.
    axial_excess = ((targets.speed - speed) / (gravity * autopilot.speed_time_constant)).clamp(
        -autopilot.deceleration_load_factor, autopilot.acceleration_load_factor)
    # Altitude: a vertical speed, then the flight-path angle that flies it, then the rate that captures it.
    max_climb = speed * math.sin(limits.max_flight_path_angle)
    error = targets.altitude - aircraft.z
    # Slow enough to stop in the remaining height (sqrt(2 a e)): a large change does not overshoot while the
    # flight-path loop is at its load-factor limit.
    capture = autopilot.capture_vertical_acceleration(gravity)
    climb = torch.minimum(torch.minimum(error.abs() / autopilot.altitude_time_constant,
                                        torch.sqrt(2.0 * capture * error.abs())), max_climb)
    vertical_speed = torch.copysign(climb, error)
    wanted_angle = torch.asin((vertical_speed / speed).clamp(-1.0, 1.0))
    flight_path_rate = (wanted_angle - flight_path_angle) / autopilot.flight_path_time_constant
    vertical_load = (cos_theta + speed * flight_path_rate / gravity).clamp(
        autopilot.push_over_load_factor, autopilot.pull_up_load_factor)
    # Heading: the horizontal lift component, within what the turn load factor leaves.
    heading_rate = wrap_angle(targets.heading - aircraft.heading) / autopilot.heading_time_constant
    horizontal_load = -speed * cos_theta * heading_rate / gravity
    room = torch.sqrt((autopilot.turn_load_factor ** 2 - vertical_load * vertical_load).clamp_min(0.0))
    horizontal_load = torch.clamp(horizontal_load, -room, room)
    normal_load = torch.sqrt(vertical_load * vertical_load + horizontal_load * horizontal_load)
    # n = 0 (a 0 g push-over with wings level): any bank; the level one.
    safe = normal_load > 0
    denominator = torch.where(safe, normal_load, 1.0)
    cos_bank = torch.where(safe, vertical_load / denominator, 1.0)
    sin_bank = torch.where(safe, horizontal_load / denominator, 0.0)
    return ManeuverLoads(
        axial_load=torch.sin(flight_path_angle) + axial_excess,
        normal_load=normal_load,
        bank=torch.atan2(horizontal_load, vertical_load),
        cos_bank=cos_bank,
        sin_bank=sin_bank,
    )


def autopilot_step(
    aircraft: AircraftState,
    targets: HeldTargets,
    dt: float | torch.Tensor,
    limits: AircraftLimits,
    autopilot: AutopilotParameters,
    gravity: float = GRAVITY,
) -> AircraftState:
    """One integration step of equation 3 with the autopilot flying ``targets``."""
    return integrate_loads(aircraft, autopilot_loads(aircraft, targets, limits, autopilot, gravity), dt, limits,
                           gravity)


class TargetKind(IntEnum):
    """What a target-holding action sets (:class:`TargetActionTable`'s ``kind``)."""

    HOLD = 0
    HEADING = 1
    ALTITUDE = 2
    SPEED = 3


class TargetActionTable(NamedTuple):
    """One row per action: the kind of target it sets (:class:`TargetKind`) and the value (rad, m or m/s)."""

    kind: torch.Tensor  # (actions,) int64
    value: torch.Tensor  # (actions,)

    def __len__(self) -> int:
        return int(self.kind.shape[0])


def target_action_table(
    altitude_range: tuple[float, float],
    limits: AircraftLimits,
    cruise_speed: float,
    headings: int = 12,
    altitude_step: float = 500.0,
    lowest_altitude: float | None = None,
    dtype: torch.dtype = torch.float32,
) -> TargetActionTable:
    """The target-holding actions: "hold everything" (action 0), ``headings`` headings evenly spaced from
    ``psi = 0``, an altitude every ``altitude_step`` m strictly inside ``altitude_range`` (m) with
    ``lowest_altitude`` (m, inside the range; for a destination on the airspace's floor) below them, and the
    minimum, cruise and maximum speeds (m/s)."""
    low, high = altitude_range
    if not low < high:
        raise ValueError(f"altitude_range={altitude_range} must be (low, high) with low < high")
    if not limits.min_speed <= cruise_speed <= limits.max_speed:
        raise ValueError(f"cruise_speed={cruise_speed} m/s must be within [{limits.min_speed}, {limits.max_speed}]")
    first = math.floor(low / altitude_step) + 1
    altitudes = [step * altitude_step for step in range(first, math.ceil(high / altitude_step))]
    if lowest_altitude is not None:
        if not low < lowest_altitude < (altitudes[0] if altitudes else high):
            raise ValueError(f"lowest_altitude={lowest_altitude} m must be above {low} m and below the other "
                             f"target altitudes ({altitudes[0] if altitudes else high} m)")
        altitudes.insert(0, lowest_altitude)
    rows = [(TargetKind.HOLD, 0.0)]
    rows += [(TargetKind.HEADING, wrap_angle(torch.tensor(2 * math.pi * index / headings)).item())
             for index in range(headings)]
    rows += [(TargetKind.ALTITUDE, altitude) for altitude in altitudes]
    rows += [(TargetKind.SPEED, speed) for speed in (limits.min_speed, cruise_speed, limits.max_speed)]
    return TargetActionTable(torch.tensor([int(kind) for kind, _ in rows]),
                             torch.tensor([value for _, value in rows], dtype=dtype))


def apply_target_action(
    targets: HeldTargets, action: torch.Tensor, table: TargetActionTable
) -> tuple[HeldTargets, torch.Tensor]:
    """The targets after ``action`` (int64, batch shape): it sets one target and keeps the others. Also returns
    whether it is an instruction (it changed a target)."""
    kind, value = table.kind[action], table.value[action].to(targets.heading.dtype)
    heading = torch.where(kind == TargetKind.HEADING, value, targets.heading)
    altitude = torch.where(kind == TargetKind.ALTITUDE, value, targets.altitude)
    speed = torch.where(kind == TargetKind.SPEED, value, targets.speed)
    changed = ((wrap_angle(heading - targets.heading) != 0) | (altitude != targets.altitude)
               | (speed != targets.speed))
    return HeldTargets(heading, altitude, speed), changed


def compass_heading_deg(heading: float) -> float:
    """Equation 3's heading (rad, 0 along +x, growing towards +y) as a controller's heading in degrees
    (0 north, clockwise), with +x east and +y north (this project's choice: the paper names no directions)."""
    return (90.0 - math.degrees(heading)) % 360.0


def target_instruction_text(kind: TargetKind, value: float, aircraft: AircraftState) -> str:
    """What a controller says for a target-holding action given to ``aircraft`` (one row): "turn left heading
    270", "climb to 3 000 m", "reduce speed to 100 m/s", "maintain" (hold everything)."""
    if kind == TargetKind.HEADING:
        # A positive change of psi turns towards +y: left (equation 3's sign; the autopilot takes the shorter way).
        side = "left" if float(wrap_angle(torch.tensor(value - float(aircraft.heading)))) > 0 else "right"
        return f"turn {side} heading {round(compass_heading_deg(value)) % 360:03d}"
    if kind == TargetKind.ALTITUDE:
        verb = "climb" if value > float(aircraft.z) else "descend"
        return f"{verb} to {value:,.0f} m".replace(",", " ")
    if kind == TargetKind.SPEED:
        verb = "increase" if value > float(aircraft.speed) else "reduce"
        return f"{verb} speed to {value:.0f} m/s"
    return "maintain"
