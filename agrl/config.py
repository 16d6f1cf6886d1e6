"""Hydra structured configs: the schema behind ``conf/`` and its validation.

The YAML files in ``conf/`` hold the values (with units and reasons); the
dataclasses here give them types and ranges. ``load_config`` turns a composed
``DictConfig`` into these objects and raises :class:`ConfigError` with one line
naming the bad value and what is allowed. ``to_guidance_parameters`` maps them to
the plain records that :mod:`agrl.envs` needs.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf

from agrl.core.aircraft import AircraftLimits
from agrl.core.initial_states import InitialStateDistribution
from agrl.core.parameters import DestinationMotion, GuidanceParameters, ManeuverLoadFactors, MotionKind
from agrl.core.reward import RewardParameters
from agrl.core.simulation import SimulationParameters
from agrl.core.termination import Airspace, SuccessTolerance


class ConfigError(ValueError):
    """A configuration value is out of range; the message is one line."""


def _require(condition: bool, key: str, value: Any, allowed: str) -> None:
    if not condition:
        raise ConfigError(f"{key}={value!r} is not allowed: {allowed}")


def _require_device(key: str, device: str) -> None:
    """``cpu``, ``cuda`` or ``cuda:N``, and only a CUDA device this machine has."""
    _require(device == "cpu" or re.fullmatch(r"cuda(:\d+)?", device) is not None, key, device,
             "cpu, cuda or cuda:N")
    if device.startswith("cuda"):
        import torch

        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        index = int(device.partition(":")[2] or 0)
        available = ", ".join(["cpu"] + [f"cuda:{n}" for n in range(count)])
        _require(index < count, key, device, f"this machine has {available} (torch {torch.__version__})")


def _range_pair(key: str, pair: list[float], low: float, high: float, unit: str) -> None:
    _require(len(pair) == 2 and pair[0] <= pair[1], key, pair, f"a [low, high] pair with low <= high ({unit})")
    _require(low <= pair[0] and pair[1] <= high, key, pair, f"within [{low}, {high}] {unit}")


# ---------------------------------------------------------------------------- task
@dataclass
class TaskConfig:
    name: str = "fixed"  # fixed | uniform | curved | irregular
    speed: float = 0.0  # m/s
    radius: float = 1_000.0  # m
    turn_direction: int = 1  # +1 counter-clockwise, -1 clockwise
    change_probability: float = 0.2  # irregular: chance per decision of a new speed and turn rate
    speed_range: list[float] = field(default_factory=lambda: [10.0, 50.0])  # irregular, m/s
    max_turn_rate_deg: float = 2.3  # irregular, deg/s

    def __post_init__(self) -> None:
        kinds = [kind.value for kind in MotionKind]
        _require(self.name in kinds, "task", self.name, f"one of {', '.join(kinds)}")
        if self.name in ("uniform", "curved"):
            _require(self.speed > 0, "speed", self.speed, f"task={self.name} needs a destination speed > 0 m/s")
        if self.name == "curved":
            _require(self.radius > 0, "radius", self.radius, "task=curved needs a turning radius > 0 m")
        _require(self.turn_direction in (-1, 1), "task.turn_direction", self.turn_direction, "-1 or 1")
        _require(0 <= self.change_probability <= 1, "task.change_probability", self.change_probability, "[0, 1]")
        _range_pair("task.speed_range", self.speed_range, 0.0, 1_000.0, "m/s")
        _require(self.max_turn_rate_deg >= 0, "task.max_turn_rate_deg", self.max_turn_rate_deg, ">= 0 deg/s")


def task_label(task) -> str:
    """A short human name of a task config for titles: ``uniform 50 m/s``, ``curved 20 m/s, radius 500 m``."""
    if task.name == "uniform":
        return f"uniform {task.speed:g} m/s"
    if task.name == "curved":
        return f"curved {task.speed:g} m/s, radius {task.radius:g} m"
    return str(task.name)


# ---------------------------------------------------------------------------- reward
@dataclass
class RewardConfig:
    name: str = "both"
    use_continuous_action: bool = True
    use_position: bool = True
    c1: float = 20.0
    c2: float = -20.0
    c3: float = -10.0
    c4: float = -0.1
    c5: float = -0.01
    c6: float = 1e-4
    c7: float = 0.5
    c8: float = 1e-5
    gamma: float = 0.99
    switch_cost: float = 0.0  # not in the paper: reward units per instruction (conf/reward/switch.yaml)

    def __post_init__(self) -> None:
        _require(self.c1 > 0, "reward.c1", self.c1, "> 0 (success must pay, equation 6)")
        _require(self.c2 < self.c3 < 0, "reward.c2/c3", (self.c2, self.c3), "c2 < c3 < 0 (equation 6)")
        _require(self.c4 < self.c5 <= 0, "reward.c4/c5", (self.c4, self.c5), "c4 < c5 <= 0 (equation 9)")
        _require(min(self.c6, self.c7, self.c8) >= 0, "reward.c6..c8", (self.c6, self.c7, self.c8), ">= 0")
        _require(0 < self.gamma <= 1, "reward.gamma", self.gamma, "(0, 1]")
        _require(0 <= self.switch_cost < self.c1, "reward.switch_cost", self.switch_cost,
                 "[0, c1) reward units per instruction")


# ---------------------------------------------------------------------------- simulation
@dataclass
class ManeuverConfig:
    turn_load_factor: float = 2.0
    pull_up_load_factor: float = 2.0
    push_over_load_factor: float = 0.0
    acceleration: float = 0.3
    deceleration: float = 0.3

    def __post_init__(self) -> None:
        _require(self.turn_load_factor > 1, "simulation.maneuvers.turn_load_factor", self.turn_load_factor,
                 "> 1 g (a level turn needs n_z > 1)")
        _require(self.pull_up_load_factor > 1, "simulation.maneuvers.pull_up_load_factor",
                 self.pull_up_load_factor, "> 1 g")
        _require(self.push_over_load_factor < 1, "simulation.maneuvers.push_over_load_factor",
                 self.push_over_load_factor, "< 1 g")
        _require(self.acceleration > 0, "simulation.maneuvers.acceleration", self.acceleration, "> 0 g")
        _require(self.deceleration > 0, "simulation.maneuvers.deceleration", self.deceleration, "> 0 g")


@dataclass
class InitialStateConfig:
    x_range: list[float] = field(default_factory=lambda: [-9_500.0, 7_000.0])
    y_range: list[float] = field(default_factory=lambda: [-9_500.0, 9_500.0])
    z_range: list[float] = field(default_factory=lambda: [0.0, 5_000.0])
    speed_range: list[float] = field(default_factory=lambda: [200.0, 200.0])
    min_horizontal_distance: float = 2_000.0


@dataclass
class SimulationConfig:
    integration_step: float = 0.02
    decision_period: float = 3.0
    max_decisions: int = 200
    airspace: dict[str, float] = field(
        default_factory=lambda: {"x_min": -10_000.0, "x_max": 10_000.0, "y_min": -10_000.0,
                                 "y_max": 10_000.0, "z_min": 0.0, "z_max": 5_000.0}
    )
    distance_tolerance: float = 1_000.0
    altitude_tolerance: float = 200.0
    heading_tolerance_deg: float = 30.0
    min_speed: float = 100.0
    max_speed: float = 250.0
    max_flight_path_angle_deg: float = 30.0
    maneuvers: ManeuverConfig = field(default_factory=ManeuverConfig)
    initial_state: InitialStateConfig = field(default_factory=InitialStateConfig)
    compile: bool = True

    def __post_init__(self) -> None:
        _require(self.integration_step > 0, "simulation.integration_step", self.integration_step, "> 0 s")
        steps = self.decision_period / self.integration_step
        _require(self.decision_period > 0 and abs(steps - round(steps)) < 1e-6, "simulation.decision_period",
                 self.decision_period, f"> 0 s and a whole multiple of integration_step={self.integration_step} s")
        _require(self.max_decisions >= 1, "simulation.max_decisions", self.max_decisions, ">= 1")
        for key in ("distance_tolerance", "altitude_tolerance", "heading_tolerance_deg"):
            _require(getattr(self, key) > 0, f"simulation.{key}", getattr(self, key), "> 0")
        _require(0 < self.min_speed < self.max_speed, "simulation.min_speed/max_speed",
                 (self.min_speed, self.max_speed), "0 < min_speed < max_speed (m/s)")
        _require(0 < self.max_flight_path_angle_deg < 90, "simulation.max_flight_path_angle_deg",
                 self.max_flight_path_angle_deg, "(0, 90) deg")
        space = self.airspace
        _require(set(space) == {"x_min", "x_max", "y_min", "y_max", "z_min", "z_max"}, "simulation.airspace",
                 dict(space), "keys x_min, x_max, y_min, y_max, z_min, z_max")
        for axis in "xyz":
            _require(space[f"{axis}_min"] < space[f"{axis}_max"], f"simulation.airspace.{axis}_min/max",
                     (space[f"{axis}_min"], space[f"{axis}_max"]), "min < max (m)")
        start = self.initial_state
        _range_pair("simulation.initial_state.x_range", start.x_range, space["x_min"], space["x_max"], "m")
        _range_pair("simulation.initial_state.y_range", start.y_range, space["y_min"], space["y_max"], "m")
        _range_pair("simulation.initial_state.z_range", start.z_range, space["z_min"], space["z_max"], "m")
        _range_pair("simulation.initial_state.speed_range", start.speed_range, self.min_speed, self.max_speed,
                    "m/s")
        _require(start.min_horizontal_distance > self.distance_tolerance,
                 "simulation.initial_state.min_horizontal_distance", start.min_horizontal_distance,
                 f"> distance_tolerance={self.distance_tolerance} m (no episode may start solved, equation 2)")


# ---------------------------------------------------------------------------- agent, PPO, method
@dataclass
class AgentConfig:
    name: str = "default"
    actor_hidden: list[int] = field(default_factory=lambda: [128, 128])
    critic_hidden: list[int] = field(default_factory=lambda: [128, 128])
    activation: str = "tanh"

    def __post_init__(self) -> None:
        _require(all(width > 0 for width in self.actor_hidden), "agent.actor_hidden", self.actor_hidden,
                 "positive layer widths")
        _require(all(width > 0 for width in self.critic_hidden), "agent.critic_hidden", self.critic_hidden,
                 "positive layer widths")
        _require(self.activation in ("tanh", "relu", "elu"), "agent.activation", self.activation,
                 "one of tanh, relu, elu")


@dataclass
class PPOConfig:
    num_envs: int = 512
    steps_per_env: int = 64
    total_frames: int = 20_000_000
    max_minutes: float = 15.0  # 0 = no wall-time limit
    epochs: int = 4
    minibatch_size: int = 512
    learning_rate: float = 5e-4
    gae_lambda: float = 0.95
    clip_epsilon: float = 0.2
    entropy_coeff: float = 0.01
    critic_coeff: float = 0.5
    max_grad_norm: float = 0.5
    anneal_lr: bool = False

    def __post_init__(self) -> None:
        for key in ("num_envs", "steps_per_env", "total_frames", "epochs", "minibatch_size"):
            _require(getattr(self, key) >= 1, f"ppo.{key}", getattr(self, key), ">= 1")
        _require(self.learning_rate > 0, "ppo.learning_rate", self.learning_rate, "> 0")
        _require(0 <= self.gae_lambda <= 1, "ppo.gae_lambda", self.gae_lambda, "[0, 1]")
        _require(self.clip_epsilon > 0, "ppo.clip_epsilon", self.clip_epsilon, "> 0")
        _require(self.max_minutes >= 0, "ppo.max_minutes", self.max_minutes, ">= 0 (0 = no limit)")
        frames = self.num_envs * self.steps_per_env
        _require(self.minibatch_size <= frames, "ppo.minibatch_size", self.minibatch_size,
                 f"<= num_envs * steps_per_env = {frames}")


@dataclass
class MethodConfig:
    name: str = "scratch"
    baseline: str | None = None  # checkpoint path, or "baseline" for the shipped one
    initial_selection_factor: float = 1.0  # e at the start (Algorithm 1)
    selection_decay: float = 2e-5  # k, subtracted from e per relabelled episode
    candidate_stride: int = 1  # consider every n-th step as a termination step t_n
    max_candidates: int = 16  # at most this many t_n per episode (evenly spread)
    keep: str = "earliest"  # which successful candidate to keep: earliest | latest
    behaviour_log_prob: str = "baseline"  # relabelled rows' PPO behaviour log-prob: current (Z's) | baseline (B's)
    use_curriculum: bool = True  # apply the root `curriculum` (off for methods that start from a baseline)
    start_from_baseline: bool = False  # reuse only: Z starts from B's weights (reuse + pre-training)

    def __post_init__(self) -> None:
        _require(self.name in ("scratch", "pretrained", "reuse"), "method", self.name,
                 "one of scratch, pretrained, reuse")
        _require(self.name == "scratch" or bool(self.baseline), "method.baseline", self.baseline,
                 f"method={self.name} needs a baseline checkpoint (a path, or 'baseline')")
        _require(0 <= self.initial_selection_factor <= 1, "method.initial_selection_factor",
                 self.initial_selection_factor, "[0, 1]")
        _require(self.selection_decay >= 0, "method.selection_decay", self.selection_decay, ">= 0")
        _require(self.candidate_stride >= 1, "method.candidate_stride", self.candidate_stride, ">= 1")
        _require(self.max_candidates >= 1, "method.max_candidates", self.max_candidates, ">= 1")
        _require(self.keep in ("earliest", "latest"), "method.keep", self.keep, "earliest or latest")
        _require(self.behaviour_log_prob in ("current", "baseline"), "method.behaviour_log_prob",
                 self.behaviour_log_prob, "current or baseline")
        _require(not self.start_from_baseline or self.name == "reuse", "method.start_from_baseline",
                 self.start_from_baseline, "true only with method=reuse (pretrained always starts from it)")


@dataclass
class EvaluationConfig:
    episodes: int = 1000
    interval: int = 10  # iterations between periodic evaluations during training (0 = never)
    interval_seconds: float = 0.0  # s of training between periodic evaluations; > 0 replaces `interval`
    periodic_episodes: int = 256  # episodes of each periodic evaluation
    trajectory_image: bool = True  # log each periodic evaluation's trajectory figure to TensorBoard (Images)

    def __post_init__(self) -> None:
        _require(self.episodes >= 1, "eval.episodes", self.episodes, ">= 1")
        _require(self.interval >= 0, "eval.interval", self.interval, ">= 0")
        _require(self.interval_seconds >= 0, "eval.interval_seconds", self.interval_seconds,
                 ">= 0 s (0 = evaluate every eval.interval iterations)")
        _require(self.periodic_episodes >= 1, "eval.periodic_episodes", self.periodic_episodes, ">= 1")


@dataclass
class CurriculumConfig:
    """Start-box curriculum: training episodes start in a shrunken box around the destination that grows
    as training succeeds (a reverse curriculum); evaluation always uses the full box."""

    enabled: bool = True
    initial_scale: float = 0.15  # fraction of the start box (about the destination's start) at first
    scale_step: float = 0.1  # added to the fraction at each promotion
    promotion_success: float = 0.8  # training success rate (one iteration) that earns a promotion

    def __post_init__(self) -> None:
        _require(0 < self.initial_scale <= 1, "curriculum.initial_scale", self.initial_scale, "(0, 1]")
        _require(self.scale_step > 0, "curriculum.scale_step", self.scale_step, "> 0")
        _require(0 < self.promotion_success <= 1, "curriculum.promotion_success", self.promotion_success,
                 "(0, 1]")


@dataclass
class TrainConfig:
    """The root config of ``python -m agrl.train``."""

    task: Any = MISSING
    reward: Any = MISSING
    simulation: Any = MISSING
    agent: Any = MISSING
    ppo: Any = MISSING
    method: Any = MISSING
    eval: EvaluationConfig = field(default_factory=EvaluationConfig)
    curriculum: CurriculumConfig = field(default_factory=CurriculumConfig)
    speed: float | None = None
    radius: float | None = None
    seed: int = 0
    device: str = "cpu"
    threads: int | None = None  # torch intra-op threads; None: torch's default (one per core)
    resume: str | None = None
    checkpoint_interval: int = 10
    progress: bool = True
    target_success: float = 0.995  # stop once periodic evaluation reaches this success rate (0 = never)

    def __post_init__(self) -> None:
        _require_device("device", self.device)
        _require(self.threads is None or self.threads >= 1, "threads", self.threads, "null or an integer >= 1")
        _require(self.checkpoint_interval >= 1, "checkpoint_interval", self.checkpoint_interval, ">= 1")
        _require(0 <= self.target_success <= 1, "target_success", self.target_success, "[0, 1]")


@dataclass
class EvaluateConfig:
    """The root config of ``python -m agrl.evaluate``."""

    checkpoint: str = MISSING
    task: Any = None
    episodes: int = 1000
    seed: int = 0
    speed: float | None = None
    radius: float | None = None
    device: str = "cpu"
    trajectories: int = 10
    output_dir: str | None = None

    def __post_init__(self) -> None:
        _require(self.episodes >= 1, "episodes", self.episodes, ">= 1")
        _require(self.trajectories >= 0, "trajectories", self.trajectories, ">= 0")
        _require_device("device", self.device)


def _default_if_null(value: Any, default: Any) -> Any:
    return default if value is None else value


def register_configs() -> None:
    """Register the schemas with Hydra's ConfigStore (idempotent)."""
    if not OmegaConf.has_resolver("agrl_default"):
        OmegaConf.register_new_resolver("agrl_default", _default_if_null)
    store = ConfigStore.instance()
    store.store(name="train_schema", node=TrainConfig)
    store.store(name="evaluate_schema", node=EvaluateConfig)
    for group, node in (
        ("task", TaskConfig), ("reward", RewardConfig), ("simulation", SimulationConfig),
        ("agent", AgentConfig), ("ppo", PPOConfig), ("method", MethodConfig),
    ):
        store.store(group=f"schema/{group}", name="base", node=node)


