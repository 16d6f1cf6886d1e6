"""Destination motion models: fixed, uniform, curved and irregular (pure, batched).

A destination state is ``(x, y, z, psi)`` (the paper's section 2.1). Every motion
pattern is the same planar unicycle with a speed (m/s) and a turn rate (rad/s):

- fixed: speed 0;
- uniform: constant speed, turn rate 0 (section 5.3: 10, 20, 50 or 100 m/s);
- curved: constant speed and turn rate ``direction * speed / radius``;
- irregular: speed and turn rate re-drawn at random at decision boundaries
  (:func:`redraw_irregular_motion`); the paper names this as future work.

The destination stays at constant altitude. Where it would cross a horizontal
airspace wall it is reflected back inside (heading mirrored): a destination
that left the sector would end the task for a reason the agent cannot control,
so this project keeps it in (see ``docs/model.md``).
"""

from __future__ import annotations

from typing import NamedTuple

import torch

#: Index of each field in a ``destination_state`` tensor ``(..., 4)``.
DESTINATION_FIELDS = ("x", "y", "z", "heading")


class DestinationState(NamedTuple):
    x: torch.Tensor
    y: torch.Tensor
    z: torch.Tensor
    heading: torch.Tensor

    @classmethod
    def from_tensor(cls, state: torch.Tensor) -> DestinationState:
        return cls(*state.unbind(-1))

    def to_tensor(self) -> torch.Tensor:
        return torch.stack(tuple(self), dim=-1)


def curved_turn_rate(speed: float, radius: float, direction: float = 1.0) -> float:
    """Turn rate (rad/s) of a destination circling at ``speed`` on ``radius``.

    ``direction`` +1 turns towards +psi (counter-clockwise seen from above), -1 the other way.
    """
    if radius <= 0:
        raise ValueError(f"turning radius must be > 0 m, got {radius}")
    return direction * speed / radius


def move_destination(
    state: DestinationState,
    speed: torch.Tensor,
    turn_rate: torch.Tensor,
    dt: float,
    x_bounds: tuple[float, float],
    y_bounds: tuple[float, float],
) -> DestinationState:
    """Advance a unicycle destination by ``dt`` seconds along its exact arc.

    The chord of an arc of angle ``w dt`` has length ``v dt sinc(w dt / 2)`` and the
    direction of the mid-arc heading, so constant-rate motion stays on its circle
    to rounding error whatever ``dt`` is. Walls reflect (see module docstring).
    """
    half_turn = 0.5 * turn_rate * dt
    chord = speed * dt * torch.sinc(half_turn / torch.pi)
    mid_heading = state.heading + half_turn
    x = state.x + chord * torch.cos(mid_heading)
    y = state.y + chord * torch.sin(mid_heading)
    heading = state.heading + 2 * half_turn

    x_low, x_high = x_bounds
    y_low, y_high = y_bounds
    # Mirror the position back inside and the heading about the wall's normal.
    crossed_x = (x > x_high) | (x < x_low)
    x = torch.where(x > x_high, 2 * x_high - x, torch.where(x < x_low, 2 * x_low - x, x))
    heading = torch.where(crossed_x, torch.pi - heading, heading)
    crossed_y = (y > y_high) | (y < y_low)
    y = torch.where(y > y_high, 2 * y_high - y, torch.where(y < y_low, 2 * y_low - y, y))
    heading = torch.where(crossed_y, -heading, heading)
    return DestinationState(x, y, state.z, heading)


def redraw_irregular_motion(
    speed: torch.Tensor,
    turn_rate: torch.Tensor,
    change_probability: float,
    speed_bounds: tuple[float, float],
    max_turn_rate: float,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Irregular maneuvering: at a decision boundary, with ``change_probability``,
    draw a new speed uniformly in ``speed_bounds`` (m/s) and a new turn rate
    uniformly in ``[-max_turn_rate, max_turn_rate]`` (rad/s)."""
    shape, device = speed.shape, speed.device
    change = torch.rand(shape, generator=generator, device=device) < change_probability
    low, high = speed_bounds
    new_speed = low + (high - low) * torch.rand(shape, generator=generator, device=device)
    new_turn_rate = max_turn_rate * (2 * torch.rand(shape, generator=generator, device=device) - 1)
    return torch.where(change, new_speed, speed), torch.where(change, new_turn_rate, turn_rate)
