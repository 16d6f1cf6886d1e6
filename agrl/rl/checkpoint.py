"""Checkpoints: atomic writes, safe loads, clear errors.

A checkpoint is one ``torch.save`` file holding everything needed to continue a
run exactly (networks, optimiser, counters, RNG states, the rows the collector
was carrying), plus the resolved config and package versions for provenance.
The observation is normalised by a fixed function (:mod:`agrl.core.observation`),
so there are no running normalisation statistics to store.

Checkpoints and baselines are shared between people, so loading one must never
run code: files are read with ``torch.load(weights_only=True)``, whose unpickler
builds only tensors and plain containers. Format 2 (written since agrl 0.1.0's
safe-loading change) holds nothing else. Format 1 files also held a TensorDict
(the collector's carried rows) and NumPy's RNG state; they still load, through
an allow-list of exactly those classes (:data:`FORMAT_1_GLOBALS`), never through
a full unpickler.
"""

from __future__ import annotations

import io
import os
import pickle
import re
import shutil
import tempfile
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict
from tensordict._reductions import _make_td

from agrl.baselines import SHIPPED_AGENTS, shipped_agent_names
from agrl.config import upgraded_config

FORMAT_VERSION = 2
#: The only non-plain objects a format-1 checkpoint holds (checked with
#: ``torch.serialization.get_unsafe_globals_in_checkpoint``): the TensorDict of carried
#: rows and NumPy's RNG state. Each of these only rebuilds data; none can run a command.
FORMAT_1_GLOBALS = [
    TensorDict, _make_td, np.ndarray, np.dtype, np.dtypes.UInt32DType, np._core.multiarray._reconstruct,
]
PACKAGES = ("agrl", "torch", "torchrl", "tensordict", "hydra-core", "gymnasium")


class CheckpointError(RuntimeError):
    """A checkpoint cannot be used; the message names the file and the problem in one line."""


def package_versions() -> dict[str, str]:
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions


def previous_checkpoint_path(path: str | Path) -> Path:
    """Where :func:`save_checkpoint` with ``keep_previous`` keeps the file it replaced: ``latest.previous.pt``."""
    path = Path(path)
    return path.with_name(f"{path.stem}.previous{path.suffix}")


