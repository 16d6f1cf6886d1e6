"""Aircraft point-mass model: the paper's equation 3 and the seven maneuvers.

All functions are pure and batched: every argument is a tensor of any (common,
broadcastable) shape, angles are in radians, lengths in metres, speeds in m/s.

The aircraft state is the tuple (x, y, z, v, theta, psi, phi):
position, speed, flight-path angle, heading and bank angle. Heading follows
equation 3's convention: ``psi = 0`` flies along +x and ``psi`` grows towards +y.
With that convention a positive bank makes ``psi`` decrease (equation 3's sign).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import torch

#: Standard gravity (m/s^2): a physical constant, not a choice, so it is not in ``conf/``.
GRAVITY = 9.81

#: Index of each field in an ``aircraft_state`` tensor ``(..., 7)``.
AIRCRAFT_FIELDS = ("x", "y", "z", "speed", "flight_path_angle", "heading", "bank")

#: The paper's seven maneuvers, in action-index order (section 3.1).
MANEUVER_NAMES = (
    "steady_flight",
    "left_turn",
    "right_turn",
    "accelerate",
    "decelerate",
    "pull_up",
    "push_over",
)


class AircraftState(NamedTuple):
    """Unpacked aircraft state; each field has the batch shape."""

    x: torch.Tensor
    y: torch.Tensor
    z: torch.Tensor
    speed: torch.Tensor
    flight_path_angle: torch.Tensor
    heading: torch.Tensor
    bank: torch.Tensor

    @classmethod
    def from_tensor(cls, state: torch.Tensor) -> AircraftState:
        return cls(*state.unbind(-1))

    def to_tensor(self) -> torch.Tensor:
        return torch.stack(tuple(self), dim=-1)


@dataclass(frozen=True)
class AircraftLimits:
    """Performance limits (Table 1's speeds plus this project's flight-path limit: ``conf/simulation/paper.yaml``)."""

    min_speed: float  # m/s
    max_speed: float  # m/s
    max_flight_path_angle_deg: float  # degrees (the radians the simulator clamps to: :attr:`max_flight_path_angle`)

    @property
    def max_flight_path_angle(self) -> float:
        """The flight-path angle limit in radians (``math.radians(max_flight_path_angle_deg)``)."""
        return math.radians(self.max_flight_path_angle_deg)


class ManeuverControls(NamedTuple):
    """Per-action control law, one row per maneuver (tensors of shape ``(7,)``).

    - ``axial_excess``: n_x - sin(theta), in g. 0 holds speed; > 0 accelerates.
    - ``normal_load``: n_z in g, or NaN for "balanced" (n_z = cos(theta), which
      with zero bank holds the flight-path angle).
    - ``turn_direction``: -1 left, +1 right, 0 wings level. In a turn the bank is
      chosen so that the flight-path angle is held at load factor ``normal_load``
      (a coordinated max-load-factor turn): cos(phi) = cos(theta) / n_z.
    """

    axial_excess: torch.Tensor
    normal_load: torch.Tensor
    turn_direction: torch.Tensor


def maneuver_table(
    turn_load_factor: float,
    pull_up_load_factor: float,
    push_over_load_factor: float,
    acceleration_load_factor: float,
    deceleration_load_factor: float,
    device: torch.device | str | None = None,
    dtype: torch.dtype = torch.float32,
) -> ManeuverControls:
    """Build the seven-row control table in :data:`MANEUVER_NAMES` order.

    ``acceleration_load_factor`` and ``deceleration_load_factor`` are the axial
    load factor in excess of what holds speed (g); the others are n_z (g).
    """
    nan = float("nan")
    rows = {
        # name: (axial_excess, normal_load, turn_direction)
        "steady_flight": (0.0, nan, 0.0),
        "left_turn": (0.0, turn_load_factor, -1.0),
        "right_turn": (0.0, turn_load_factor, 1.0),
        "accelerate": (acceleration_load_factor, nan, 0.0),
        "decelerate": (-deceleration_load_factor, nan, 0.0),
        "pull_up": (0.0, pull_up_load_factor, 0.0),
        "push_over": (0.0, push_over_load_factor, 0.0),
    }
    table = torch.tensor([rows[name] for name in MANEUVER_NAMES], device=device, dtype=dtype)
    return ManeuverControls(table[:, 0].contiguous(), table[:, 1].contiguous(), table[:, 2].contiguous())


class ManeuverLoads(NamedTuple):
    """One maneuver's control law at the current flight-path angle: load factors and bank."""

    axial_load: torch.Tensor  # n_x, g
    normal_load: torch.Tensor  # n_z, g
    bank: torch.Tensor  # phi, rad
    cos_bank: torch.Tensor  # cos(phi)
    sin_bank: torch.Tensor  # sin(phi)