register_configs()


def load_config(cfg: DictConfig) -> TrainConfig:
    """Validate a composed config; raise :class:`ConfigError` (one line) on a bad value."""
    try:
        return OmegaConf.to_object(cfg)
    except ConfigError:
        raise
    except Exception as error:  # OmegaConf wraps errors raised in __post_init__
        cause = error
        while cause.__cause__ is not None or cause.__context__ is not None:
            cause = cause.__cause__ or cause.__context__
            if isinstance(cause, ConfigError):
                raise cause from None
        raise ConfigError(str(error).splitlines()[0]) from None


def compose_config(*overrides: str, config_name: str = "config") -> DictConfig:
    """Compose ``conf/`` (installed as ``agrl.conf``) with Hydra's compose API, as ``python -m agrl.train``
    would with these command-line overrides; validate it with :func:`load_config`."""
    from hydra import compose, initialize_config_module

    with initialize_config_module(config_module="agrl.conf", version_base="1.3"):
        return compose(config_name=config_name, overrides=list(overrides))


def validated_section(schema, values: dict) -> Any:
    """One config section (e.g. a checkpoint's saved ``task``) checked against its schema, as a dataclass."""
    try:
        return OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(schema), values))
    except Exception as error:
        cause = error
        while cause is not None and not isinstance(cause, ConfigError):
            cause = cause.__cause__ or cause.__context__
        raise (cause or ConfigError(str(error).splitlines()[0])) from None


