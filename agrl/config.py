"""Hydra structured configs: the schema behind ``conf/`` and its validation.

The YAML files in ``conf/`` hold every value, once (with units and reasons); the
dataclasses here give them types and ranges, and no values of their own (``MISSING``,
or None for a field one task or method does not use). ``load_config`` turns a composed
``DictConfig`` into these objects and raises :class:`ConfigError` with one line
naming the bad value and what is allowed. Each field that describes the task says
which field of the env's records it sets (:func:`feeds`), so
:func:`to_guidance_parameters` builds those records generically.
"""

from __future__ import annotations

import math
import re
import typing
from collections.abc import Callable
from dataclasses import dataclass, field, fields, is_dataclass
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf

from agrl.baselines import shipped_agent_names
from agrl.core.observation import LEGACY_OBSERVATION
from agrl.core.parameters import GuidanceParameters, MotionKind


class ConfigError(ValueError):
    """A configuration value is out of range; the message is one line."""


def one_line(value: Any, limit: int = 200) -> str:
    """``repr(value)`` for a one-line error message: on one line (a numpy array or a tensor of several rows
    prints them on lines of their own) and cut to ``limit`` characters."""
    text = " ".join(repr(value).split())
    return text if len(text) <= limit else f"{text[:limit]}..."


def require(condition: bool, key: str, value: Any, allowed: str) -> None:
    """Raise :class:`ConfigError` ``<key>=<value> is not allowed: <allowed>`` unless ``condition``."""
    if not condition:
        raise ConfigError(f"{key}={value!r} is not allowed: {allowed}")


def _require_device(key: str, device: str) -> None:
    """``cpu``, ``cuda`` or ``cuda:N``, and only a CUDA device this machine has."""
    require(device == "cpu" or re.fullmatch(r"cuda(:\d+)?", device) is not None, key, device,
             "cpu, cuda or cuda:N")
    if device.startswith("cuda"):
        import torch

        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        index = int(device.partition(":")[2] or 0)
        available = ", ".join(["cpu"] + [f"cuda:{n}" for n in range(count)])
        require(index < count, key, device, f"this machine has {available} (torch {torch.__version__})")


def _range_pair(key: str, pair: list[float], low: float, high: float, unit: str) -> None:
    require(len(pair) == 2 and pair[0] <= pair[1], key, pair, f"a [low, high] pair with low <= high ({unit})")
    require(low <= pair[0] and pair[1] <= high, key, pair, f"within [{low}, {high}] {unit}")


def feeds(target: str, convert: Callable[[Any], Any] | None = None, default: Any = MISSING) -> Any:
    """A schema field whose value sets the :class:`GuidanceParameters` field at the dotted path ``target``
    (``"reward.success"``), converted by ``convert`` (e.g. degrees to radians); see :func:`to_guidance_parameters`."""
    return field(default=default, metadata={"feeds": target, "convert": convert})


# ---------------------------------------------------------------------------- task
# A field one task does not use is None (e.g. a fixed destination's radius); the task's own YAML sets it.
#: The largest destination speed a task takes (m/s): ten times the paper's fastest (100 m/s), far above any target
#: in the airspace, and small enough that the float32 simulation stays finite.
MAX_DESTINATION_SPEED = 1_000.0
#: The largest turning radius a curved task takes (m): a thousand times the paper's largest (5 000 m), beyond
#: which the motion is a straight line for every episode's length.
MAX_TURNING_RADIUS = 5_000_000.0

