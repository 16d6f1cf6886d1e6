"""Episode outcomes: success (equation 2), out of the airspace (equation 1), decision budget.

Pure and batched. Outcome codes are small integers so that they can live in a
TensorDict and be counted cheaply.
"""

from __future__ import annotations

import math
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
    """Equation 1's box (metres); the values (Table 1's) are in ``conf/simulation/paper.yaml``."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    z_min: float
    z_max: float


@dataclass(frozen=True)
class SuccessTolerance:
    """Equation 2's allowed ranges (the paper gives no values: ``conf/simulation/paper.yaml``)."""

    distance: float  # d_e, m (horizontal)
    altitude: float  # z_e, m
    heading_deg: float  # psi_e, degrees (the radians the simulator compares with: :attr:`heading`)

    @property
    def heading(self) -> float:
        """psi_e in radians (``math.radians(heading_deg)``)."""
        return math.radians(self.heading_deg)


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


def decision_outcome(simulated: torch.Tensor, decisions: torch.Tensor, max_decisions: int) -> torch.Tensor:
    """A decision's outcome: the simulator's (``simulated``: success, out of the airspace or running), or the
    budget's end for a row still running after its ``decisions``-th decision of ``max_decisions``."""
    return torch.where((simulated == Outcome.RUNNING) & (decisions >= max_decisions),
                       int(Outcome.BUDGET_EXHAUSTED), simulated)
