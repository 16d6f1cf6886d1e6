"""The command line of the Hydra entry points (``python -m agrl.train``, ``python -m agrl.evaluate``), checked
before Hydra runs.

Hydra reports a mistyped key, config-group option or value in several lines (with a hint to set
``HYDRA_FULL_ERROR``), and only after it has created the run directory. :func:`check_overrides` composes the
same config with Hydra's compose API and validates it against the schemas of :mod:`agrl.config`. A bad override
then stops with one line that names it and what is allowed, and nothing is written. A multirun (``-m``) has
each value of each sweep checked. Hydra's own overrides (``hydra.run.dir=...``, ``hydra/launcher=joblib``) compose
here as they do in Hydra; its other flags (``--help``, ``--cfg`` ...) are left to it. A checkpoint the command
names (``resume=``, ``checkpoint=``, ``method.baseline=``) must exist, and a resumed run takes only the overrides
of :data:`RESUMABLE_OVERRIDES`; each entry point may also check what its run will read and write (``inputs`` of
:func:`run_checked`: the baseline, the checkpoint to evaluate, the evaluation's ``output_dir``), so a file that
does not fit stops it before Hydra writes anything too.

A resumed run goes on in its own directory: :func:`run_checked` points Hydra's run directory there (its log is
appended to the run's ``train.log``, its ``.hydra/`` record of the original command is left as it was), so a
resume leaves no second directory behind.
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn

from omegaconf import DictConfig, ListConfig, OmegaConf

from agrl.baselines import SHIPPED_AGENTS, shipped_agent_names
from agrl.config import ConfigError, compose_checked, load_config, override_key

#: Where a required value has no default, what it may be (shown when it is left out).
REQUIRED_VALUES = {
    "checkpoint": f"a checkpoint file, a run directory, or a shipped agent ({shipped_agent_names()})",
}


#: Values a resumed run may take from the command line; all else comes from its checkpoint.
RESUMABLE_OVERRIDES = ("ppo.total_frames", "ppo.max_minutes", "ppo.compile_loss", "target_success", "progress",
                       "device", "threads", "checkpoint_interval", "eval.")
#: Keys whose value names a checkpoint (a file, a run directory or a shipped agent's name): it must exist.
CHECKPOINT_KEYS = ("resume", "checkpoint", "method.baseline")


def positive_int(text: str) -> int:
    """An ``argparse`` type: an integer >= 1 (its error names the value and what is allowed)."""
    try:
        value = int(text)
    except ValueError:
        value = None
    if value is None or value < 1:
        raise argparse.ArgumentTypeError(f"{text} is not allowed: a positive integer")
    return value


def writable_folder(path: str | Path) -> Path:
    """Create ``path``'s folder if needed; :class:`ConfigError` naming ``path`` if it cannot be written there
    (checked before the work, so that an unwritable output does not end a long run with a traceback)."""
    folder = Path(path).parent
    try:
        blocking = next((above for above in (folder, *folder.parents) if above.exists() and not above.is_dir()), None)
        if blocking is None:
            folder.mkdir(parents=True, exist_ok=True)
    except (OSError, ValueError) as error:  # a name too long, a NUL byte, no permission
        raise ConfigError(f"{path}: cannot be written: {getattr(error, 'strerror', None) or error}") from None
    if blocking is not None:
        raise ConfigError(f"{path}: cannot be written: {blocking} is a file, not a folder")
    if not os.access(folder, os.W_OK):
        raise ConfigError(f"{path}: cannot be written: {folder} is not writable")
    return folder


def refuse_unresumable(overrides: Sequence[str]) -> None:
    """Raise :class:`ConfigError` for the first of a resumed run's overrides it may not take (all but ``resume``
    itself and :data:`RESUMABLE_OVERRIDES`: a resumed run keeps its saved config)."""
    for override in overrides:
        key = override_key(override)
        if key != "resume" and not key.startswith(RESUMABLE_OVERRIDES):
            allowed = ", ".join(prefix + ("*" if prefix.endswith(".") else "") for prefix in RESUMABLE_OVERRIDES)
            raise ConfigError(f"{override} is not allowed with resume: a resumed run keeps its saved config; "
                              f"only {allowed} may be given")


def _candidates(overrides: list[str], multirun: bool) -> list[list[str]]:
    """The override lists to check: the overrides themselves, or for a multirun each value of each sweep with
    every other sweep at its first value (not every combination: a bad value fails on its own)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import OverrideParseException

    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except OverrideParseException as error:
        # Hydra's message: maybe "Error parsing override '...'", the parser's reason, a caret line, a link.
        lines = [line.strip() for line in str(error).splitlines()]
        reasons = [line for line in lines if line and not line.startswith(("Error parsing override", "See https", "^"))]
        override = error.override
        shown = override if override.isprintable() and override.strip() == override != "" else repr(override)
        reason = reasons[0].removeprefix("LexerNoViableAltException:").strip() if reasons else ""
        if reason in ("", override.strip()):  # the lexer names only the override: say what it is not
            reason = "not key=value in Hydra's override grammar (quote a value with special characters)"
        raise ConfigError(f"{shown} is not allowed: {reason}") from None
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