@dataclass
class TaskConfig:
    name: str = feeds("destination.kind", MotionKind)  # fixed | uniform | curved | irregular
    speed: float | None = feeds("destination.speed", default=None)  # uniform, curved: m/s
    radius: float | None = feeds("destination.radius", default=None)  # curved: m
    turn_direction: int | None = feeds("destination.turn_direction", float, default=None)  # curved: +1 or -1
    change_probability: float | None = feeds("destination.change_probability", default=None)  # irregular
    speed_range: list[float] | None = feeds("destination.speed_range", default=None)  # irregular: m/s
    max_turn_rate_deg: float | None = feeds("destination.max_turn_rate", math.radians, default=None)  # deg/s

    def __post_init__(self) -> None:
        kinds = [kind.value for kind in MotionKind]
        require(self.name in kinds, "task", self.name, f"one of {', '.join(kinds)}")
        needs = {"uniform": ("speed",), "curved": ("speed", "radius", "turn_direction"),
                 "irregular": ("change_probability", "speed_range", "max_turn_rate_deg")}.get(self.name, ())
        for key in needs:
            require(getattr(self, key) is not None, f"task.{key}", None, f"task={self.name} needs a value")
        if self.name in ("uniform", "curved"):
            require(0 < self.speed <= MAX_DESTINATION_SPEED, "speed", self.speed,
                     f"task={self.name} needs a destination speed in (0, {MAX_DESTINATION_SPEED:g}] m/s")
        if self.name == "curved":
            require(0 < self.radius <= MAX_TURNING_RADIUS, "radius", self.radius,
                     f"task=curved needs a turning radius in (0, {MAX_TURNING_RADIUS:g}] m")
        if self.turn_direction is not None:
            require(self.turn_direction in (-1, 1), "task.turn_direction", self.turn_direction, "-1 or 1")
        if self.change_probability is not None:
            require(0 <= self.change_probability <= 1, "task.change_probability", self.change_probability,
                     "[0, 1]")
        if self.speed_range is not None:
            _range_pair("task.speed_range", self.speed_range, 0.0, MAX_DESTINATION_SPEED, "m/s")
        if self.max_turn_rate_deg is not None:
            require(self.max_turn_rate_deg >= 0, "task.max_turn_rate_deg", self.max_turn_rate_deg, ">= 0 deg/s")


#: The destination parameters each task takes (their defaults live in conf/task/*.yaml, nowhere else).
TASK_PARAMETERS: dict[str, tuple[str, ...]] = {
    "fixed": (), "uniform": ("speed",), "curved": ("speed", "radius", "turn_direction"), "irregular": (),
}


def tasks_taking(parameter: str) -> list[str]:
    """The tasks whose destination takes ``parameter`` (``tasks_taking("radius")`` -> ``["curved"]``)."""
    return [task for task, parameters in TASK_PARAMETERS.items() if parameter in parameters]


def _require_shorthands_used(task: TaskConfig | None, speed: float | None, radius: float | None) -> None:
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


# ---------------------------------------------------------------------------- reward
@dataclass
class RewardConfig:
    name: str = MISSING
    use_continuous_action: bool = feeds("reward.use_continuous_action")
    use_position: bool = feeds("reward.use_position")
    c1: float = feeds("reward.success")
    c2: float = feeds("reward.out_of_airspace")
    c3: float = feeds("reward.budget_exhausted")
    c4: float = feeds("reward.action_change")
    c5: float = feeds("reward.action_hold")
    c6: float = feeds("reward.distance_weight")
    c7: float = feeds("reward.heading_weight")
    c8: float = feeds("reward.altitude_weight")
    gamma: float = feeds("reward.gamma")
    switch_cost: float = feeds("reward.switch_cost")  # not in the paper (conf/reward/switch.yaml)

    def __post_init__(self) -> None:
        require(self.c1 > 0, "reward.c1", self.c1, "> 0 (success must pay, equation 6)")
        require(self.c2 < self.c3 < 0, "reward.c2/c3", (self.c2, self.c3), "c2 < c3 < 0 (equation 6)")
        require(self.c4 < self.c5 <= 0, "reward.c4/c5", (self.c4, self.c5), "c4 < c5 <= 0 (equation 9)")
        require(min(self.c6, self.c7, self.c8) >= 0, "reward.c6..c8", (self.c6, self.c7, self.c8), ">= 0")
        require(0 < self.gamma <= 1, "reward.gamma", self.gamma, "(0, 1]")
        require(0 <= self.switch_cost < self.c1, "reward.switch_cost", self.switch_cost,
                 "[0, c1) reward units per instruction")


