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
airspace stays in, because walls and floor end an episode. This is the default
(``agent.observation=relative``).

:func:`absolute_observation` is equation 4 itself, normalised: the aircraft's and
the destination's positions and headings in the airspace (``agent.observation=absolute``).
A baseline trained on the fixed destination at the origin then has only ever seen
the destination at (0, 0, 0, 0); the paper's policy reuse queries it in the
predicted destination's frame (:func:`in_destination_frame`, section 5.1), while
pre-training hands Z weights that never learnt to read the destination's fields.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import torch

from agrl.core.aircraft import MANEUVER_NAMES, AircraftLimits, wrap_angle
from agrl.core.termination import Airspace

#: Names of the relative observation's geometric features (:func:`relative_features`), in order.
RELATIVE_FEATURES = (
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
)
#: The maneuver an agent flies, one-hot: what a maneuver agent's input ends with.
LAST_MANEUVER_FEATURES = tuple(f"last_action_{name}" for name in MANEUVER_NAMES)
#: Names of the policy-input features (relative observation, maneuver agent), in order.
OBSERVATION_FEATURES = RELATIVE_FEATURES + LAST_MANEUVER_FEATURES

OBSERVATION_SIZE = len(OBSERVATION_FEATURES)

# Scales of the "near" features: a few times equation 2's tolerances, so that the
# last approach is resolved finely (the airspace-wide features alone put the whole
# 200 m altitude band into 4 % of their range).
NEAR_ALTITUDE_SCALE = 500.0  # m
NEAR_DISTANCE_SCALE = 2_000.0  # m


#: Equation 4's positions and headings as the network sees them with ``agent.observation=absolute``.
ABSOLUTE_FEATURES = (
    "x",  # mapped to [-1, 1] over the airspace
    "y",
    "altitude",  # mapped to [-1, 1] over the airspace height
    "speed",  # mapped to [-1, 1] over the speed limits
    "flight_path_angle",  # / max flight-path angle
    "heading_sin",  # psi_a
    "heading_cos",
    "bank",  # / 90 deg
    "destination_x",  # mapped like the aircraft's
    "destination_y",
    "destination_altitude",
    "destination_heading_sin",  # psi_d
    "destination_heading_cos",
    # The same positions on a fine scale, tanh(x / 2 km), tanh(z / 500 m): on the airspace-wide scale alone the
    # 1 km x 200 m tolerance region near the origin (the fixed destination) is 1-4 % of an input's range.
    "x_near",
    "y_near",
    "altitude_near",
    "destination_x_near",
    "destination_y_near",
    "destination_altitude_near",
)
#: Equation 4's fields as a maneuver agent sees them with ``agent.observation=absolute``.
ABSOLUTE_OBSERVATION_FEATURES = ABSOLUTE_FEATURES + LAST_MANEUVER_FEATURES

def _one_hot(last_action: torch.Tensor, dtype: torch.dtype) -> torch.Tensor:
    """The last maneuver, one-hot by comparison: F.one_hot's values without its range check (a pass over the batch)."""
    maneuvers = torch.arange(len(MANEUVER_NAMES), device=last_action.device)
    return (last_action.long().unsqueeze(-1) == maneuvers).to(dtype)


def _to_unit_interval(value: torch.Tensor, low: float, high: float) -> torch.Tensor:
    return 2.0 * (value - low) / (high - low) - 1.0


def policy_observation(
    aircraft_state: torch.Tensor,
    destination_state: torch.Tensor,
    last_action: torch.Tensor,
    airspace: Airspace,
    limits: AircraftLimits,
) -> torch.Tensor:
    """Normalised, relative-frame policy input ``(..., OBSERVATION_SIZE)`` from equation 4's fields: the
    :func:`relative_features`, then the last maneuver one-hot."""
    features = relative_features(aircraft_state, destination_state, airspace, limits)
    return torch.cat((features, _one_hot(last_action, features.dtype)), dim=-1)