def _refuse_added_keys(overrides: list[str], config_name: str) -> None:
    """``+section.key=value`` adds a key no schema reads (Hydra suggests ``+`` for a mistyped key): refuse it.
    A ``+group=option`` (``+experiment=fast``) appends a config and stays allowed."""
    added = [override for override in overrides
             if override.startswith("+") and not override.startswith("++") and "." in override_key(override)]
    if not added:
        return
    without = compose_checked(*[override for override in overrides if override not in added], config_name=config_name)
    for override in added:
        parent, _, leaf = override_key(override).rpartition(".")
        node = OmegaConf.select(without, parent)
        if isinstance(node, DictConfig) and leaf not in node.keys():
            raise ConfigError(f"{override} is not allowed: {parent} has no key {leaf!r}; its keys: "
                              f"{', '.join(str(key) for key in node.keys())}")


def _refuse_unresolvable(overrides: list[str], config: DictConfig) -> None:
    """An override whose value is an interpolation (``seed=${foo}``) must resolve, to a value of its key's type:
    else :class:`ConfigError` naming it (OmegaConf would name neither the override nor, often, the key)."""
    for override in overrides:
        if "${" not in override:
            continue
        try:
            node = OmegaConf.select(config, override_key(override), throw_on_resolution_failure=True)
            if isinstance(node, (DictConfig, ListConfig)):
                OmegaConf.to_container(node, resolve=True)
        except Exception as error:  # OmegaConf's interpolation, resolver and type errors
            raise ConfigError(f"{override} is not allowed: {str(error).strip().splitlines()[0]}") from None


def check_overrides(arguments: Sequence[str], config_name: str) -> DictConfig | None:
    """Raise :class:`ConfigError` (one line) if the command line's overrides do not make a valid config; return
    the composed config (None for a multirun or Hydra's own modes).

    ``arguments`` are the command-line arguments (``sys.argv[1:]``); ``config_name`` the root config in
    ``conf/`` (``config`` for training, ``evaluate``). A run that resumes (``resume=...``) takes its values from
    the checkpoint, so only its composition, its overrides (:func:`refuse_unresumable`) and its checkpoint's
    existence are checked here.
    """
    flags = [argument for argument in arguments if argument.startswith("-")]
    multirun = any(flag in ("-m", "--multirun") for flag in flags)
    if any(flag not in ("-m", "--multirun") for flag in flags):
        return None  # --help, --cfg, --info ...: Hydra's own modes
    overrides = [argument for argument in arguments if not argument.startswith("-")]
    try:
        candidates = _candidates(overrides, multirun)
    except ConfigError:
        raise
    except Exception:  # a sweep this check does not expand by itself (glob over a group's options ...): Hydra's
        return None
    composed = []
    for candidate in candidates:
        config = compose_checked(*candidate, config_name=config_name)
        _refuse_unresolvable(candidate, config)
        _refuse_added_keys(candidate, config_name)
        composed.append(config)
        if config.get("resume"):
            refuse_unresumable([override for override in candidate if not override_key(override).startswith("hydra")])
            _check_checkpoint("resume", config.resume)
            continue
        missing = [key for key in REQUIRED_VALUES if key in config.keys() and OmegaConf.is_missing(config, key)]
        if missing:
            raise ConfigError(f"{missing[0]} is required: {missing[0]}=<{REQUIRED_VALUES[missing[0]]}>")
        load_config(config)
        for key in CHECKPOINT_KEYS:
            reference = OmegaConf.select(config, key, default=None)
            if reference and not (key == "method.baseline" and config.method.name == "scratch"):
                _check_checkpoint(key, reference)
    return None if multirun else composed[0]