def save_checkpoint(payload: dict[str, Any], path: str | Path, keep_previous: bool = False) -> Path:
    """Write ``payload`` to ``path`` atomically: a temporary file in the same folder, synced, then a rename.

    A crash, Ctrl-C or kill -9 at any moment of the write leaves a whole file at ``path`` (the previous one or the
    new one). With ``keep_previous``, the file it replaces stays as :func:`previous_checkpoint_path`, so a file
    damaged later (a copy cut short, a bad disk) still has a readable predecessor; it is linked, not copied, so it
    costs no disk space while both are the same. A write that fails (a full disk, a file-size limit) raises
    :class:`CheckpointError` in one line and leaves the files there were.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {"format_version": FORMAT_VERSION, "versions": package_versions(), **payload}
    buffer = io.BytesIO()
    torch.save(payload, buffer)
    for stale in path.parent.glob(f".{path.name}.*.tmp"):  # left by a writer killed mid-write
        stale.unlink(missing_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(handle, "wb") as file:
            file.write(buffer.getbuffer())
            file.flush()
            os.fsync(file.fileno())
        # mkstemp creates the file readable by its owner only; checkpoints are meant to be shared, so they get the
        # permissions any new file would (0666 less the umask), as torch.save would give them.
        os.chmod(temporary, 0o666 & ~_umask())
        if keep_previous and path.is_file():
            _keep_as_previous(path)
        os.replace(temporary, path)
    except OSError as error:
        Path(temporary).unlink(missing_ok=True)
        raise CheckpointError(f"{path}: could not write the checkpoint ({error.strerror or error}); the files there "
                              "before are kept") from None
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path


def _keep_as_previous(path: Path) -> None:
    """Make :func:`previous_checkpoint_path` the file now at ``path``, atomically: a hard link under a temporary
    name renamed over it (a copy where the filesystem has no hard links)."""
    previous = previous_checkpoint_path(path)
    temporary = previous.with_name(f".{previous.name}.link.tmp")
    temporary.unlink(missing_ok=True)
    try:
        os.link(path, temporary)
    except OSError:
        shutil.copyfile(path, temporary)
    os.replace(temporary, previous)


def load_latest_checkpoint(path: str | Path, required: tuple[str, ...] = ("actor",)
                           ) -> tuple[Path, dict[str, Any], str | None]:
    """Read ``path``, or, if it is unreadable and the checkpoint it replaced (:func:`previous_checkpoint_path`) is
    not, that one: ``(the file read, its payload, a one-line note saying why the previous one was read or None)``.
    Raises :class:`CheckpointError` naming both files if neither can be read."""
    path = Path(path)
    try:
        return path, load_checkpoint(path, required), None
    except CheckpointError as error:
        previous = previous_checkpoint_path(path)
        if not previous.is_file():
            raise
        try:
            payload = load_checkpoint(previous, required)
        except CheckpointError as previous_error:
            raise CheckpointError(f"{error}; and the one before it, {previous_error}") from None
        return previous, payload, f"{error}; going on from the checkpoint before it, {previous}"


def kept_checkpoint(checkpoint_dir: Path, interval: int) -> str:
    """What a run that stopped on an error leaves to resume from, for its error line: the folder of its last good
    ``latest`` checkpoint, or that it stopped before its first (written every ``interval`` iterations)."""
    if (checkpoint_dir / "latest.pt").is_file():
        return f"last good checkpoint kept in {checkpoint_dir}"
    return f"no checkpoint yet: the run stopped before its first (every checkpoint_interval={interval} iterations)"


def set_aside_damaged(path: str | Path) -> Path:
    """Put the readable :func:`previous_checkpoint_path` back at ``path`` and keep the damaged file beside it as
    ``<name>.damaged`` (for a look, never read): the run's checkpoints are whole again, and its next save keeps a
    good previous one. Returns where the damaged file went."""
    path = Path(path)
    damaged = path.with_name(f"{path.name}.damaged")
    if path.exists():
        os.replace(path, damaged)
    temporary = path.with_name(f".{path.name}.restore.tmp")
    shutil.copyfile(previous_checkpoint_path(path), temporary)
    os.replace(temporary, path)
    return damaged


def _umask() -> int:
    mask = os.umask(0)  # reading the umask means setting it; put it back at once
    os.umask(mask)
    return mask


def load_checkpoint(path: str | Path, required: tuple[str, ...] = ("actor",)) -> dict[str, Any]:
    """Read a checkpoint, raising :class:`CheckpointError` if it is missing, corrupt or incomplete."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no such checkpoint file")
    try:
        with torch.serialization.safe_globals(FORMAT_1_GLOBALS):
            payload = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as error:
        # The weights-only unpickler met an object outside the allow-list and refused it, unrun.
        refused = re.search(r"GLOBAL ([\w.]+)|but got <\w+ '([\w.]+)'>", str(error))
        if refused is None:  # plain garbage rather than a refused object
            raise CheckpointError(f"{path}: not a readable checkpoint (corrupt or truncated?)") from None
        raise CheckpointError(
            f"{path}: refused to load: it holds a pickled {refused.group(1) or refused.group(2)}, and agrl "
            "loads only tensors and plain data (a file from an untrusted source, or not an agrl checkpoint)"
        ) from None
    except Exception as error:  # torch raises many types for truncated or foreign files
        reason = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise CheckpointError(f"{path}: not a readable checkpoint (corrupt or truncated?): {reason}") from None
    if not isinstance(payload, dict) or "format_version" not in payload:
        raise CheckpointError(f"{path}: not an agrl checkpoint (no format_version)")
    if payload["format_version"] not in (1, FORMAT_VERSION):
        raise CheckpointError(
            f"{path}: checkpoint format {payload['format_version']} is not supported "
            f"(this agrl reads formats 1 and {FORMAT_VERSION})"
        )
    missing = [key for key in required if key not in payload]
    if missing:
        raise CheckpointError(f"{path}: checkpoint lacks {', '.join(missing)}")
    if isinstance(payload.get("config"), dict):  # a checkpoint written before the keys' renaming has the old ones
        payload["config"] = upgraded_config(payload["config"])
    return payload


def _layout_differences(expected: dict[str, torch.Tensor], found: dict[str, torch.Tensor],
                        where: tuple[str, str] = ("here", "in the file")) -> str:
    """The first few parameters whose name or shape differ between two state dicts ("" if none), for one line:
    each with its shape in ``expected`` and in ``found``, labelled by ``where``."""
    expected_shapes = {name: tuple(tensor.shape) for name, tensor in expected.items()}
    found_shapes = {name: tuple(tensor.shape) for name, tensor in found.items()}
    differing = sorted(name for name in expected_shapes.keys() | found_shapes.keys()
                       if expected_shapes.get(name) != found_shapes.get(name))
    return "; ".join(f"{name} {expected_shapes.get(name, 'absent')} {where[0]}, "
                     f"{found_shapes.get(name, 'absent')} {where[1]}" for name in differing[:4])