# ---------------------------------------------------------------------------- simulation
@dataclass
class ManeuverConfig:
    turn_load_factor: float = feeds("maneuvers.turn")
    pull_up_load_factor: float = feeds("maneuvers.pull_up")
    push_over_load_factor: float = feeds("maneuvers.push_over")
    acceleration: float = feeds("maneuvers.acceleration")
    deceleration: float = feeds("maneuvers.deceleration")

    def __post_init__(self) -> None:
        require(self.turn_load_factor > 1, "simulation.maneuvers.turn_load_factor", self.turn_load_factor,
                 "> 1 g (a level turn needs n_z > 1)")
        require(self.pull_up_load_factor > 1, "simulation.maneuvers.pull_up_load_factor",
                 self.pull_up_load_factor, "> 1 g")
        require(self.push_over_load_factor < 1, "simulation.maneuvers.push_over_load_factor",
                 self.push_over_load_factor, "< 1 g")
        require(self.acceleration > 0, "simulation.maneuvers.acceleration", self.acceleration, "> 0 g")
        require(self.deceleration > 0, "simulation.maneuvers.deceleration", self.deceleration, "> 0 g")


@dataclass
class InitialStateConfig:
    x_range: list[float] = feeds("initial_state.x_range")
    y_range: list[float] = feeds("initial_state.y_range")
    z_range: list[float] = feeds("initial_state.z_range")
    speed_range: list[float] = feeds("initial_state.speed_range")
    min_horizontal_distance: float = feeds("initial_state.min_horizontal_distance")


@dataclass
class SimulationConfig:
    integration_step: float = feeds("simulation.integration_step")
    decision_period: float = feeds("simulation.decision_period")
    max_decisions: int = feeds("max_decisions")
    airspace: dict[str, float] = feeds("simulation.airspace")
    distance_tolerance: float = feeds("simulation.tolerance.distance")
    altitude_tolerance: float = feeds("simulation.tolerance.altitude")
    heading_tolerance_deg: float = feeds("simulation.tolerance.heading", math.radians)
    min_speed: float = feeds("simulation.limits.min_speed")
    max_speed: float = feeds("simulation.limits.max_speed")
    max_flight_path_angle_deg: float = feeds("simulation.limits.max_flight_path_angle", math.radians)
    maneuvers: ManeuverConfig = MISSING
    initial_state: InitialStateConfig = MISSING
    compile: bool = feeds("compile")

    def __post_init__(self) -> None:
        require(self.integration_step > 0, "simulation.integration_step", self.integration_step, "> 0 s")
        steps = self.decision_period / self.integration_step
        require(self.decision_period > 0 and abs(steps - round(steps)) < 1e-6, "simulation.decision_period",
                 self.decision_period, f"> 0 s and a whole multiple of integration_step={self.integration_step} s")
        require(self.max_decisions >= 1, "simulation.max_decisions", self.max_decisions, ">= 1")
        for key in ("distance_tolerance", "altitude_tolerance", "heading_tolerance_deg"):
            require(getattr(self, key) > 0, f"simulation.{key}", getattr(self, key), "> 0")
        require(0 < self.min_speed < self.max_speed, "simulation.min_speed/max_speed",
                 (self.min_speed, self.max_speed), "0 < min_speed < max_speed (m/s)")
        require(0 < self.max_flight_path_angle_deg < 90, "simulation.max_flight_path_angle_deg",
                 self.max_flight_path_angle_deg, "(0, 90) deg")
        space = self.airspace
        require(set(space) == {"x_min", "x_max", "y_min", "y_max", "z_min", "z_max"}, "simulation.airspace",
                 dict(space), "keys x_min, x_max, y_min, y_max, z_min, z_max")
        for axis in "xyz":
            require(space[f"{axis}_min"] < space[f"{axis}_max"], f"simulation.airspace.{axis}_min/max",
                     (space[f"{axis}_min"], space[f"{axis}_max"]), "min < max (m)")
        start = self.initial_state
        _range_pair("simulation.initial_state.x_range", start.x_range, space["x_min"], space["x_max"], "m")
        _range_pair("simulation.initial_state.y_range", start.y_range, space["y_min"], space["y_max"], "m")
        _range_pair("simulation.initial_state.z_range", start.z_range, space["z_min"], space["z_max"], "m")
        _range_pair("simulation.initial_state.speed_range", start.speed_range, self.min_speed, self.max_speed,
                    "m/s")
        require(start.min_horizontal_distance > self.distance_tolerance,
                 "simulation.initial_state.min_horizontal_distance", start.min_horizontal_distance,
                 f"> distance_tolerance={self.distance_tolerance} m (no episode may start solved, equation 2)")


