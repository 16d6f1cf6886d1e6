"""The command line of the Hydra entry points (``python -m agrl.train``, ``python -m agrl.evaluate``), checked
before Hydra runs.

Hydra reports a mistyped key, config-group option or value in several lines (with a hint to set
``HYDRA_FULL_ERROR``), and only after it has created the run directory. :func:`check_overrides` composes the
same config with Hydra's compose API and validates it against the schemas of :mod:`agrl.config`. A bad override
then stops with one line that names it and what is allowed, and nothing is written. A multirun (``-m``) has
each value of each sweep checked. Hydra's own overrides (``hydra.run.dir=...``, ``hydra/launcher=joblib``) compose
here as they do in Hydra; its other flags (``--help``, ``--cfg`` ...) are left to it.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence

from omegaconf import DictConfig, OmegaConf

from agrl.config import ConfigError, compose_config, config_options, load_config

#: Where a required value has no default, what it may be (shown when it is left out).
REQUIRED_VALUES = {
    "checkpoint": "a checkpoint file, a run directory, or baseline (the shipped fixed-destination agent)",
}


def _key(override: str) -> str:
    return override.split("=", 1)[0].lstrip("+~")


def _candidates(overrides: list[str], multirun: bool) -> list[list[str]]:
    """The override lists to check: the overrides themselves, or for a multirun each value of each sweep with
    every other sweep at its first value (not every combination: a bad value fails on its own)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import OverrideParseException

    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except OverrideParseException as error:
        raise ConfigError(str(error).strip().splitlines()[0]) from None
    sweeps = {}
    for index, override in enumerate(parsed):
        if override.is_sweep_override():
            if not multirun:
                raise ConfigError(f"{override.input_line} is not allowed: a sweep needs -m (--multirun)")
            key = override.input_line.split("=", 1)[0]
            sweeps[index] = [f"{key}={value}" for value in override.sweep_string_iterator()]
    first = [sweeps[index][0] if index in sweeps else override for index, override in enumerate(overrides)]
    candidates = [first]
    for index, values in sweeps.items():
        candidates += [[*first[:index], value, *first[index + 1:]] for value in values[1:]]
    return candidates


def _chain(error: BaseException) -> list[BaseException]:
    chain = [error]
    while chain[-1].__cause__ is not None or chain[-1].__context__ is not None:
        chain.append(chain[-1].__cause__ or chain[-1].__context__)
    return chain


def _reason(error: Exception, override: str, config_name: str) -> str:
    """What is allowed instead of ``override``, from the error Hydra or OmegaConf raised for it."""
    from hydra.errors import HydraException, MissingConfigException
    from omegaconf.errors import ConfigAttributeError, ConfigKeyError

    if isinstance(error, MissingConfigException) and "/" not in _key(override):
        return f"one of {', '.join(config_options(_key(override).split('@', 1)[0]))}"
    chain = _chain(error)
    if any(isinstance(cause, (ConfigKeyError, ConfigAttributeError)) for cause in chain):
        parent, _, leaf = _key(override).rpartition(".")
        defaults = compose_config(config_name=config_name)
        node = OmegaConf.select(defaults, parent) if parent else defaults
        if isinstance(node, DictConfig):
            where = parent or "the config"
            return f"{where} has no key {leaf!r}; its keys: {', '.join(str(key) for key in node.keys())}"
    # Hydra's own message says only which override failed; the first error under it says why.
    reasons = [cause for cause in chain if not isinstance(cause, HydraException)] or chain
    return str(reasons[0]).strip().splitlines()[0]


def _composed(overrides: list[str], config_name: str) -> DictConfig:
    """The config these overrides compose, or :class:`ConfigError` naming the first override that fails."""
    try:
        return compose_config(*overrides, config_name=config_name)
    except Exception as error:  # Hydra's composition errors, OmegaConf's key and type errors
        failure = error
    for count in range(1, len(overrides) + 1):  # the shortest failing prefix ends with the culprit
        try:
            compose_config(*overrides[:count], config_name=config_name)
        except Exception as error:
            culprit = overrides[count - 1]
            raise ConfigError(f"{culprit} is not allowed: {_reason(error, culprit, config_name)}") from None
    raise ConfigError(str(failure).strip().splitlines()[0]) from None


def _refuse_added_keys(overrides: list[str], config_name: str) -> None:
    """``+section.key=value`` adds a key no schema reads (Hydra suggests ``+`` for a mistyped key): refuse it.
    A ``+group=option`` (``+experiment=fast``) appends a config and stays allowed."""
    added = [override for override in overrides
             if override.startswith("+") and not override.startswith("++") and "." in _key(override)]
    if not added:
        return
    without = _composed([override for override in overrides if override not in added], config_name)
    for override in added:
        parent, _, leaf = _key(override).rpartition(".")
        node = OmegaConf.select(without, parent)
        if isinstance(node, DictConfig) and leaf not in node.keys():
            raise ConfigError(f"{override} is not allowed: {parent} has no key {leaf!r}; its keys: "
                              f"{', '.join(str(key) for key in node.keys())}")


def check_overrides(arguments: Sequence[str], config_name: str) -> None:
    """Raise :class:`ConfigError` (one line) if the command line's overrides do not make a valid config.

    ``arguments`` are the command-line arguments (``sys.argv[1:]``); ``config_name`` the root config in
    ``conf/`` (``config`` for training, ``evaluate``). A run that resumes (``resume=...``) takes its values from
    the checkpoint, so only its composition is checked here.
    """
    flags = [argument for argument in arguments if argument.startswith("-")]
    multirun = any(flag in ("-m", "--multirun") for flag in flags)
    if any(flag not in ("-m", "--multirun") for flag in flags):
        return  # --help, --cfg, --info ...: Hydra's own modes
    overrides = [argument for argument in arguments if not argument.startswith("-")]
    try:
        candidates = _candidates(overrides, multirun)
    except ConfigError:
        raise
    except Exception:  # a sweep this check does not expand by itself (glob over a group's options ...): Hydra's
        return
    for candidate in candidates:
        config = _composed(candidate, config_name)
        _refuse_added_keys(candidate, config_name)
        if config.get("resume"):
            continue
        missing = [key for key in REQUIRED_VALUES if key in config.keys() and OmegaConf.is_missing(config, key)]
        if missing:
            raise ConfigError(f"{missing[0]} is required: {missing[0]}=<{REQUIRED_VALUES[missing[0]]}>")
        load_config(config)


def run_checked(main: Callable[[], None], program: str, config_name: str) -> None:
    """Check the command line (:func:`check_overrides`), then run the Hydra entry point ``main``."""
    try:
        check_overrides(sys.argv[1:], config_name)
    except ConfigError as error:
        print(f"{program}: error: {error}", file=sys.stderr)
        sys.exit(2)
    main()