def load_factors_and_bank(
    flight_path_angle: torch.Tensor,
    axial_excess: torch.Tensor,
    normal_load: torch.Tensor,
    turn_direction: torch.Tensor,
) -> ManeuverLoads:
    """Map one maneuver's control law to (n_x, n_z, phi) at the current flight-path angle.

    A coordinated turn banks so that the vertical lift component balances gravity's:
    n_z cos(phi) = cos(theta). So cos(phi) = cos(theta) / n_z and sin(phi) = +-sqrt(1 - cos^2(phi))
    without evaluating trigonometric functions of phi (they are most of a step's cost otherwise);
    phi itself is only needed where the state is reported.
    """
    cos_theta = torch.cos(flight_path_angle)
    axial_load = torch.sin(flight_path_angle) + axial_excess
    normal = torch.where(torch.isnan(normal_load), cos_theta, normal_load)
    turn_cos_bank = (cos_theta / normal).clamp(-1.0, 1.0)
    # Wings-level rows have turn_direction 0: phi = 0, so cos(phi) = 1 and sin(phi) = 0.
    cos_bank = torch.where(turn_direction == 0, 1.0, turn_cos_bank)
    sin_bank = turn_direction * torch.sqrt(1.0 - turn_cos_bank * turn_cos_bank)
    bank = turn_direction * torch.acos(turn_cos_bank)
    return ManeuverLoads(axial_load, normal, bank, cos_bank, sin_bank)


def point_mass_derivatives(
    speed: torch.Tensor,
    flight_path_angle: torch.Tensor,
    heading: torch.Tensor,
    cos_bank: torch.Tensor,
    sin_bank: torch.Tensor,
    axial_load: torch.Tensor,
    normal_load: torch.Tensor,
    gravity: float = GRAVITY,
) -> tuple[torch.Tensor, ...]:
    """Equation 3: time derivatives (x', y', z', v', theta', psi') of the point-mass aircraft.

    The bank angle phi enters equation 3 only through cos(phi) and sin(phi), which are passed as such.
    """
    cos_theta = torch.cos(flight_path_angle)
    sin_theta = torch.sin(flight_path_angle)
    x_rate = speed * cos_theta * torch.cos(heading)
    y_rate = speed * cos_theta * torch.sin(heading)
    z_rate = speed * sin_theta
    speed_rate = gravity * (axial_load - sin_theta)
    flight_path_rate = gravity / speed * (normal_load * cos_bank - cos_theta)
    heading_rate = -gravity / (speed * cos_theta) * normal_load * sin_bank
    return x_rate, y_rate, z_rate, speed_rate, flight_path_rate, heading_rate


def integrate_aircraft(
    state: AircraftState,
    axial_excess: torch.Tensor,
    normal_load: torch.Tensor,
    turn_direction: torch.Tensor,
    dt: float | torch.Tensor,
    limits: AircraftLimits,
    gravity: float = GRAVITY,
) -> AircraftState:
    """Advance equation 3 by one simulation step ``dt`` under one maneuver's control law
    (:func:`load_factors_and_bank`, then :func:`integrate_loads`)."""
    loads = load_factors_and_bank(state.flight_path_angle, axial_excess, normal_load, turn_direction)
    return integrate_loads(state, loads, dt, limits, gravity)


def integrate_loads(
    state: AircraftState,
    loads: ManeuverLoads,
    dt: float | torch.Tensor,
    limits: AircraftLimits,
    gravity: float = GRAVITY,
) -> AircraftState:
    """Advance equation 3 by one simulation step ``dt`` (semi-implicit Euler) at the given load factors and bank.

    Speed, flight-path angle and heading are updated first and the position is
    then moved with the updated values. This costs the same as explicit Euler
    but keeps a constant-rate turn on a closed circle instead of spiralling out.
    Speed and flight-path angle are clamped to the performance limits. The bank
    angle is the commanded one (the paper's discrete action model commands it; so does the autopilot,
    :mod:`agrl.core.autopilot`).
    Heading is left unwrapped: callers wrap it where they compare angles. ``dt`` may be a per-row tensor: a row
    with ``dt = 0`` keeps its state exactly (the simulator freezes finished rows so), except the bank.
    """
    _, _, _, speed_rate, flight_path_rate, heading_rate = point_mass_derivatives(
        state.speed, state.flight_path_angle, state.heading, loads.cos_bank, loads.sin_bank, loads.axial_load,
        loads.normal_load, gravity,
    )
    speed = (state.speed + speed_rate * dt).clamp(limits.min_speed, limits.max_speed)
    flight_path_angle = (state.flight_path_angle + flight_path_rate * dt).clamp(
        -limits.max_flight_path_angle, limits.max_flight_path_angle
    )
    heading = state.heading + heading_rate * dt
    horizontal_speed = speed * torch.cos(flight_path_angle)
    return AircraftState(
        x=state.x + horizontal_speed * torch.cos(heading) * dt,
        y=state.y + horizontal_speed * torch.sin(heading) * dt,
        z=state.z + speed * torch.sin(flight_path_angle) * dt,
        speed=speed,
        flight_path_angle=flight_path_angle,
        heading=heading,
        bank=loads.bank,
    )


def wrap_angle(angle: torch.Tensor) -> torch.Tensor:
    """Wrap angles to [-pi, pi)."""
    return torch.remainder(angle + torch.pi, 2 * torch.pi) - torch.pi