# ---------------------------------------------------------------------------- agent, PPO, method
@dataclass
class AgentConfig:
    name: str = MISSING
    actor_hidden: list[int] = MISSING
    critic_hidden: list[int] = MISSING
    activation: str = MISSING
    observation: str = MISSING  # relative or absolute; see saved_agent_config for checkpoints without it

    def __post_init__(self) -> None:
        require(self.observation in ("relative", "absolute"), "agent.observation", self.observation,
                 "relative or absolute")
        require(all(width > 0 for width in self.actor_hidden), "agent.actor_hidden", self.actor_hidden,
                 "positive layer widths")
        require(all(width > 0 for width in self.critic_hidden), "agent.critic_hidden", self.critic_hidden,
                 "positive layer widths")
        require(self.activation in ("tanh", "relu", "elu"), "agent.activation", self.activation,
                 "one of tanh, relu, elu")


@dataclass
class PPOConfig:
    num_envs: int = MISSING
    steps_per_env: int = MISSING
    total_frames: int = MISSING
    max_minutes: float = MISSING  # 0 = no wall-time limit
    epochs: int = MISSING
    minibatch_size: int = MISSING
    learning_rate: float = MISSING
    gae_lambda: float = MISSING
    clip_epsilon: float = MISSING
    entropy_coeff: float = MISSING
    critic_coeff: float = MISSING
    max_grad_norm: float = MISSING
    anneal_lr: bool = MISSING
    compile_loss: bool = MISSING  # torch.compile the loss's forward and backward (agrl.rl.ppo.CompiledLoss)
    target_kl: float = MISSING  # stop an update once a minibatch's approximate KL exceeds 1.5 x this; 0 = never
    collector_workers: int = MISSING  # 1 = one Collector in this process; N > 1 = MultiSyncCollector

    def __post_init__(self) -> None:
        for key in ("num_envs", "steps_per_env", "total_frames", "epochs", "minibatch_size", "collector_workers"):
            require(getattr(self, key) >= 1, f"ppo.{key}", getattr(self, key), ">= 1")
        require(self.learning_rate > 0, "ppo.learning_rate", self.learning_rate, "> 0")
        require(0 <= self.gae_lambda <= 1, "ppo.gae_lambda", self.gae_lambda, "[0, 1]")
        require(self.clip_epsilon > 0, "ppo.clip_epsilon", self.clip_epsilon, "> 0")
        require(self.max_minutes >= 0, "ppo.max_minutes", self.max_minutes, ">= 0 (0 = no limit)")
        require(self.target_kl >= 0, "ppo.target_kl", self.target_kl, ">= 0 (0 = no limit)")
        frames = self.num_envs * self.steps_per_env
        require(self.minibatch_size <= frames, "ppo.minibatch_size", self.minibatch_size,
                 f"<= num_envs * steps_per_env = {frames}")
        require(self.num_envs % self.collector_workers == 0, "ppo.collector_workers", self.collector_workers,
                 f"a divisor of ppo.num_envs={self.num_envs} (each worker steps num_envs / collector_workers envs)")


@dataclass
class MethodConfig:
    """What every training method's config has. A method's own knobs live in its own schema, a subclass beside
    the method (``agrl/rl/methods/``); ``conf/method/<name>.yaml`` holds the values."""

    name: str = MISSING  # the registered method (register_method): scratch | pretrained | reuse | ...
    use_curriculum: bool = MISSING  # apply the root `curriculum` (off for methods that start from a baseline)
    # The agent B a method starts from or reuses: a checkpoint, a run directory or a shipped agent's name
    # (agrl.baselines). Scratch ignores it, so one sweep over methods can set it for all of them.
    baseline: str | None = None

    def check(self, train: TrainConfig) -> None:
        """Checks across sections (e.g. against ``train.ppo``); a method's schema adds its own."""


def require_baseline(method: MethodConfig) -> None:
    """For a method that starts from (or reuses) B: ``method.baseline`` must name one."""
    require(bool(method.baseline), "method.baseline", method.baseline,
             f"method={method.name} needs a baseline checkpoint (a path, or a shipped agent: "
             f"{shipped_agent_names()})")


#: The training methods by name: the method's class, or for the built-in ones ``"module:Class"``, imported on first
#: use (as gymnasium's entry points): this layer names the trainer's modules without importing them.
_METHODS: dict[str, type | str] = {
    "scratch": "agrl.rl.methods.scratch:Scratch",
    "pretrained": "agrl.rl.methods.pretrained:Pretrained",
    "reuse": "agrl.rl.methods.reuse:PolicyReuse",
}


