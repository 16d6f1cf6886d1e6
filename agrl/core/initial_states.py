"""Initial conditions (the paper's Table 1: random position, theta = psi = phi = 0).

The paper draws the aircraft's start at random in the airspace. A start must be
feasible, so this project trims the box: the aircraft begins heading +x, flies
one whole decision period before it can act and needs about one turn radius to
turn away, so starts near the +x wall would leave the airspace whatever the
agent does. Starts inside a disc around the destination's start are redrawn so
that no episode begins solved. The values live in ``conf/simulation/paper.yaml``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import torch


@dataclass(frozen=True)
class InitialStateDistribution:
    """Uniform box for the aircraft's start (metres), a start speed (m/s), and an exclusion disc."""

    x_range: tuple[float, float]
    y_range: tuple[float, float]
    z_range: tuple[float, float]
    speed_range: tuple[float, float]
    min_horizontal_distance: float  # m from the destination's start


def scale_distribution(
    distribution: InitialStateDistribution,
    scale: float,
    destination_start: tuple[float, float, float],
    success_distance: float,
) -> InitialStateDistribution:
    """Shrink the start box towards the destination's start by ``scale`` in (0, 1] (a reverse curriculum).

    Horizontal ranges shrink about the destination; the altitude range keeps its
    lower bound and shrinks its height. The exclusion disc shrinks too, but never
    below ``success_distance`` (d_e of equation 2, m): a start inside it could
    satisfy equation 2 before the first decision. ``scale=1`` returns the
    distribution unchanged.
    """
    if not 0 < scale <= 1:
        raise ValueError(f"scale={scale} is not allowed: (0, 1]")

    def shrink(bounds: tuple[float, float], centre: float) -> tuple[float, float]:
        low, high = bounds
        centre = min(max(centre, low), high)
        return centre + scale * (low - centre), centre + scale * (high - centre)

    x_dest, y_dest, _ = destination_start
    z_low, z_high = distribution.z_range
    return dataclasses.replace(
        distribution,
        x_range=shrink(distribution.x_range, x_dest),
        y_range=shrink(distribution.y_range, y_dest),
        z_range=(z_low, z_low + scale * (z_high - z_low)),
        min_horizontal_distance=max(scale * distribution.min_horizontal_distance, success_distance),
    )


def _uniform(low: float, high: float, count: int, generator, device) -> torch.Tensor:
    return low + (high - low) * torch.rand(count, generator=generator, device=device)


def sample_initial_aircraft(
    count: int,
    distribution: InitialStateDistribution,
    destination_start: torch.Tensor,
    generator: torch.Generator | None = None,
    device: torch.device | str = "cpu",
    max_redraws: int = 32,
) -> torch.Tensor:
    """Draw ``count`` aircraft states ``(count, 7)``; theta = psi = phi = 0 (Table 1).

    ``destination_start`` is ``(count, 4)``: starts within
    ``min_horizontal_distance`` of it (boundary included, as equation 2 includes
    its own) are redrawn (vectorised rejection sampling).
    """
    x = _uniform(*distribution.x_range, count, generator, device)
    y = _uniform(*distribution.y_range, count, generator, device)
    for _ in range(max_redraws):
        too_close = torch.hypot(x - destination_start[:, 0], y - destination_start[:, 1]) <= (
            distribution.min_horizontal_distance
        )
        if not bool(too_close.any()):
            break
        x = torch.where(too_close, _uniform(*distribution.x_range, count, generator, device), x)
        y = torch.where(too_close, _uniform(*distribution.y_range, count, generator, device), y)
    else:
        raise ValueError(
            f"min_horizontal_distance={distribution.min_horizontal_distance} m leaves (almost) no room "
            f"in the start box x={distribution.x_range}, y={distribution.y_range}"
        )
    z = _uniform(*distribution.z_range, count, generator, device)
    speed = _uniform(*distribution.speed_range, count, generator, device)
    zeros = torch.zeros(count, device=device)
    return torch.stack((x, y, z, speed, zeros, zeros, zeros), dim=-1)
