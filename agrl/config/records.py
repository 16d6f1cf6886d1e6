"""The core records (:class:`agrl.core.parameters.GuidanceParameters`) from the composed config, by name.

A section's keys have the names of the record's fields (``reward.success`` sets ``RewardParameters.success``,
``simulation.tolerance.heading_deg`` sets ``SuccessTolerance.heading_deg``), so :func:`build_record` builds any
record from its section with no table: it walks the record's fields and takes the same-named keys. Old saved
configs (checkpoints and run folders written before the keys took these names, or before an option whose default
is not what such runs did) are read through :func:`upgraded_config`, the one place that knows old configs.
"""

from __future__ import annotations

import copy
import types
import typing
from collections.abc import Mapping
from dataclasses import asdict, fields, is_dataclass
from enum import Enum
from typing import Any

from agrl.config.checks import ConfigError
from agrl.config.compose import compose_checked, load_config, validated_section
from agrl.config.schemas import AgentConfig
from agrl.config.task import ActionsConfig, RewardConfig, SimulationConfig, TaskConfig, require_actions_fit
from agrl.core.observation import LEGACY_OBSERVATION
from agrl.core.parameters import GuidanceParameters

#: The keys saved configs had before each value took its core record field's name (agrl issue 33, "One name per
#: value"): ``{old dotted key: today's}``. Only :func:`upgraded_config` reads it: values flow by name, not by it.
RENAMED_KEYS = {
    "reward.c1": "reward.success",
    "reward.c2": "reward.out_of_airspace",
    "reward.c3": "reward.budget_exhausted",
    "reward.c4": "reward.action_change",
    "reward.c5": "reward.action_hold",
    "reward.c6": "reward.distance_weight",
    "reward.c7": "reward.heading_weight",
    "reward.c8": "reward.altitude_weight",
    "simulation.distance_tolerance": "simulation.tolerance.distance",
    "simulation.altitude_tolerance": "simulation.tolerance.altitude",
    "simulation.heading_tolerance_deg": "simulation.tolerance.heading_deg",
    "simulation.min_speed": "simulation.limits.min_speed",
    "simulation.max_speed": "simulation.limits.max_speed",
    "simulation.max_flight_path_angle_deg": "simulation.limits.max_flight_path_angle_deg",
    "simulation.maneuvers.turn_load_factor": "simulation.maneuvers.turn",
    "simulation.maneuvers.pull_up_load_factor": "simulation.maneuvers.pull_up",
    "simulation.maneuvers.push_over_load_factor": "simulation.maneuvers.push_over",
}


def upgraded_config(saved: Mapping) -> dict:
    """A saved config (a checkpoint's ``config``, a run's ``.hydra/config.yaml`` as a dict) with today's keys: each
    key of :data:`RENAMED_KEYS` it holds moves, value unchanged, to its new place, and a config saved before
    ``ppo.compiled_entropy_draw`` existed gets what its loss did then (TorchRL's draw wherever the loss was compiled),
    so that a resumed run goes on as it would have. A config with today's keys comes back equal (a copy); the input
    is not changed. Everything that reads a saved config calls this first."""
    config = copy.deepcopy(dict(saved))
    ppo = config.get("ppo")
    if isinstance(ppo, dict) and "compile_loss" in ppo:
        ppo.setdefault("compiled_entropy_draw", bool(ppo["compile_loss"]))
    for old, new in RENAMED_KEYS.items():
        *path, leaf = old.split(".")
        section: Any = config
        for key in path:
            section = section.get(key) if isinstance(section, dict) else None
        if not isinstance(section, dict) or leaf not in section:
            continue
        value = section.pop(leaf)
        *new_path, new_leaf = new.split(".")
        target = config
        for key in new_path:
            target = target.setdefault(key, {})
        target.setdefault(new_leaf, value)
    return config


def _plain(hint: Any) -> Any:
    """``X`` of ``X | None``."""
    if isinstance(hint, types.UnionType) or typing.get_origin(hint) is typing.Union:
        options = [option for option in typing.get_args(hint) if option is not type(None)]
        return options[0] if len(options) == 1 else hint
    return hint