def register_method(name: str, method: type | str, defaults: dict[str, Any] | None = None) -> None:
    """Make ``method=<name>`` train with ``method`` (a subclass of :class:`agrl.rl.methods.Method`, or
    ``"module:Class"``). ``defaults`` (its config's values) also make ``name`` an option of the ``method`` group
    without a YAML file in ``conf/method/``; ``docs/training.md``, "Adding a method"."""
    _METHODS[name] = method
    if defaults is not None:
        ConfigStore.instance().store(group="method", name=name, node={"name": name, **defaults})


def method_names() -> list[str]:
    return sorted(_METHODS)


def method_class(name: str) -> type:
    """The class registered as ``name`` (a one-line :class:`ConfigError` naming the registered ones if none)."""
    require(name in _METHODS, "method", name, f"one of {', '.join(method_names())}")
    entry = _METHODS[name]
    if isinstance(entry, str):
        import importlib

        module, _, attribute = entry.partition(":")
        entry = _METHODS[name] = getattr(importlib.import_module(module), attribute)
    return entry


def method_config(values: Any) -> MethodConfig:
    """A composed ``method`` section as its method's schema (``config_class``), validated (one-line errors)."""
    if isinstance(values, MethodConfig):
        return values
    values = OmegaConf.to_container(values, resolve=True) if isinstance(values, DictConfig) else dict(values)
    schema = method_class(values.get("name")).config_class
    return validated_section(schema, values, prefix="method")


@dataclass
class EvaluationConfig:
    episodes: int = MISSING
    interval: int = MISSING  # iterations between periodic evaluations during training (0 = never)
    interval_seconds: float = MISSING  # s of training between periodic evaluations; > 0 replaces `interval`
    periodic_episodes: int = MISSING  # episodes of each periodic evaluation
    trajectory_image: bool = MISSING  # log each periodic evaluation's trajectory figure to TensorBoard (Images)
    min_train_success: float = MISSING  # periodic evaluations wait for this training success on the full start box

    def __post_init__(self) -> None:
        require(self.episodes >= 1, "eval.episodes", self.episodes, ">= 1")
        require(self.interval >= 0, "eval.interval", self.interval, ">= 0")
        require(self.interval_seconds >= 0, "eval.interval_seconds", self.interval_seconds,
                 ">= 0 s (0 = evaluate every eval.interval iterations)")
        require(self.periodic_episodes >= 1, "eval.periodic_episodes", self.periodic_episodes, ">= 1")
        require(0.0 <= self.min_train_success <= 1.0, "eval.min_train_success", self.min_train_success,
                 "in [0, 1] (0 = no wait)")


@dataclass
class CurriculumConfig:
    """Start-box curriculum: training episodes start in a shrunken box around the destination that grows
    as training succeeds (a reverse curriculum); evaluation always uses the full box."""

    enabled: bool = MISSING
    initial_scale: float = MISSING  # fraction of the start box (about the destination's start) at first
    scale_step: float = MISSING  # added to the fraction at each promotion
    promotion_success: float = MISSING  # training success rate (one iteration) that earns a promotion

    def __post_init__(self) -> None:
        require(0 < self.initial_scale <= 1, "curriculum.initial_scale", self.initial_scale, "(0, 1]")
        require(self.scale_step > 0, "curriculum.scale_step", self.scale_step, "> 0")
        require(0 < self.promotion_success <= 1, "curriculum.promotion_success", self.promotion_success,
                 "(0, 1]")


