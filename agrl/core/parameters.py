"""Plain parameter records for a guidance task (no Hydra): what the env and the reuse step need."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from enum import StrEnum

import torch

from agrl.core.aircraft import MANEUVER_NAMES, AircraftLimits, ManeuverControls, maneuver_table
from agrl.core.autopilot import AutopilotParameters, TargetActionTable, target_action_table
from agrl.core.destinations import curved_turn_rate
from agrl.core.initial_states import InitialStateDistribution
from agrl.core.reward import RewardParameters
from agrl.core.simulation import SimulationParameters
from agrl.core.termination import Airspace


class MotionKind(StrEnum):
    FIXED = "fixed"
    UNIFORM = "uniform"
    CURVED = "curved"
    IRREGULAR = "irregular"


#: Where the destination starts: the origin, heading psi = 0 (x m, y m, z m, psi rad; the paper's Table 1).
#: Fixed by the paper's setting and the same for every task, so ``conf/`` has no entry for it.
DESTINATION_START = (0.0, 0.0, 0.0, 0.0)

#: The :class:`DestinationMotion` fields each task reads (the others stay None): the one list of them, which the
#: task schema (``agrl.config``) checks and the command-line shorthands ``speed=``/``radius=`` are matched against.
MOTION_FIELDS = {
    "fixed": (),
    "uniform": ("speed",),
    "curved": ("speed", "radius", "turn_direction"),
    "irregular": ("change_probability", "speed_range", "max_turn_rate_deg"),
}


def require_fields_of_kind(record, kind: StrEnum, fields_by_kind: dict[str, tuple[str, ...]]) -> None:
    """A record whose ``name`` is ``kind`` must set the fields that kind reads (``fields_by_kind[kind]``; the others
    stay None): a ``ValueError`` naming the first one missing."""
    missing = [name for name in fields_by_kind[kind.value] if getattr(record, name) is None]
    if missing:
        raise ValueError(f"{type(record).__name__} {missing[0]}=None is not allowed: name={kind.value} needs "
                         f"{', '.join(fields_by_kind[kind.value])}")


def tasks_taking(field_name: str) -> list[str]:
    """The tasks whose destination reads ``field_name`` (``tasks_taking("radius")`` -> ``["curved"]``)."""
    return [task for task, names in MOTION_FIELDS.items() if field_name in names]


@dataclass(frozen=True)
class DestinationMotion:
    """How the destination moves (section 5.3), and where it starts (:data:`DESTINATION_START`).

    The values are in ``conf/task/*.yaml``, under the same names. Only ``name`` (the task, the kind of
    motion) is required: each task reads its own fields (:data:`MOTION_FIELDS`) and a task's YAML sets only
    those, so the others are None (a fixed destination has no speed) rather than a made-up value; a task's
    own fields must be given.
    """

    name: MotionKind
    speed: float | None = None  # m/s (uniform, curved)
    radius: float | None = None  # m (curved)
    turn_direction: float | None = None  # +1 or -1 (curved)
    start: tuple[float, float, float, float] = DESTINATION_START  # x m, y m, z m, psi rad
    # irregular: re-drawn at each decision with this probability, within these bounds
    change_probability: float | None = None
    speed_range: tuple[float, float] | None = None  # m/s
    max_turn_rate_deg: float | None = None  # deg/s (the radians the simulator draws in: :attr:`max_turn_rate`)

    def __post_init__(self) -> None:
        require_fields_of_kind(self, MotionKind(self.name), MOTION_FIELDS)

    @property
    def max_turn_rate(self) -> float | None:
        """The irregular destination's largest turn rate in rad/s (``math.radians(max_turn_rate_deg)``)."""
        return None if self.max_turn_rate_deg is None else math.radians(self.max_turn_rate_deg)

    def initial_motion(
        self, count: int, generator: torch.Generator | None, device: torch.device
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Initial (speed m/s, turn rate rad/s) for ``count`` destinations."""
        if self.name is MotionKind.IRREGULAR:
            low, high = self.speed_range
            speed = low + (high - low) * torch.rand(count, generator=generator, device=device)
            turn_rate = self.max_turn_rate * (2 * torch.rand(count, generator=generator, device=device) - 1)
            return speed, turn_rate
        speed = {MotionKind.FIXED: 0.0}.get(self.name, self.speed)
        turn_rate = (
            curved_turn_rate(self.speed, self.radius, self.turn_direction) if self.name is MotionKind.CURVED else 0.0
        )
        return torch.full((count,), speed, device=device), torch.full((count,), turn_rate, device=device)


@dataclass(frozen=True)
class ManeuverLoadFactors:
    """The seven maneuvers' load factors (g); see ``conf/simulation/paper.yaml`` for the reasons."""

    turn: float
    pull_up: float
    push_over: float
    acceleration: float
    deceleration: float

    def controls(self, device: torch.device | str | None = None) -> ManeuverControls:
        return maneuver_table(
            self.turn, self.pull_up, self.push_over, self.acceleration, self.deceleration, device=device
        )


class ActionKind(StrEnum):
    """What an action is (``actions``): one of the paper's seven maneuvers, or a held target (heading, altitude,
    speed) that an autopilot flies (:mod:`agrl.core.autopilot`)."""

    MANEUVERS = "maneuvers"
    TARGETS = "targets"


#: The :class:`ActionSet` fields each action set reads (the others stay None), as :data:`MOTION_FIELDS`.
ACTION_FIELDS = {
    "maneuvers": (),
    "targets": ("headings", "altitude_step", "lowest_altitude", "cruise_speed", "heading_time_constant",
                "altitude_time_constant", "flight_path_time_constant", "speed_time_constant", "capture_fraction"),
}


@dataclass(frozen=True)
class ActionSet:
    """The agent's actions (``conf/actions/*.yaml``, under the same names): the paper's seven maneuvers, or
    target-holding actions (``targets``: :func:`agrl.core.autopilot.target_action_table`, flown by the autopilot
    with the time constants here and the maneuvers' load factors). Fields ``name`` does not read stay None."""

    name: ActionKind
    headings: int | None = None  # evenly spaced target headings
    altitude_step: float | None = None  # m between target altitudes
    lowest_altitude: float | None = None  # m: a target altitude below the others
    cruise_speed: float | None = None  # m/s: the middle target speed
    heading_time_constant: float | None = None  # s: tau_psi
    altitude_time_constant: float | None = None  # s: tau_z
    flight_path_time_constant: float | None = None  # s: tau_theta
    speed_time_constant: float | None = None  # s: tau_v
    capture_fraction: float | None = None  # of the vertical acceleration the load factors allow

    def __post_init__(self) -> None:
        require_fields_of_kind(self, ActionKind(self.name), ACTION_FIELDS)

    @property
    def holds_targets(self) -> bool:
        return ActionKind(self.name) is ActionKind.TARGETS

    def autopilot(self, maneuvers: ManeuverLoadFactors) -> AutopilotParameters | None:
        """The autopilot flying held targets within the maneuvers' load factors (None for maneuvers)."""
        if not self.holds_targets:
            return None
        return AutopilotParameters(
            turn_load_factor=maneuvers.turn, pull_up_load_factor=maneuvers.pull_up,
            push_over_load_factor=maneuvers.push_over, acceleration_load_factor=maneuvers.acceleration,
            deceleration_load_factor=maneuvers.deceleration, heading_time_constant=self.heading_time_constant,
            altitude_time_constant=self.altitude_time_constant,
            flight_path_time_constant=self.flight_path_time_constant,
            speed_time_constant=self.speed_time_constant, capture_fraction=self.capture_fraction,
        )

    def target_table(self, airspace: Airspace, limits: AircraftLimits) -> TargetActionTable | None:
        """The target-holding actions inside ``airspace``'s heights and the speed ``limits`` (None for maneuvers)."""
        if not self.holds_targets:
            return None
        return target_action_table((airspace.z_min, airspace.z_max), limits, self.cruise_speed, self.headings,
                                   self.altitude_step, self.lowest_altitude)

    def count(self, airspace: Airspace, limits: AircraftLimits) -> int:
        """How many actions there are (7 maneuvers; 26 targets with ``conf/actions/targets.yaml``)."""
        return len(self.target_table(airspace, limits)) if self.holds_targets else len(MANEUVER_NAMES)


@dataclass(frozen=True)
class GuidanceParameters:
    """Everything that defines a guidance task for :class:`agrl.envs.GuidanceEnv`.

    ``conf/`` is the one source of every value: these records have no defaults of their own (except
    the physical constant :data:`agrl.core.aircraft.GRAVITY` and :data:`DESTINATION_START`, which
    ``conf/`` does not hold). Build them from ``conf/`` with :func:`agrl.config.guidance_parameters`
    (``guidance_parameters("task=curved", "reward=both")`` composes ``conf/`` as ``python -m agrl.train``
    would, Hydra overrides and all) and change a value with :func:`dataclasses.replace`."""

    simulation: SimulationParameters
    maneuvers: ManeuverLoadFactors
    reward: RewardParameters
    initial_state: InitialStateDistribution
    destination: DestinationMotion
    actions: ActionSet
    max_decisions: int  # decision budget ("control times"), this project's choice
    # Fuse the 20 ms integration step with torch.compile. Training turns it on (conf/simulation/paper.yaml),
    # tests and single-episode tools choose eager; keyword-only so that each caller says which.
    compile: bool = field(kw_only=True)

    @property
    def num_actions(self) -> int:
        return self.actions.count(self.simulation.airspace, self.simulation.limits)

    def with_switch_cost(self, switch_cost: float) -> GuidanceParameters:
        """These parameters with each instruction priced at ``switch_cost`` reward units (a run's ``finetune``)."""
        return replace(self, reward=replace(self.reward, switch_cost=switch_cost))
