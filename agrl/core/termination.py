"""Episode outcomes: success (equation 2), out of the airspace (equation 1), decision budget.

Pure and batched. Outcome codes are small integers so that they can live in a
TensorDict and be counted cheaply.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import torch

from agrl.core.aircraft import wrap_angle


class Outcome(IntEnum):
    """How a decision step ended. ``RUNNING`` is every non-terminal step."""

    RUNNING = 0
    SUCCESS = 1
    OUT_OF_AIRSPACE = 2
    BUDGET_EXHAUSTED = 3


@dataclass(frozen=True)
class Airspace:
    """Equation 1's box (metres); Table 1 gives the paper's values."""

    x_min: float = -10_000.0
    x_max: float = 10_000.0
    y_min: float = -10_000.0
    y_max: float = 10_000.0
    z_min: float = 0.0
    z_max: float = 5_000.0


@dataclass(frozen=True)
class SuccessTolerance:
    """Equation 2's allowed ranges; the paper gives no values (this project's choice)."""

    distance: float = 1_000.0  # d_e, m (horizontal)
    altitude: float = 200.0  # z_e, m
    heading: float = 0.5235987755982988  # psi_e, rad (30 deg)


def is_success(
    aircraft_x: torch.Tensor,
    aircraft_y: torch.Tensor,
    aircraft_z: torch.Tensor,
    aircraft_heading: torch.Tensor,
    destination_x: torch.Tensor,
    destination_y: torch.Tensor,
    destination_z: torch.Tensor,
    destination_heading: torch.Tensor,
    tolerance: SuccessTolerance,
) -> torch.Tensor:
    """Equation 2: within d_e horizontally, z_e vertically and psi_e in heading."""
    dx = aircraft_x - destination_x
    dy = aircraft_y - destination_y
    close = dx * dx + dy * dy <= tolerance.distance**2
    level = (aircraft_z - destination_z).abs() <= tolerance.altitude
    aligned = wrap_angle(aircraft_heading - destination_heading).abs() <= tolerance.heading
    return close & level & aligned


def is_outside_airspace(
    x: torch.Tensor, y: torch.Tensor, z: torch.Tensor, airspace: Airspace
) -> torch.Tensor:
    """Equation 1's space constraint, violated."""
    return (
        (x < airspace.x_min)
        | (x > airspace.x_max)
        | (y < airspace.y_min)
        | (y > airspace.y_max)
        | (z < airspace.z_min)
        | (z > airspace.z_max)
    )