@dataclass
class TrainConfig:
    """The root config of ``python -m agrl.train`` (values: ``conf/config.yaml``)."""

    task: Any = MISSING
    reward: Any = MISSING
    simulation: Any = MISSING
    agent: Any = MISSING
    ppo: Any = MISSING
    method: Any = MISSING  # a MethodConfig subclass: the schema of the method it names (method_config)
    eval: EvaluationConfig = MISSING
    curriculum: CurriculumConfig = MISSING
    speed: float | None = MISSING
    radius: float | None = MISSING
    seed: int = MISSING
    device: str = MISSING
    threads: int | None = MISSING  # torch intra-op threads; None: torch's default (one per core)
    resume: str | None = MISSING
    checkpoint_interval: int = MISSING
    progress: bool = MISSING
    target_success: float = MISSING  # stop once periodic evaluation reaches this success rate (0 = never)

    def __post_init__(self) -> None:
        _require_device("device", self.device)
        _require_shorthands_used(self.task, self.speed, self.radius)
        require(self.threads is None or self.threads >= 1, "threads", self.threads, "null or an integer >= 1")
        require(self.checkpoint_interval >= 1, "checkpoint_interval", self.checkpoint_interval, ">= 1")
        require(0 <= self.target_success <= 1, "target_success", self.target_success, "[0, 1]")
        workers = self.ppo.collector_workers
        require(workers == 1 or not self.resume, "ppo.collector_workers", workers,
                 "1 with resume (exact resume needs the single in-process collector's carried rows)")
        self.method = method_config(self.method)
        self.method.check(self)


@dataclass
class EvaluateConfig:
    """The root config of ``python -m agrl.evaluate`` (values: ``conf/evaluate.yaml``)."""

    checkpoint: str = MISSING
    task: Any = None
    episodes: int = MISSING
    seed: int = MISSING
    speed: float | None = MISSING
    radius: float | None = MISSING
    device: str = MISSING
    threads: int | None = MISSING  # torch intra-op threads; None: torch's default (one per core)
    trajectories: int = MISSING
    output_dir: str | None = MISSING

    def __post_init__(self) -> None:
        require(self.episodes >= 1, "episodes", self.episodes, ">= 1")
        require(self.trajectories >= 0, "trajectories", self.trajectories, ">= 0")
        _require_device("device", self.device)
        _require_shorthands_used(self.task, self.speed, self.radius)
        require(self.threads is None or self.threads >= 1, "threads", self.threads, "null or an integer >= 1")


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
        ("agent", AgentConfig), ("ppo", PPOConfig),
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


def override_key(override: str) -> str:
    """The key an override sets (``+ppo.lr=1`` -> ``ppo.lr``)."""
    return override.split("=", 1)[0].lstrip("+~")


def _chain(error: BaseException) -> list[BaseException]:
    chain = [error]
    while chain[-1].__cause__ is not None or chain[-1].__context__ is not None:
        chain.append(chain[-1].__cause__ or chain[-1].__context__)
    return chain


def _reason(error: Exception, override: str, config_name: str, before: tuple[str, ...] = ()) -> str:
    """What is allowed instead of ``override``, from the error Hydra or OmegaConf raised for it (``before``: the
    overrides ahead of it, which compose: they choose the sections whose keys are allowed)."""
    from hydra.errors import HydraException, MissingConfigException
    from omegaconf.errors import ConfigAttributeError, ConfigKeyError

    if isinstance(error, MissingConfigException) and "/" not in override_key(override):
        return f"one of {', '.join(config_options(override_key(override).split('@', 1)[0]))}"
    chain = _chain(error)
    if any(isinstance(cause, (ConfigKeyError, ConfigAttributeError)) for cause in chain):
        parent, _, leaf = override_key(override).rpartition(".")
        defaults = compose_config(*before, config_name=config_name)
        node = OmegaConf.select(defaults, parent) if parent else defaults
        if isinstance(node, DictConfig):
            where = parent or "the config"
            return f"{where} has no key {leaf!r}; its keys: {', '.join(str(key) for key in node.keys())}"
    # Hydra's own message says only which override failed; the first error under it says why.
    reasons = [cause for cause in chain if not isinstance(cause, HydraException)] or chain
    return str(reasons[0]).strip().splitlines()[0]


def compose_checked(*overrides: str, config_name: str = "config") -> DictConfig:
    """:func:`compose_config`, or :class:`ConfigError` in one line naming the first override that fails and what
    is allowed (the keys of its section, the options of its group, or the reason OmegaConf gives)."""
    try:
        return compose_config(*overrides, config_name=config_name)
    except Exception as error:  # Hydra's composition errors, OmegaConf's key and type errors
        failure = error
    for count in range(1, len(overrides) + 1):  # the shortest failing prefix ends with the culprit
        try:
            compose_config(*overrides[:count], config_name=config_name)
        except Exception as error:
            culprit = overrides[count - 1]
            reason = _reason(error, culprit, config_name, tuple(overrides[:count - 1]))
            raise ConfigError(f"{culprit} is not allowed: {reason}") from None
    raise ConfigError(str(failure).strip().splitlines()[0]) from None


