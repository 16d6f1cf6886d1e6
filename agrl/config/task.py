"""The schemas of the guidance task's sections: ``task``, ``reward`` and ``simulation`` (``conf/task``,
``conf/reward``, ``conf/simulation``).

Each key has the name of the core record field it sets (:mod:`agrl.core`; :func:`agrl.config.records.build_record`
builds the records by those names, with no table), and each value's range is checked here, once, beside its
schema: the command line (:mod:`agrl.cli`), the gymnasium env and :func:`agrl.config.guidance_parameters` all
go through these checks. The reward's keys are the paper's constants; its symbols (c1..c8) are in the comments,
in ``conf/reward/both.yaml`` and in ``docs/model.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from omegaconf import MISSING

from agrl.config.checks import ConfigError, require, require_range_pair
from agrl.core.parameters import ACTION_FIELDS, MOTION_FIELDS, ActionKind, MotionKind, tasks_taking

# ---------------------------------------------------------------------------- task
#: The largest destination speed a task takes (m/s): ten times the paper's fastest (100 m/s), far above any target
#: in the airspace, and small enough that the float32 simulation stays finite.
MAX_DESTINATION_SPEED = 1_000.0
#: The largest turning radius a curved task takes (m): a thousand times the paper's largest (5 000 m), beyond
#: which the motion is a straight line for every episode's length.
MAX_TURNING_RADIUS = 5_000_000.0


@dataclass
class TaskConfig:
    """The destination's motion (:class:`agrl.core.parameters.DestinationMotion`). A field one task does not
    read is None (a fixed destination has no speed); the fields each task needs: ``MOTION_FIELDS``."""

    name: str = MISSING  # fixed | uniform | curved | irregular
    speed: float | None = None  # uniform, curved: m/s
    radius: float | None = None  # curved: m
    turn_direction: int | None = None  # curved: +1 or -1
    change_probability: float | None = None  # irregular
    speed_range: list[float] | None = None  # irregular: m/s
    max_turn_rate_deg: float | None = None  # irregular: deg/s

    def __post_init__(self) -> None:
        kinds = [kind.value for kind in MotionKind]
        require(self.name in kinds, "task", self.name, f"one of {', '.join(kinds)}")
        for key in MOTION_FIELDS[self.name]:
            require(getattr(self, key) is not None, f"task.{key}", None, f"task={self.name} needs a value")
        if self.name in ("uniform", "curved"):
            require(0 < self.speed <= MAX_DESTINATION_SPEED, "speed", self.speed,
                     f"task={self.name} needs a destination speed in (0, {MAX_DESTINATION_SPEED:g}] m/s")
        if self.name == "curved":
            require(0 < self.radius <= MAX_TURNING_RADIUS, "radius", self.radius,
                     f"task=curved needs a turning radius in (0, {MAX_TURNING_RADIUS:g}] m")
        if self.turn_direction is not None:
            require(self.turn_direction in (-1, 1), "task.turn_direction", self.turn_direction,
                     "+1 (counter-clockwise) or -1 (clockwise)")
        if self.change_probability is not None:
            require(0 <= self.change_probability <= 1, "task.change_probability", self.change_probability,
                     "[0, 1]")
        if self.speed_range is not None:
            require_range_pair("task.speed_range", self.speed_range, 0.0, MAX_DESTINATION_SPEED, "m/s")
        if self.max_turn_rate_deg is not None:
            require(self.max_turn_rate_deg >= 0, "task.max_turn_rate_deg", self.max_turn_rate_deg, ">= 0 deg/s")


def require_shorthands_used(task: TaskConfig | None, speed: float | None, radius: float | None) -> None:
    """The command-line shorthands ``speed=`` and ``radius=`` (conf/config.yaml, conf/evaluate.yaml): one the task
    does not take would be dropped without a word, so refuse it."""
    for key, value in (("speed", speed), ("radius", radius)):
        users = tasks_taking(key)
        if value is not None and task is None:
            raise ConfigError(f"{key}={value!r} is not allowed without task=...: the checkpoint's own task is "
                              f"evaluated; give task={' or '.join(users)} with it")
        if value is not None:
            require(task.name in users, key, value,
                     f"task={task.name} has no destination {key} (only task={' or '.join(users)})")


def task_label(task) -> str:
    """A short human name of a task config for titles: ``uniform 50 m/s``, ``curved 20 m/s, radius 500 m``."""
    if task.name == "uniform":
        return f"uniform {task.speed:g} m/s"
    if task.name == "curved":
        return f"curved {task.speed:g} m/s, radius {task.radius:g} m"
    return str(task.name)


# ---------------------------------------------------------------------------- actions
@dataclass
class ActionsConfig:
    """The agent's actions (:class:`agrl.core.parameters.ActionSet`): ``maneuvers`` (the paper's seven) or
    ``targets`` (held heading, altitude and speed); the fields each reads: ``ACTION_FIELDS``."""

    name: str = MISSING  # maneuvers | targets
    headings: int | None = None  # targets: evenly spaced target headings
    altitude_step: float | None = None  # targets: m between target altitudes
    lowest_altitude: float | None = None  # targets: m
    cruise_speed: float | None = None  # targets: m/s
    heading_time_constant: float | None = None  # targets: s
    altitude_time_constant: float | None = None  # targets: s
    flight_path_time_constant: float | None = None  # targets: s
    speed_time_constant: float | None = None  # targets: s
    capture_fraction: float | None = None  # targets

    def __post_init__(self) -> None:
        kinds = [kind.value for kind in ActionKind]
        require(self.name in kinds, "actions", self.name, f"one of {', '.join(kinds)}")
        for key in ACTION_FIELDS[self.name]:
            require(getattr(self, key) is not None, f"actions.{key}", None, f"actions={self.name} needs a value")
        if self.name != ActionKind.TARGETS:
            return
        require(2 <= self.headings <= 360, "actions.headings", self.headings, "an integer in [2, 360]")
        require(self.altitude_step > 0, "actions.altitude_step", self.altitude_step, "> 0 m")
        for key in ("heading_time_constant", "altitude_time_constant", "flight_path_time_constant",
                    "speed_time_constant"):
            require(getattr(self, key) > 0, f"actions.{key}", getattr(self, key), "> 0 s")
        require(0 < self.capture_fraction <= 1, "actions.capture_fraction", self.capture_fraction, "(0, 1]")


def require_actions_fit(actions: ActionsConfig, reward: RewardConfig, simulation: SimulationConfig) -> None:
    """Checks of the action set against the other sections: a target speed within the aircraft's limits, target
    altitudes inside the airspace, and no continuous-action term with targets (equation 9 prices a change of
    maneuver; a target agent's instructions are priced by ``reward.switch_cost``)."""
    if actions.name != ActionKind.TARGETS:
        return
    limits, space = simulation.limits, simulation.airspace
    require(limits.min_speed <= actions.cruise_speed <= limits.max_speed, "actions.cruise_speed",
             actions.cruise_speed, f"within simulation.limits [{limits.min_speed}, {limits.max_speed}] m/s")
    next_level = min((math.floor(space["z_min"] / actions.altitude_step) + 1) * actions.altitude_step,
                     space["z_max"])
    require(space["z_min"] < actions.lowest_altitude < next_level, "actions.lowest_altitude",
             actions.lowest_altitude, f"in ({space['z_min']}, {next_level}) m: above the airspace's floor, below "
             "the other target altitudes")
    require(not reward.use_continuous_action, "reward.use_continuous_action", reward.use_continuous_action,
             "false with actions=targets (equation 9 prices changes of maneuver; use reward.switch_cost)")


# ---------------------------------------------------------------------------- reward
@dataclass
class RewardConfig:
    """:class:`agrl.core.reward.RewardParameters` (the paper's Table 2; its symbols in the comments)."""

    name: str = MISSING
    use_continuous_action: bool = MISSING  # the C term of equation 8
    use_position: bool = MISSING  # the P term of equation 8
    success: float = MISSING  # c1
    out_of_airspace: float = MISSING  # c2
    budget_exhausted: float = MISSING  # c3
    action_change: float = MISSING  # c4
    action_hold: float = MISSING  # c5
    distance_weight: float = MISSING  # c6
    heading_weight: float = MISSING  # c7
    altitude_weight: float = MISSING  # c8
    gamma: float = MISSING
    switch_cost: float = MISSING  # not in the paper (conf/reward/switch.yaml)

    def __post_init__(self) -> None:
        require(self.success > 0, "reward.success", self.success, "> 0 (c1: success must pay, equation 6)")
        require(self.out_of_airspace < self.budget_exhausted < 0, "reward.out_of_airspace/budget_exhausted",
                 (self.out_of_airspace, self.budget_exhausted),
                 "out_of_airspace < budget_exhausted < 0 (c2 < c3 < 0, equation 6)")
        require(self.action_change < self.action_hold <= 0, "reward.action_change/action_hold",
                 (self.action_change, self.action_hold), "action_change < action_hold <= 0 (c4 < c5 <= 0, equation 9)")
        weights = (self.distance_weight, self.heading_weight, self.altitude_weight)
        require(min(weights) >= 0, "reward.distance_weight/heading_weight/altitude_weight", weights,
                 ">= 0 (c6..c8, equation 10)")
        require(0 < self.gamma <= 1, "reward.gamma", self.gamma, "(0, 1]")
        require(0 <= self.switch_cost < self.success, "reward.switch_cost", self.switch_cost,
                 "[0, success) reward units per instruction")


# ---------------------------------------------------------------------------- simulation
@dataclass
class ToleranceConfig:
    """:class:`agrl.core.termination.SuccessTolerance` (equation 2)."""

    distance: float = MISSING  # d_e, m
    altitude: float = MISSING  # z_e, m
    heading_deg: float = MISSING  # psi_e, deg

    def __post_init__(self) -> None:
        for key in ("distance", "altitude", "heading_deg"):
            require(getattr(self, key) > 0, f"simulation.tolerance.{key}", getattr(self, key), "> 0")


@dataclass
class LimitsConfig:
    """:class:`agrl.core.aircraft.AircraftLimits`."""

    min_speed: float = MISSING  # m/s
    max_speed: float = MISSING  # m/s
    max_flight_path_angle_deg: float = MISSING  # deg

    def __post_init__(self) -> None:
        require(0 < self.min_speed < self.max_speed, "simulation.limits.min_speed/max_speed",
                 (self.min_speed, self.max_speed), "0 < min_speed < max_speed (m/s)")
        require(0 < self.max_flight_path_angle_deg < 90, "simulation.limits.max_flight_path_angle_deg",
                 self.max_flight_path_angle_deg, "(0, 90) deg")


@dataclass
class ManeuverConfig:
    """:class:`agrl.core.parameters.ManeuverLoadFactors` (g)."""

    turn: float = MISSING
    pull_up: float = MISSING
    push_over: float = MISSING
    acceleration: float = MISSING
    deceleration: float = MISSING

    def __post_init__(self) -> None:
        require(self.turn > 1, "simulation.maneuvers.turn", self.turn, "> 1 g (a level turn needs n_z > 1)")
        require(self.pull_up > 1, "simulation.maneuvers.pull_up", self.pull_up, "> 1 g")
        require(self.push_over < 1, "simulation.maneuvers.push_over", self.push_over, "< 1 g")
        require(self.acceleration > 0, "simulation.maneuvers.acceleration", self.acceleration, "> 0 g")
        require(self.deceleration > 0, "simulation.maneuvers.deceleration", self.deceleration, "> 0 g")


@dataclass
class InitialStateConfig:
    """:class:`agrl.core.initial_states.InitialStateDistribution` (checked against the airspace and the limits
    by :class:`SimulationConfig`)."""

    x_range: list[float] = MISSING
    y_range: list[float] = MISSING
    z_range: list[float] = MISSING
    speed_range: list[float] = MISSING
    min_horizontal_distance: float = MISSING


AIRSPACE_KEYS = ("x_min", "x_max", "y_min", "y_max", "z_min", "z_max")


def require_max_decisions(value: int, key: str = "max_decisions") -> None:
    """The decision budget's check, for the schema and for an env given a record built without it
    (:class:`agrl.envs.GuidanceEnv`)."""
    require(value >= 1, key, value, "an integer >= 1")


@dataclass
class SimulationConfig:
    """:class:`agrl.core.simulation.SimulationParameters` (steps, airspace, tolerance, limits) and the other
    records of :class:`agrl.core.parameters.GuidanceParameters` but the reward and the destination."""

    integration_step: float = MISSING  # s
    decision_period: float = MISSING  # s
    max_decisions: int = MISSING
    airspace: dict[str, float] = MISSING  # m: x_min, x_max, y_min, y_max, z_min, z_max
    tolerance: ToleranceConfig = MISSING
    limits: LimitsConfig = MISSING
    maneuvers: ManeuverConfig = MISSING
    initial_state: InitialStateConfig = MISSING
    compile: bool = MISSING

    def __post_init__(self) -> None:
        require(self.integration_step > 0, "simulation.integration_step", self.integration_step, "> 0 s")
        steps = self.decision_period / self.integration_step
        require(self.decision_period > 0 and abs(steps - round(steps)) < 1e-6, "simulation.decision_period",
                 self.decision_period, f"> 0 s and a whole multiple of integration_step={self.integration_step} s")
        require_max_decisions(self.max_decisions, "simulation.max_decisions")
        space = self.airspace
        require(set(space) == set(AIRSPACE_KEYS), "simulation.airspace", dict(space),
                 f"keys {', '.join(AIRSPACE_KEYS)}")
        for axis in "xyz":
            require(space[f"{axis}_min"] < space[f"{axis}_max"], f"simulation.airspace.{axis}_min/max",
                     (space[f"{axis}_min"], space[f"{axis}_max"]), "min < max (m)")
        start, limits = self.initial_state, self.limits
        require_range_pair("simulation.initial_state.x_range", start.x_range, space["x_min"], space["x_max"], "m")
        require_range_pair("simulation.initial_state.y_range", start.y_range, space["y_min"], space["y_max"], "m")
        require_range_pair("simulation.initial_state.z_range", start.z_range, space["z_min"], space["z_max"], "m")
        require_range_pair("simulation.initial_state.speed_range", start.speed_range, limits.min_speed,
                           limits.max_speed, "m/s")
        distance = self.tolerance.distance
        require(start.min_horizontal_distance > distance, "simulation.initial_state.min_horizontal_distance",
                 start.min_horizontal_distance,
                 f"> tolerance.distance={distance} m (no episode may start solved, equation 2)")