def _check_checkpoint(key: str, reference: str) -> None:
    """That ``reference`` names a checkpoint file, a run directory with one, or a shipped agent (it is not
    read here: the run reads it, safely, and says what is wrong with its content)."""
    from agrl.rl.checkpoint import CheckpointError, resolve_checkpoint_path  # torch: only where a path is checked

    if key == "resume" and str(reference) in SHIPPED_AGENTS:  # not a training run: nothing to resume, and its
        # folder (inside the installed package) would become the run directory
        raise ConfigError(f"resume={reference} is not allowed: {reference} is a shipped agent, not a training run; "
                          f"allowed: a run directory or its checkpoint (to start from {reference}: "
                          f"method=pretrained method.baseline={reference})")
    try:
        resolve_checkpoint_path(reference)
    except CheckpointError as error:
        raise ConfigError(f"{key}: {error}") from None
    except (OSError, ValueError) as error:  # a name too long for the file system, a NUL byte
        raise ConfigError(f"{key}={reference} is not allowed: {getattr(error, 'strerror', None) or error}") from None


def resume_in_place(arguments: Sequence[str], config: DictConfig | None) -> list[str]:
    """Hydra overrides that make ``resume=<run>`` go on in the run's own directory: Hydra's run directory is the
    run's, and Hydra writes no ``.hydra/`` there (the original command's record stays). Nothing for a multirun, or
    if the command line sets ``hydra.run.dir`` itself."""
    chosen = any(override_key(argument) == "hydra.run.dir" for argument in arguments)
    if config is None or not config.get("resume") or chosen:
        return []
    from agrl.rl.checkpoint import checkpoint_run_directory, resolve_checkpoint_path

    directory = str(checkpoint_run_directory(resolve_checkpoint_path(config.resume)))
    quoted = directory.replace("\\", "\\\\").replace("'", "\\'")
    return [f"hydra.run.dir='{quoted}'", "hydra.output_subdir=null"]


def run_checked(main: Callable[[], None], program: str, config_name: str,
                inputs: Callable[[object], None] | None = None) -> None:
    """Check the command line (:func:`check_overrides`), then run the Hydra entry point ``main``.

    ``inputs(config)``, given the validated config of a run that does not resume, loads the files the run will read
    (a baseline, a checkpoint) and raises :class:`ConfigError` or :class:`CheckpointError` if one does not fit:
    that too stops before Hydra writes anything.
    """
    from agrl.rl.checkpoint import CheckpointError

    try:
        config = check_overrides(sys.argv[1:], config_name)
        sys.argv += resume_in_place(sys.argv[1:], config)
        if inputs is not None and config is not None and not config.get("resume"):
            inputs(load_config(config))
    except (ConfigError, CheckpointError) as error:
        print(f"{program}: error: {error}", file=sys.stderr)
        sys.exit(2)
    try:
        main()
    finally:
        collect_and_freeze()


def run_command(main: Callable[[], int | None]) -> NoReturn:
    """``sys.exit(main())`` for an entry point without Hydra, with :func:`collect_and_freeze` as it ends."""
    try:
        code = main()
    finally:
        collect_and_freeze()
    sys.exit(code)


def collect_and_freeze() -> None:
    """Collect cyclic garbage once, then move what is left to the collector's permanent generation: called as a
    command ends, so that the interpreter's teardown has little left to walk.

    torch, TorchRL and Hydra leave about half a million objects, and the teardown's collections walk them all
    several times, 1-2 s of every command; one collection here, then the freeze, takes a few tenths of a second
    (docs/benchmarks.md, "A command's exit"). The garbage is collected first, so nothing left for the collector
    (an unclosed file in a reference cycle) goes unfinalised. Not at start-up: frozen early, the objects the
    trainer and compilation make afterwards are walked more often, and the first iteration came later.
    """
    gc.collect()
    gc.freeze()
