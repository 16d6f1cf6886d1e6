"""Plain parameter records for a guidance task (no Hydra): what the env and the reuse step need."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

import torch

from agrl.core.aircraft import ManeuverControls, maneuver_table
from agrl.core.destinations import curved_turn_rate
from agrl.core.initial_states import InitialStateDistribution
from agrl.core.reward import RewardParameters
from agrl.core.simulation import SimulationParameters


class MotionKind(StrEnum):
    FIXED = "fixed"
    UNIFORM = "uniform"
    CURVED = "curved"
    IRREGULAR = "irregular"


@dataclass(frozen=True)
class DestinationMotion:
    """How the destination moves (section 5.3), and where it starts (Table 1: (0, 0, 0, 0))."""

    kind: MotionKind = MotionKind.FIXED
    speed: float = 0.0  # m/s (uniform, curved)
    radius: float = 1_000.0  # m (curved)
    turn_direction: float = 1.0  # +1 or -1 (curved)
    start: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # x m, y m, z m, psi rad
    # irregular: re-drawn at each decision with this probability, within these bounds
    change_probability: float = 0.2
    speed_range: tuple[float, float] = (10.0, 50.0)  # m/s
    max_turn_rate: float = math.radians(2.3)  # rad/s: 20 m/s on a 500 m radius

    def initial_motion(
        self, count: int, generator: torch.Generator | None, device: torch.device
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Initial (speed m/s, turn rate rad/s) for ``count`` destinations."""
        if self.kind is MotionKind.IRREGULAR:
            low, high = self.speed_range
            speed = low + (high - low) * torch.rand(count, generator=generator, device=device)
            turn_rate = self.max_turn_rate * (2 * torch.rand(count, generator=generator, device=device) - 1)
            return speed, turn_rate
        speed = {MotionKind.FIXED: 0.0}.get(self.kind, self.speed)
        turn_rate = (
            curved_turn_rate(self.speed, self.radius, self.turn_direction) if self.kind is MotionKind.CURVED else 0.0
        )
        return torch.full((count,), speed, device=device), torch.full((count,), turn_rate, device=device)


@dataclass(frozen=True)
class ManeuverLoadFactors:
    """The seven maneuvers' load factors (g); see ``conf/simulation/paper.yaml`` for the reasons."""

    turn: float = 2.0
    pull_up: float = 2.0
    push_over: float = 0.0
    acceleration: float = 0.3
    deceleration: float = 0.3

    def controls(self, device: torch.device | str | None = None) -> ManeuverControls:
        return maneuver_table(
            self.turn, self.pull_up, self.push_over, self.acceleration, self.deceleration, device=device
        )


@dataclass(frozen=True)
class GuidanceParameters:
    """Everything that defines a guidance task for :class:`agrl.envs.GuidanceEnv`.

    Training builds it from ``conf/`` (:func:`agrl.config.to_guidance_parameters`). The records' own defaults,
    for torch-only use without Hydra, are conf's values for the fixed task with ``reward=both``
    (``tests/test_config.py`` checks that they agree)."""

    simulation: SimulationParameters = field(default_factory=SimulationParameters)
    maneuvers: ManeuverLoadFactors = field(default_factory=ManeuverLoadFactors)
    reward: RewardParameters = field(default_factory=RewardParameters)
    initial_state: InitialStateDistribution = field(default_factory=InitialStateDistribution)
    destination: DestinationMotion = field(default_factory=DestinationMotion)
    max_decisions: int = 200  # decision budget ("control times"), this project's choice
    # Fuse the 20 ms integration step with torch.compile. No default: training turns it on
    # (conf/simulation/paper.yaml), tests and single-episode tools choose eager; each caller says which.
    compile: bool = field(kw_only=True)
