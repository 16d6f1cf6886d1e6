"""The policy's input, computed from the paper's raw state fields (equation 4).

The environment keeps equation 4's fields as separate entries (aircraft state,
destination state, last action). :func:`policy_observation` is the one function
that turns them into the network input, so that the policy-reuse step can
rewrite the destination fields and recompute the input the same way.

The paper allows relative positions (section 5.1). Absolute coordinates train
poorly here (an agent must learn the same geometry at every place in the
airspace), so the destination is described in the aircraft's frame (distance,
bearing, relative altitude and heading) and the aircraft in the destination's
frame (which side of the approach it is on). The aircraft's own position in the
airspace stays in, because walls and floor end an episode.
"""

from __future__ import annotations

import torch

from agrl.core.aircraft import MANEUVER_NAMES, AircraftLimits, wrap_angle
from agrl.core.termination import Airspace

#: Names of the policy-input features, in order.
OBSERVATION_FEATURES = (
    "horizontal_distance",  # / airspace half-width
    "bearing_sin",  # bearing of the destination relative to the aircraft's heading
    "bearing_cos",
    "altitude_difference",  # (z_d - z_a) / airspace height
    "altitude_difference_near",  # tanh((z_d - z_a) / 500 m): resolves the tolerance band near the goal
    "horizontal_distance_near",  # tanh(distance / 2 km)
    "heading_difference_sin",  # psi_d - psi_a
    "heading_difference_cos",
    "along_track",  # aircraft position in the destination's frame / half-width
    "cross_track",
    "speed",  # mapped to [-1, 1] over the speed limits
    "flight_path_angle",  # / max flight-path angle
    "bank",  # / 90 deg
    "altitude",  # mapped to [-1, 1] over the airspace height
    "x",  # mapped to [-1, 1] over the airspace
    "y",
) + tuple(f"last_action_{name}" for name in MANEUVER_NAMES)

OBSERVATION_SIZE = len(OBSERVATION_FEATURES)

# Scales of the "near" features: a few times equation 2's tolerances, so that the
# last approach is resolved finely (the airspace-wide features alone put the whole
# 200 m altitude band into 4 % of their range).
NEAR_ALTITUDE_SCALE = 500.0  # m
NEAR_DISTANCE_SCALE = 2_000.0  # m


def _to_unit_interval(value: torch.Tensor, low: float, high: float) -> torch.Tensor:
    return 2.0 * (value - low) / (high - low) - 1.0


def policy_observation(
    aircraft_state: torch.Tensor,
    destination_state: torch.Tensor,
    last_action: torch.Tensor,
    airspace: Airspace,
    limits: AircraftLimits,
) -> torch.Tensor:
    """Normalised, relative-frame policy input ``(..., OBSERVATION_SIZE)`` from equation 4's fields."""
    x, y, z, speed, flight_path_angle, heading, bank = aircraft_state.unbind(-1)
    dest_x, dest_y, dest_z, dest_heading = destination_state.unbind(-1)
    half_width = 0.5 * max(airspace.x_max - airspace.x_min, airspace.y_max - airspace.y_min)
    height = airspace.z_max - airspace.z_min

    dx, dy = dest_x - x, dest_y - y
    distance = torch.sqrt(dx * dx + dy * dy)
    bearing = wrap_angle(torch.atan2(dy, dx) - heading)
    heading_difference = wrap_angle(dest_heading - heading)
    cos_dest, sin_dest = torch.cos(dest_heading), torch.sin(dest_heading)
    along_track = -(cos_dest * dx + sin_dest * dy)
    cross_track = sin_dest * dx - cos_dest * dy

    features = torch.stack(
        (
            distance / half_width,
            torch.sin(bearing),
            torch.cos(bearing),
            (dest_z - z) / height,
            torch.tanh((dest_z - z) / NEAR_ALTITUDE_SCALE),
            torch.tanh(distance / NEAR_DISTANCE_SCALE),
            torch.sin(heading_difference),
            torch.cos(heading_difference),
            along_track / half_width,
            cross_track / half_width,
            _to_unit_interval(speed, limits.min_speed, limits.max_speed),
            flight_path_angle / limits.max_flight_path_angle,
            bank / (0.5 * torch.pi),
            _to_unit_interval(z, airspace.z_min, airspace.z_max),
            _to_unit_interval(x, airspace.x_min, airspace.x_max),
            _to_unit_interval(y, airspace.y_min, airspace.y_max),
        ),
        dim=-1,
    )
    # One-hot by comparison: the same values as F.one_hot without its range check (a pass over the batch).
    maneuvers = torch.arange(len(MANEUVER_NAMES), device=last_action.device)
    one_hot = (last_action.long().unsqueeze(-1) == maneuvers).to(features.dtype)
    return torch.cat((features, one_hot), dim=-1)
