"""The schemas of the run: agent, PPO, training method, evaluation, curriculum and the two root configs
(``python -m agrl.train``, ``python -m agrl.evaluate``), and their registration with Hydra's ConfigStore."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf

from agrl.baselines import shipped_agent_names
from agrl.config.checks import require, require_device
from agrl.config.compose import validated_section
from agrl.config.task import (
    ActionsConfig,
    RewardConfig,
    SimulationConfig,
    TaskConfig,
    require_actions_fit,
    require_shorthands_used,
)


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
    compiled_entropy_draw: bool = MISSING  # TorchRL's unused Monte-Carlo entropy draw in the compiled loss
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
    confirm_episodes: int = MISSING  # other episodes that must confirm target_success before a stop (0 = none)

    def __post_init__(self) -> None:
        require(self.episodes >= 1, "eval.episodes", self.episodes, ">= 1")
        require(self.interval >= 0, "eval.interval", self.interval, ">= 0")
        require(self.interval_seconds >= 0, "eval.interval_seconds", self.interval_seconds,
                 ">= 0 s (0 = evaluate every eval.interval iterations)")
        require(self.periodic_episodes >= 1, "eval.periodic_episodes", self.periodic_episodes, ">= 1")
        require(0.0 <= self.min_train_success <= 1.0, "eval.min_train_success", self.min_train_success,
                 "in [0, 1] (0 = no wait)")
        require(self.confirm_episodes >= 0, "eval.confirm_episodes", self.confirm_episodes,
                 ">= 0 (0 = stop on the periodic evaluation alone)")


@dataclass
class SearchConfig:
    """What ``python -m agrl.train`` returns to a Hydra sweeper (``+experiment=recipe_search``): seconds of training
    to an agent that meets ``success`` and ``max_instructions`` on the final evaluation, plus ``penalty_seconds``
    per percentage point of success short and per instruction over (:func:`agrl.rl.evaluation.search_objective`);
    with ``seeds`` > 1, the worst of that many runs (one per seed), so that a search favours a recipe that holds on
    every seed rather than one seed's luck."""

    success: float = MISSING  # fraction of the final evaluation's episodes
    max_instructions: float = MISSING  # instructions per episode
    penalty_seconds: float = MISSING  # s per point of success short and per instruction over
    seeds: int = MISSING  # runs per trial (seed, seed + 1, ...): the trial's cost is its worst run's

    def __post_init__(self) -> None:
        require(self.seeds >= 1, "search.seeds", self.seeds, ">= 1")
        require(0 < self.success <= 1, "search.success", self.success, "in (0, 1]")
        require(self.max_instructions > 0, "search.max_instructions", self.max_instructions, "> 0")
        require(self.penalty_seconds >= 0, "search.penalty_seconds", self.penalty_seconds, ">= 0 s")


@dataclass
class FinetuneConfig:
    """A switch-cost schedule in one run (not in the paper; docs/training.md): once a periodic evaluation reaches
    ``target_success``, the run trains ``iterations`` more PPO iterations at ``reward.switch_cost = switch_cost``
    instead of stopping: a training and its fine-tune as one process (``make train``)."""

    iterations: int = MISSING  # PPO iterations after the target (0 = stop at the target)
    switch_cost: float = MISSING  # reward units per instruction during them
    learning_rate: float | None = MISSING  # Adam's rate during them; None: ppo.learning_rate's

    def __post_init__(self) -> None:
        require(self.iterations >= 0, "finetune.iterations", self.iterations, ">= 0 (0 = stop at target_success)")
        require(self.switch_cost >= 0, "finetune.switch_cost", self.switch_cost, ">= 0 reward units per instruction")
        require(self.learning_rate is None or self.learning_rate > 0, "finetune.learning_rate", self.learning_rate,
                 "null (ppo.learning_rate) or > 0")


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
    actions: Any = MISSING
    agent: Any = MISSING
    ppo: Any = MISSING
    method: Any = MISSING  # a MethodConfig subclass: the schema of the method it names (method_config)
    eval: EvaluationConfig = MISSING
    curriculum: CurriculumConfig = MISSING
    search: SearchConfig = MISSING
    finetune: FinetuneConfig = MISSING
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
        require_device("device", self.device)
        require_shorthands_used(self.task, self.speed, self.radius)
        require(self.threads is None or self.threads >= 1, "threads", self.threads, "null or an integer >= 1")
        require(self.checkpoint_interval >= 1, "checkpoint_interval", self.checkpoint_interval, ">= 1")
        require(0 <= self.target_success <= 1, "target_success", self.target_success, "[0, 1]")
        require_actions_fit(self.actions, self.reward, self.simulation)
        workers = self.ppo.collector_workers
        require(workers == 1 or not self.resume, "ppo.collector_workers", workers,
                 "1 with resume (exact resume needs the single in-process collector's carried rows)")
        require(self.search.seeds == 1 or not self.resume, "search.seeds", self.search.seeds,
                 "1 with resume (resume one seed's run, <trial>/seed_<n>)")
        if self.finetune.iterations:
            require(self.target_success > 0, "finetune.iterations", self.finetune.iterations,
                     "0 when target_success=0 (the fine-tune starts when a run reaches target_success)")
            require(workers == 1, "finetune.iterations", self.finetune.iterations,
                     "0 with ppo.collector_workers > 1 (the workers' envs keep their switch cost)")
            require(self.finetune.switch_cost < self.reward.success, "finetune.switch_cost",
                     self.finetune.switch_cost, f"< reward.success={self.reward.success}")
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
        require_device("device", self.device)
        require_shorthands_used(self.task, self.speed, self.radius)
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
        ("actions", ActionsConfig), ("agent", AgentConfig), ("ppo", PPOConfig),
    ):
        store.store(group=f"schema/{group}", name="base", node=node)


register_configs()
