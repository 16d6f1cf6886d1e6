"""Composing ``conf/`` with Hydra's compose API and validating it: :func:`compose_checked` (one line naming a bad
override and what is allowed), :func:`load_config` (the schemas' one-line range errors) and
:func:`validated_section` (one saved section against its schema)."""

from __future__ import annotations

import typing
from typing import Any

from omegaconf import DictConfig, OmegaConf

from agrl.config.checks import ConfigError, one_line


def load_config(cfg: DictConfig) -> Any:
    """Validate a composed config (a ``TrainConfig`` or ``EvaluateConfig``); raise :class:`ConfigError` (one line)
    on a bad value."""
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


def config_options(group: str) -> list[str]:
    """The options of a config group as shipped in ``conf/`` (``config_options("task")`` -> fixed, ...)."""
    from importlib.resources import files

    return sorted(entry.name.removesuffix(".yaml") for entry in files("agrl.conf").joinpath(group).iterdir()
                  if entry.name.endswith(".yaml"))