def load_module_state(module: torch.nn.Module, state: dict[str, torch.Tensor], path: Path, what: str) -> None:
    """Load ``state`` into ``module``, turning a layout mismatch into a one-line :class:`CheckpointError`."""
    detail = _layout_differences(module.state_dict(), state)
    if detail:
        raise CheckpointError(
            f"{path}: the {what} network does not match this configuration (differing parameters: {detail})"
        )
    module.load_state_dict(state)


def resolve_checkpoint_path(reference: str | Path) -> Path:
    """A shipped agent's name (``baseline``, ... :data:`agrl.baselines.SHIPPED_AGENTS`) -> its file; a run
    directory -> its ``checkpoints/latest.pt``; else the path. A name wins over a file of that name."""
    agent = SHIPPED_AGENTS.get(str(reference))
    if agent is not None:
        if not agent.file.is_file():
            raise CheckpointError(
                f"{agent.file}: the shipped agent {agent.name} is missing from this installation; reinstall agrl, or "
                f"make one ({agent.made_by[0]}) and pass its checkpoint path instead of '{agent.name}'"
            )
        return agent.file
    path = Path(reference)
    if path.is_dir():
        candidate = path / "checkpoints" / "latest.pt"
        if not candidate.is_file():
            raise CheckpointError(f"{path}: run directory has no checkpoints/latest.pt")
        return candidate
    if not path.exists():
        raise CheckpointError(f"{path}: no such checkpoint file or run directory; allowed: a checkpoint file, a run "
                              f"directory, or a shipped agent ({shipped_agent_names()})")
    return path


def checkpoint_run_directory(path: Path, payload: dict | None = None) -> Path:
    """The run directory a checkpoint continues in: the folder above its ``checkpoints/`` (even if the run was
    moved), else the run directory it records (``payload``, read from ``path`` if not given), else its folder."""
    if path.parent.name == "checkpoints":
        return path.parent.parent
    if payload is None:
        payload = load_checkpoint(path)
    return Path(payload.get("run_dir", path.parent))


SLIM_KEYS = ("actor", "critic", "config", "config_yaml", "counters")


def export_agent(source: str | Path, destination: str | Path, **extra: Any) -> Path:
    """Write a slim copy of a training checkpoint: networks, config and provenance, no optimiser or RNG.

    This is what the shipped agents in ``agrl/baselines/`` are (about a sixth of a full checkpoint).
    """
    source = resolve_checkpoint_path(source)
    return _save_slim(load_checkpoint(source, required=("actor", "critic", "config")), source, destination, extra)


def _save_slim(payload: dict, source: Path, destination: str | Path, extra: dict[str, Any]) -> Path:
    """Write ``payload``'s :data:`SLIM_KEYS` with ``exported_from`` = ``source`` and ``extra`` to ``destination``."""
    slim = {key: payload[key] for key in SLIM_KEYS if key in payload}
    slim["exported_from"] = str(source)
    slim.update(extra)
    return save_checkpoint(slim, destination)


def average_agents(sources: list[str | Path], destination: str | Path, **extra: Any) -> Path:
    """Write one slim checkpoint whose actor and critic weights are the element-wise means of ``sources``'.

    Meant for agents fine-tuned from one start, such as the seeds of ``+experiment=switch_finetune``: their
    weights stay close, and their average (a "model soup") is an agent of its own, evaluated in
    docs/results/switch_cost.md. The config and counters are the first source's, ``exported_from`` names it and
    ``averaged_from`` lists them all. Agents whose networks differ in any parameter's name or shape are refused.
    """
    paths = [resolve_checkpoint_path(source) for source in sources]
    payloads = [load_checkpoint(path, required=("actor", "critic", "config")) for path in paths]
    first = payloads[0]
    for path, payload in zip(paths[1:], payloads[1:], strict=True):
        for part in ("actor", "critic"):
            detail = _layout_differences(first[part], payload[part], ("in the first", "in this one"))
            if detail:
                raise CheckpointError(f"{path}: its {part} network differs from {paths[0]}'s ({detail}); only agents "
                                      "of one architecture can be averaged")
    averaged = {part: {name: torch.stack([payload[part][name] for payload in payloads]).mean(0).to(tensor.dtype)
                       for name, tensor in first[part].items()} for part in ("actor", "critic")}
    return _save_slim({**first, **averaged}, paths[0], destination,
                      {"averaged_from": [str(path) for path in paths], **extra})