def validated_section(schema, values: dict, prefix: str = "") -> Any:
    """One config section (e.g. a checkpoint's saved ``task``) checked against its schema, as a dataclass; an
    unknown key or a value of the wrong type is one line naming it (under ``prefix``, e.g. ``method``)."""
    try:
        return OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(schema), values))
    except Exception as error:
        cause = error
        while cause is not None and not isinstance(cause, ConfigError):
            cause = cause.__cause__ or cause.__context__
        if cause is None:
            key = getattr(error, "full_key", None)
            where = f"{prefix}.{key}" if prefix and key else key or prefix
            message = str(error).splitlines()[0]
            if key and isinstance(values, dict) and key in values:
                allowed = {int: "an integer", float: "a number", bool: "true or false", str: "a string"}.get(
                    typing.get_type_hints(schema).get(key), message)
                cause = ConfigError(f"{where}={one_line(values[key])} is not allowed: {allowed}")
            else:
                cause = ConfigError(f"{where}: {message}" if where else message)
        raise cause from None


def saved_agent_config(saved: dict) -> AgentConfig:
    """A checkpoint's saved ``agent`` section, validated. Checkpoints written before ``agent.observation``
    existed (the shipped ``baseline-both-terms`` among them) have no entry: their agents read the relative
    observation."""
    return validated_section(AgentConfig, {"observation": LEGACY_OBSERVATION, **saved["agent"]})


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


def _record_values(section: Any) -> dict[str, Any]:
    """``{record path: value}`` for every field of a config section (and its nested sections) that feeds one."""
    values = {}
    for spec in fields(section):
        value = getattr(section, spec.name)
        if is_dataclass(value):
            values.update(_record_values(value))
        elif "feeds" in spec.metadata and value is not None:
            convert = spec.metadata["convert"]
            values[spec.metadata["feeds"]] = convert(value) if convert is not None else value
    return values


def _build_record(record_type: type, values: dict[str, Any]) -> Any:
    """A frozen record from ``{dotted path: value}``: nested records (and dicts) are built the same way, lists
    become tuples, and fields no value names keep the record's own default (only the constants ``conf/`` does
    not hold, and the None of a destination field the task does not use; ``tests/test_config.py``)."""
    hints = typing.get_type_hints(record_type)
    names = {spec.name for spec in fields(record_type)}
    unknown = sorted({path.partition(".")[0] for path in values} - names)
    if unknown:
        raise TypeError(f"{record_type.__name__} has no field {unknown[0]!r}")
    kwargs = {}
    for name in names:
        nested = {path.partition(".")[2]: value for path, value in values.items() if path.startswith(f"{name}.")}
        value = values.get(name, nested or None)
        if isinstance(value, dict):
            value = _build_record(hints[name], value)
        elif isinstance(value, list):
            value = tuple(value)
        if value is not None:
            kwargs[name] = value
    return record_type(**kwargs)


def to_guidance_parameters(task: TaskConfig, reward: RewardConfig, simulation: SimulationConfig,
                           compile: bool | None = None) -> GuidanceParameters:
    """The records of :mod:`agrl.envs` from validated config sections: each value goes where its schema field's
    :func:`feeds` says (``compile``, if given, replaces ``simulation.compile``)."""
    values = {**_record_values(task), **_record_values(reward), **_record_values(simulation)}
    if compile is not None:
        values["compile"] = compile
    return _build_record(GuidanceParameters, values)


def guidance_parameters(*overrides: str, compile: bool = False) -> GuidanceParameters:
    """The records ``python -m agrl.train <overrides>`` would build, from ``conf/`` (the one source of every
    value): ``guidance_parameters("task=uniform", "speed=20", "reward=both")``. ``compile`` fuses the 20 ms
    step with torch.compile (training's choice, ``simulation.compile``); off here for one-off and test use.
    Raises :class:`ConfigError` (one line) on a bad value."""
    config = load_config(compose_checked(*overrides))
    return to_guidance_parameters(config.task, config.reward, config.simulation, compile=compile)