def build_record(record_type: type, values: Mapping[str, Any]) -> Any:
    """A frozen record from a config section: each field takes the section's same-named key (a nested record is
    built from its own sub-section the same way). Lists become tuples, an enum field its enum, an integer in a
    float field a float; a field the section does not set (or sets to None) keeps the record's own default (only
    the constants ``conf/`` does not hold, and the None of a destination field the task does not read)."""
    hints = typing.get_type_hints(record_type)
    arguments = {}
    for spec in fields(record_type):
        value, hint = values.get(spec.name), _plain(hints[spec.name])
        if value is None:
            continue
        if is_dataclass(hint):
            value = build_record(hint, value)
        elif isinstance(value, (list, tuple)):
            value = tuple(value)
        elif isinstance(hint, type) and issubclass(hint, Enum):
            value = hint(value)
        elif hint is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        arguments[spec.name] = value
    return record_type(**arguments)


#: The ``actions`` section of a config written before action sets existed: the paper's seven maneuvers.
LEGACY_ACTIONS = {"name": "maneuvers"}


def to_guidance_parameters(task: TaskConfig, reward: RewardConfig, simulation: SimulationConfig,
                           compile: bool | None = None, actions: ActionsConfig | None = None) -> GuidanceParameters:
    """The records of :mod:`agrl.envs` from validated config sections (``compile``, if given, replaces
    ``simulation.compile``). :class:`GuidanceParameters` holds the ``reward`` section, the ``task`` section (its
    ``destination``), the ``actions`` section (None: the paper's maneuvers, :data:`LEGACY_ACTIONS`) and the
    ``simulation`` section's records and values; its ``simulation`` record reads its own fields (steps, airspace,
    tolerance, limits) from the same section. The action set is checked against the others here
    (:func:`agrl.config.task.require_actions_fit`)."""
    if actions is None:
        actions = validated_section(ActionsConfig, LEGACY_ACTIONS)
    require_actions_fit(actions, reward, simulation)
    section = asdict(simulation)
    values = {**section, "simulation": section, "reward": asdict(reward), "destination": asdict(task),
              "actions": asdict(actions)}
    if compile is not None:
        values["compile"] = compile
    return build_record(GuidanceParameters, values)


def guidance_parameters(*overrides: str, compile: bool = False) -> GuidanceParameters:
    """The records ``python -m agrl.train <overrides>`` would build, from ``conf/`` (the one source of every
    value): ``guidance_parameters("task=uniform", "speed=20", "reward=both")``. ``compile`` fuses the 20 ms
    step with torch.compile (training's choice, ``simulation.compile``); off here for one-off and test use.
    Raises :class:`ConfigError` (one line) on a bad value."""
    config = load_config(compose_checked(*overrides))
    return to_guidance_parameters(config.task, config.reward, config.simulation, compile=compile,
                                  actions=config.actions)


def saved_agent_config(saved: dict) -> AgentConfig:
    """A checkpoint's saved ``agent`` section, validated. Checkpoints written before ``agent.observation``
    existed (the shipped ``baseline-both-terms`` among them) have no entry: their agents read the relative
    observation."""
    return validated_section(AgentConfig, {"observation": LEGACY_OBSERVATION, **saved["agent"]})


def saved_guidance_parameters(saved: dict, task: TaskConfig | None = None,
                              compile: bool | None = None) -> GuidanceParameters:
    """The task a checkpoint's saved config describes (or ``task`` instead of its own), validated, with the
    checkpoint's action set (a config without one: :data:`LEGACY_ACTIONS`); a config with the old keys is read
    through :func:`upgraded_config`."""
    saved = upgraded_config(saved)
    task = task if task is not None else validated_section(TaskConfig, saved["task"])
    return to_guidance_parameters(task, validated_section(RewardConfig, saved["reward"]),
                                  validated_section(SimulationConfig, saved["simulation"]), compile=compile,
                                  actions=validated_section(ActionsConfig, saved.get("actions", LEGACY_ACTIONS),
                                                            prefix="actions"))


__all__ = ["ConfigError", "LEGACY_ACTIONS", "RENAMED_KEYS", "build_record", "guidance_parameters", "saved_agent_config",
           "saved_guidance_parameters", "to_guidance_parameters", "upgraded_config"]