def saved_guidance_parameters(saved: dict, task: TaskConfig | None = None,
                              compile: bool | None = None) -> GuidanceParameters:
    """The task a checkpoint's saved config describes (or ``task`` instead of its own), validated."""
    task = task if task is not None else validated_section(TaskConfig, saved["task"])
    return to_guidance_parameters(task, validated_section(RewardConfig, saved["reward"]),
                                  validated_section(SimulationConfig, saved["simulation"]), compile=compile)


def config_options(group: str) -> list[str]:
    """The options of a config group as shipped in ``conf/`` (``config_options("task")`` -> fixed, ...)."""
    from importlib.resources import files

    return sorted(entry.name.removesuffix(".yaml") for entry in files("agrl.conf").joinpath(group).iterdir()
                  if entry.name.endswith(".yaml"))


def to_guidance_parameters(task: TaskConfig, reward: RewardConfig, simulation: SimulationConfig,
                           compile: bool | None = None) -> GuidanceParameters:
    """Map validated configs to the plain records of :mod:`agrl.envs`."""
    start = simulation.initial_state
    maneuvers = simulation.maneuvers
    return GuidanceParameters(
        simulation=SimulationParameters(
            integration_step=simulation.integration_step,
            decision_period=simulation.decision_period,
            airspace=Airspace(**simulation.airspace),
            tolerance=SuccessTolerance(
                distance=simulation.distance_tolerance,
                altitude=simulation.altitude_tolerance,
                heading=math.radians(simulation.heading_tolerance_deg),
            ),
            limits=AircraftLimits(
                min_speed=simulation.min_speed,
                max_speed=simulation.max_speed,
                max_flight_path_angle=math.radians(simulation.max_flight_path_angle_deg),
            ),
        ),
        maneuvers=ManeuverLoadFactors(
            turn=maneuvers.turn_load_factor,
            pull_up=maneuvers.pull_up_load_factor,
            push_over=maneuvers.push_over_load_factor,
            acceleration=maneuvers.acceleration,
            deceleration=maneuvers.deceleration,
        ),
        reward=RewardParameters(
            success=reward.c1, out_of_airspace=reward.c2, budget_exhausted=reward.c3,
            action_change=reward.c4, action_hold=reward.c5,
            distance_weight=reward.c6, heading_weight=reward.c7, altitude_weight=reward.c8,
            gamma=reward.gamma,
            use_continuous_action=reward.use_continuous_action, use_position=reward.use_position,
            switch_cost=reward.switch_cost,
        ),
        initial_state=InitialStateDistribution(
            x_range=tuple(start.x_range), y_range=tuple(start.y_range), z_range=tuple(start.z_range),
            speed_range=tuple(start.speed_range), min_horizontal_distance=start.min_horizontal_distance,
        ),
        destination=DestinationMotion(
            kind=MotionKind(task.name),
            speed=task.speed,
            radius=task.radius,
            turn_direction=float(task.turn_direction),
            change_probability=task.change_probability,
            speed_range=tuple(task.speed_range),
            max_turn_rate=math.radians(task.max_turn_rate_deg),
        ),
        max_decisions=simulation.max_decisions,
        compile=simulation.compile if compile is None else compile,
    )
