"""Hydra structured configs: the schema behind ``conf/``, its validation, and the core records built from it.

The YAML files in ``conf/`` hold every value, once (with units and reasons); the dataclasses here give them types
and ranges, and no values of their own (``MISSING``, or None for a field one task or method does not use). Each
key of the task's sections has the name of the core record field it sets, so the records are built by name
(:func:`to_guidance_parameters`). :func:`load_config` turns a composed ``DictConfig`` into these objects and raises
:class:`ConfigError` with one line naming the bad value and what is allowed.

The modules, by job: :mod:`~agrl.config.checks` (the error and the range checks), :mod:`~agrl.config.task` (the
``task``, ``reward`` and ``simulation`` schemas), :mod:`~agrl.config.schemas` (agent, PPO, methods, the root
configs), :mod:`~agrl.config.compose` (composing ``conf/`` and one-line errors), :mod:`~agrl.config.records` (the
core records, and old saved configs' keys).
"""

from agrl.config.checks import ConfigError, one_line, require, require_device, require_range_pair
from agrl.config.compose import (
    compose_checked,
    compose_config,
    config_options,
    load_config,
    override_key,
    validated_section,
)
from agrl.config.records import (
    LEGACY_ACTIONS,
    RENAMED_KEYS,
    build_record,
    guidance_parameters,
    saved_agent_config,
    saved_guidance_parameters,
    to_guidance_parameters,
    upgraded_config,
)
from agrl.config.schemas import (
    AgentConfig,
    CurriculumConfig,
    EvaluateConfig,
    EvaluationConfig,
    FinetuneConfig,
    MethodConfig,
    PPOConfig,
    TrainConfig,
    method_class,
    method_config,
    method_names,
    register_configs,
    register_method,
    require_baseline,
)
from agrl.config.task import (
    MAX_DESTINATION_SPEED,
    MAX_TURNING_RADIUS,
    ActionsConfig,
    InitialStateConfig,
    LimitsConfig,
    ManeuverConfig,
    RewardConfig,
    SimulationConfig,
    TaskConfig,
    ToleranceConfig,
    require_actions_fit,
    require_max_decisions,
    require_shorthands_used,
    task_label,
)

__all__ = [
    "LEGACY_ACTIONS", "MAX_DESTINATION_SPEED", "MAX_TURNING_RADIUS", "RENAMED_KEYS", "ActionsConfig", "AgentConfig",
    "ConfigError", "CurriculumConfig", "EvaluateConfig", "EvaluationConfig", "FinetuneConfig", "InitialStateConfig",
    "LimitsConfig", "ManeuverConfig", "MethodConfig", "PPOConfig", "RewardConfig", "SimulationConfig", "TaskConfig",
    "ToleranceConfig", "TrainConfig", "build_record", "compose_checked", "compose_config", "config_options",
    "guidance_parameters", "load_config", "method_class", "method_config", "method_names", "one_line", "override_key",
    "register_configs", "register_method", "require", "require_actions_fit", "require_baseline", "require_device",
    "require_max_decisions", "require_range_pair", "require_shorthands_used", "saved_agent_config",
    "saved_guidance_parameters", "task_label", "to_guidance_parameters", "upgraded_config", "validated_section",
]