def relative_features(
    aircraft_state: torch.Tensor, destination_state: torch.Tensor, airspace: Airspace, limits: AircraftLimits
) -> torch.Tensor:
    """The destination in the aircraft's frame and the aircraft in the destination's and the airspace's,
    normalised: ``(..., len(RELATIVE_FEATURES))``."""
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

    return torch.stack(
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


def absolute_observation(
    aircraft_state: torch.Tensor,
    destination_state: torch.Tensor,
    last_action: torch.Tensor,
    airspace: Airspace,
    limits: AircraftLimits,
) -> torch.Tensor:
    """Equation 4's state vector ``S_t``, normalised: ``(..., len(ABSOLUTE_OBSERVATION_FEATURES))``.

    Each input is a function of one field of ``S_t``: positions mapped to [-1, 1] over the airspace and again
    on a fine scale (``tanh(x / 2 km)``, ``tanh(z / 500 m)``), headings as sine and cosine. No relative quantity
    is computed, so the network must learn the geometry itself (the paper's input interface). The
    :func:`absolute_features`, then the last maneuver one-hot.
    """
    features = absolute_features(aircraft_state, destination_state, airspace, limits)
    return torch.cat((features, _one_hot(last_action, features.dtype)), dim=-1)


def absolute_features(
    aircraft_state: torch.Tensor, destination_state: torch.Tensor, airspace: Airspace, limits: AircraftLimits
) -> torch.Tensor:
    """Equation 4's positions and headings, normalised: ``(..., len(ABSOLUTE_FEATURES))``."""
    x, y, z, speed, flight_path_angle, heading, bank = aircraft_state.unbind(-1)
    dest_x, dest_y, dest_z, dest_heading = destination_state.unbind(-1)
    return torch.stack(
        (
            _to_unit_interval(x, airspace.x_min, airspace.x_max),
            _to_unit_interval(y, airspace.y_min, airspace.y_max),
            _to_unit_interval(z, airspace.z_min, airspace.z_max),
            _to_unit_interval(speed, limits.min_speed, limits.max_speed),
            flight_path_angle / limits.max_flight_path_angle,
            torch.sin(heading),
            torch.cos(heading),
            bank / (0.5 * torch.pi),
            _to_unit_interval(dest_x, airspace.x_min, airspace.x_max),
            _to_unit_interval(dest_y, airspace.y_min, airspace.y_max),
            _to_unit_interval(dest_z, airspace.z_min, airspace.z_max),
            torch.sin(dest_heading),
            torch.cos(dest_heading),
            torch.tanh(x / NEAR_DISTANCE_SCALE),
            torch.tanh(y / NEAR_DISTANCE_SCALE),
            torch.tanh(z / NEAR_ALTITUDE_SCALE),
            torch.tanh(dest_x / NEAR_DISTANCE_SCALE),
            torch.tanh(dest_y / NEAR_DISTANCE_SCALE),
            torch.tanh(dest_z / NEAR_ALTITUDE_SCALE),
        ),
        dim=-1,
    )


def in_destination_frame(
    aircraft_state: torch.Tensor, destination_state: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The aircraft seen from ``destination_state`` placed at the origin, heading 0 (section 5.1).

    The paper maps the predicted destination to (0, 0, 0, 0), the fixed destination its baseline was trained
    on, and the aircraft to ``(x_a - x_d, y_a - y_d, z_a - z_d, psi_a - psi_d)``. This function also rotates the
    horizontal offset by ``-psi_d`` (this project's choice): with the heading alone shifted, a destination
    heading other than 0 would put the approach on the wrong side. For ``psi_d = 0`` (the uniform destination)
    the two are the same. Returns ``(aircraft_state, destination_state)`` with the destination all zeros.
    """
    x, y, z, speed, flight_path_angle, heading, bank = aircraft_state.unbind(-1)
    dest_x, dest_y, dest_z, dest_heading = destination_state.unbind(-1)
    dx, dy = x - dest_x, y - dest_y
    cos_dest, sin_dest = torch.cos(dest_heading), torch.sin(dest_heading)
    moved = torch.stack(
        (cos_dest * dx + sin_dest * dy, -sin_dest * dx + cos_dest * dy, z - dest_z, speed, flight_path_angle,
         wrap_angle(heading - dest_heading), bank),
        dim=-1,
    )
    return moved, torch.zeros_like(destination_state)


#: What :func:`held_target_features` adds to the policy input for an agent that flies held targets.
HELD_TARGET_FEATURES = ("target_heading_sin", "target_heading_cos", "target_altitude_above", "target_speed_above")


def held_target_features(
    aircraft_state: torch.Tensor, held_targets: torch.Tensor, airspace: Airspace, limits: AircraftLimits
) -> torch.Tensor:
    """The held targets (``(..., 3)``: heading rad, altitude m, speed m/s; :mod:`agrl.core.autopilot`) relative to
    the aircraft, ``(..., 4)``: the sine and cosine of the heading still to turn, the altitude still to climb over
    the airspace's height, the speed still to gain over the speed range. All 0 (cosine 1) when every target is
    reached."""
    _, _, z, speed, _, heading, _ = aircraft_state.unbind(-1)
    target_heading, target_altitude, target_speed = held_targets.unbind(-1)
    turn = wrap_angle(target_heading - heading)
    return torch.stack((
        torch.sin(turn),
        torch.cos(turn),
        (target_altitude - z) / (airspace.z_max - airspace.z_min),
        (target_speed - speed) / (limits.max_speed - limits.min_speed),
    ), dim=-1)


class ObservationKind(NamedTuple):
    """One ``agent.observation``: a maneuver agent's input (``function``, ``features``: the geometry, then the last
    maneuver) and its geometric features alone (``geometry``, ``geometry_features``), which an agent holding targets
    reads before its held targets."""

    function: Callable[..., torch.Tensor]
    features: tuple[str, ...]
    geometry: Callable[..., torch.Tensor]
    geometry_features: tuple[str, ...]


#: ``agent.observation`` -> its functions and feature names.
OBSERVATIONS = {
    "relative": ObservationKind(policy_observation, OBSERVATION_FEATURES, relative_features, RELATIVE_FEATURES),
    "absolute": ObservationKind(absolute_observation, ABSOLUTE_OBSERVATION_FEATURES, absolute_features,
                                ABSOLUTE_FEATURES),
}
#: What a checkpoint written before ``agent.observation`` existed reads (the shipped ``baseline-both-terms`` among
#: them).
LEGACY_OBSERVATION = "relative"


def _observation(kind: str) -> ObservationKind:
    if kind not in OBSERVATIONS:
        raise ValueError(f"observation={kind!r} is not allowed: one of {', '.join(OBSERVATIONS)}")
    return OBSERVATIONS[kind]


def observation_function(kind: str):
    """The function computing observation ``kind``'s policy input from equation 4's fields (a maneuver agent's:
    the geometry, then the last maneuver)."""
    return _observation(kind).function


def target_observation_function(kind: str):
    """The function computing observation ``kind``'s policy input for an agent holding targets:
    ``(aircraft_state, destination_state, held_targets, airspace, limits) -> (..., size)``, the geometric features
    of ``kind``, then :func:`held_target_features` (the held targets take the last maneuver's place)."""
    geometry = _observation(kind).geometry

    def observe(aircraft_state, destination_state, held_targets, airspace, limits):
        return torch.cat((geometry(aircraft_state, destination_state, airspace, limits),
                          held_target_features(aircraft_state, held_targets, airspace, limits)), dim=-1)

    return observe


def observation_features(kind: str, holds_targets: bool = False) -> tuple[str, ...]:
    """The names of observation ``kind``'s features, in order, for a maneuver agent or one holding targets."""
    entry = _observation(kind)
    return entry.geometry_features + HELD_TARGET_FEATURES if holds_targets else entry.features


def observation_size(kind: str, holds_targets: bool = False) -> int:
    """Width of the policy input of observation ``kind`` (relative or absolute), for a maneuver agent or one
    holding targets."""
    return len(observation_features(kind, holds_targets))
