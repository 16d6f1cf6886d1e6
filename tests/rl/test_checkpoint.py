"""Checkpoints: atomic save, round trip into ``agrl.rl.models.load_agent``, one-line errors for bad files."""

from __future__ import annotations

import os
import random
import stat
import threading
from pathlib import Path

import pytest
import torch
from torchrl.envs import ExplorationType, set_exploration_type

from agrl.config import to_guidance_parameters
from agrl.core.observation import OBSERVATION_SIZE
from agrl.envs.guidance import GuidanceEnv
from agrl.rl.checkpoint import (
    FORMAT_VERSION,
    CheckpointError,
    load_checkpoint,
    resolve_checkpoint_path,
    save_checkpoint,
)
from agrl.rl.models import load_agent
from agrl.rl.trainer import Trainer

pytestmark = pytest.mark.usefixtures("torch_one_thread")


@pytest.fixture(scope="module")
def small_trainer(tmp_path_factory, compose_train, tiny_args):
    """A Trainer with a non-default actor (one hidden layer of 32) after one iteration; its run directory."""
    config = compose_train(*tiny_args({"agent.actor_hidden": "[32]", "ppo.total_frames": 512,
                                       "eval.episodes": 4}))
    trainer = Trainer(config, tmp_path_factory.mktemp("small_actor") / "run")
    trainer.train()
    return trainer


def deterministic_actions(actor, observations: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    from tensordict import TensorDict

    td = TensorDict({"observation": observations}, batch_size=observations.shape[:1])
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        td = actor(td)
    return td["action"], td["logits"]


# ---------------------------------------------------------------------------- round trip
def test_loaded_actor_acts_like_the_trainers_actor(small_trainer):
    trainer = small_trainer
    actor, saved, path = load_agent(str(trainer.run_dir))  # a run directory -> checkpoints/latest.pt
    assert path == trainer.run_dir / "checkpoints" / "latest.pt"
    assert saved["agent"]["actor_hidden"] == [32]
    assert not actor.training

    # Observations the policy meets (a fresh batch of episode starts) plus arbitrary ones.
    env = GuidanceEnv(to_guidance_parameters(trainer.cfg.task, trainer.cfg.reward, trainer.cfg.simulation),
                      num_envs=64, seed=11)
    generator = torch.Generator().manual_seed(3)
    observations = torch.cat([env.reset()["observation"],
                              3 * torch.randn(256, OBSERVATION_SIZE, generator=generator)])
    expected_actions, expected_logits = deterministic_actions(trainer.actor, observations)
    actions, logits = deterministic_actions(actor, observations)
    assert torch.equal(logits, expected_logits)
    assert torch.equal(actions, expected_actions)
    assert torch.equal(actions, expected_logits.argmax(-1))
    assert actions.unique().numel() > 1  # the comparison is not between two constant policies


def test_save_is_atomic_and_stamps_format_and_versions(tmp_path):
    path = tmp_path / "nested" / "state.pt"
    save_checkpoint({"actor": {"w": torch.arange(3.0)}}, path)
    payload = load_checkpoint(path)
    assert payload["format_version"] == FORMAT_VERSION
    assert {"agrl", "torch", "torchrl", "tensordict"} <= set(payload["versions"])
    assert torch.equal(payload["actor"]["w"], torch.arange(3.0))

    # A payload that cannot be written leaves the previous file intact and no temporary file behind.
    with pytest.raises(TypeError, match="pickle"):
        save_checkpoint({"actor": {"w": torch.zeros(1)}, "unpicklable": threading.Lock()}, path)
    assert torch.equal(load_checkpoint(path)["actor"]["w"], torch.arange(3.0))
    assert sorted(p.name for p in path.parent.iterdir()) == ["state.pt"]


def test_missing_required_entries_are_named(tmp_path):
    path = save_checkpoint({"actor": {}}, tmp_path / "partial.pt")
    with pytest.raises(CheckpointError, match="lacks critic, optimizer") as raised:
        load_checkpoint(path, required=("actor", "critic", "optimizer"))
    assert str(path) in str(raised.value)


# ---------------------------------------------------------------------------- corrupt files
def write_bad_file(kind: str, directory, good_checkpoint) -> object:
    path = directory / f"{kind}.pt"
    if kind == "truncated":
        data = good_checkpoint.read_bytes()
        path.write_bytes(data[: len(data) // 2])
    elif kind == "random-bytes":
        path.write_bytes(random.Random(5).randbytes(4096))
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "foreign-torch-file":
        torch.save({"actor": torch.nn.Linear(2, 2).state_dict()}, path)  # a torch file, but not ours
    elif kind == "bare-tensor":
        torch.save(torch.zeros(3), path)
    # "missing": nothing written
    return path


@pytest.mark.parametrize(
    ("kind", "reason"),
    [("truncated", "not a readable checkpoint"), ("random-bytes", "not a readable checkpoint"),
     ("empty", "not a readable checkpoint"), ("foreign-torch-file", "not an agrl checkpoint"),
     ("bare-tensor", "not an agrl checkpoint"), ("missing", "no such checkpoint file")],
)
def test_bad_checkpoint_is_a_one_line_error_naming_the_file(tmp_path, small_trainer, kind, reason):
    path = write_bad_file(kind, tmp_path, small_trainer.checkpoint_dir / "latest.pt")
    for load in (load_checkpoint, load_agent):
        with pytest.raises(CheckpointError) as raised:
            load(str(path))
        message = str(raised.value)
        assert "\n" not in message
        assert message.startswith(f"{path}: ")
        assert reason in message


def test_run_directory_without_checkpoint_is_named(tmp_path):
    with pytest.raises(CheckpointError, match="run directory has no checkpoints/latest.pt") as raised:
        resolve_checkpoint_path(tmp_path)
    assert str(tmp_path) in str(raised.value)


# ---------------------------------------------------------------------------- mismatched networks
def test_a_baseline_whose_weights_do_not_fit_its_own_config_is_a_one_line_error(
    small_trainer, compose_train, tiny_args, tmp_path
):
    """Z takes the networks B's saved config names: weights of other shapes (a file edited or put together by hand)
    are refused in one line naming each differing parameter."""
    payload = load_checkpoint(small_trainer.checkpoint_dir / "latest.pt")
    payload["config"]["agent"]["actor_hidden"] = [128, 128]  # the weights stay one hidden layer of 32
    baseline = tmp_path / "inconsistent.pt"
    torch.save(payload, baseline)
    config = compose_train(*tiny_args(), "method=pretrained", f"method.baseline={baseline}")
    with pytest.raises(CheckpointError) as raised:
        Trainer(config, tmp_path / "run")
    message = str(raised.value)
    assert "\n" not in message
    assert message.startswith(f"{baseline}: the actor network does not match")
    # Each differing parameter with its shape in this configuration and in the file (one hidden layer of 32).
    assert "module.0.module.0.weight (128, 23) here, (32, 23) in the file" in message
    assert "module.0.module.2.weight (128, 128) here, (7, 32) in the file" in message  # the file's output layer


@pytest.mark.parametrize(
    ("method", "copied"),
    [(("method=pretrained",), True), (("method=reuse", "method.start_from_baseline=true"), True),
     (("method=reuse",), False)],
)
def test_pretrained_and_reuse_from_baseline_copy_its_weights(small_trainer, compose_train, tiny_args, tmp_path,
                                                            method, copied):
    """Z starts from B's weights, and so has B's networks (one hidden layer of 32, not the agent section's 2 x 128),
    which its checkpoints record; Z trained from scratch beside B keeps its own."""
    baseline = small_trainer.checkpoint_dir / "latest.pt"
    config = compose_train(*tiny_args({"ppo.total_frames": 512, "eval.episodes": 4}), *method,
                           f"method.baseline={baseline}")
    assert config.agent.actor_hidden == [128, 128]
    trainer = Trainer(config, tmp_path / "run")
    assert trainer.cfg.agent.actor_hidden == ([32] if copied else [128, 128])
    assert config.agent.actor_hidden == [128, 128]  # the caller's config is not rewritten
    saved = load_checkpoint(baseline)
    for network, state in (("actor", trainer.actor.state_dict()), ("critic", trainer.critic.state_dict())):
        same = [name in saved[network] and torch.equal(value, saved[network][name]) for name, value in state.items()]
        assert all(same) if copied else not any(same), network
    trainer.train()
    assert load_checkpoint(tmp_path / "run" / "checkpoints" / "latest.pt")["config"]["agent"]["actor_hidden"] == (
        [32] if copied else [128, 128])


# ---------------------------------------------------------------------------- safe loading
class _CreatesAFileWhenUnpickled:
    """A pickle payload of the kind a crafted checkpoint carries: unpickling it calls ``Path.touch``."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return (Path.touch, (self.marker,))


def test_written_checkpoints_hold_only_tensors_and_plain_data(small_trainer):
    from torch.serialization import get_unsafe_globals_in_checkpoint

    path = small_trainer.checkpoint_dir / "latest.pt"
    assert get_unsafe_globals_in_checkpoint(path) == []
    assert load_checkpoint(path)["format_version"] == FORMAT_VERSION == 2


def test_shipped_baseline_holds_only_tensors_and_plain_data():
    from torch.serialization import get_unsafe_globals_in_checkpoint

    assert get_unsafe_globals_in_checkpoint(resolve_checkpoint_path("baseline")) == []


def test_crafted_checkpoint_is_refused_without_running_its_code(tmp_path, run_cli):
    marker = tmp_path / "code_ran"
    path = tmp_path / "crafted.pt"
    torch.save({"format_version": FORMAT_VERSION, "actor": _CreatesAFileWhenUnpickled(marker)}, path)
    for load in (load_checkpoint, load_agent):
        with pytest.raises(CheckpointError) as raised:
            load(str(path))
        message = str(raised.value)
        # Path.touch pickles as getattr(Path, "touch"): the first object outside the allow-list is named.
        assert message == (f"{path}: refused to load: it holds a pickled getattr, and agrl loads only tensors "
                           "and plain data (a file from an untrusted source, or not an agrl checkpoint)")
    # The same file given to the CLI as a baseline: exit 2, one line, and the payload never ran (agrl.cli's checks
    # before Hydra runs, in process: real processes refusing a baseline file are in tests/test_train_cli.py).
    result = run_cli.checks("train", "method=pretrained", f"method.baseline={path}", f"hydra.run.dir={tmp_path / 'h'}")
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [f"agrl.train: error: method.baseline: {message}"]
    assert not marker.exists()


def test_format_1_checkpoint_still_resumes_identically(small_trainer, tmp_path):
    """A file as agrl wrote it before format 2 (the carried rows as a TensorDict, NumPy's key array as an
    ndarray) loads through the allow-list and restores the same training state as its format-2 twin."""
    import numpy as np
    from tensordict import TensorDict

    current = load_checkpoint(small_trainer.checkpoint_dir / "latest.pt")
    legacy = dict(current)
    legacy["format_version"] = 1
    carrier = current["carrier"]
    legacy["carrier"] = TensorDict.from_dict(carrier, batch_size=carrier["step_count"].shape[:1])
    name, keys, position, has_gauss, cached = current["rng"]["numpy"]
    legacy["rng"] = {**current["rng"], "numpy": (name, keys.numpy(), position, has_gauss, cached)}
    path = tmp_path / "format1.pt"
    torch.save({key: value for key, value in legacy.items()}, path)

    batches = []
    for payload in (load_checkpoint(path), current):
        payload["_path"] = str(path)
        trainer = Trainer(small_trainer.cfg, tmp_path / f"resumed_{len(batches)}", resume_payload=payload)
        batches.append(next(iter(trainer.collector)))
        trainer.collector.shutdown()
        batches.append(torch.from_numpy(np.random.get_state()[1].copy()))
    assert torch.equal(batches[0]["observation"], batches[2]["observation"])
    assert torch.equal(batches[0]["action"], batches[2]["action"])
    assert torch.equal(batches[1], batches[3])


@pytest.mark.parametrize("umask", [0o022, 0o077])
def test_checkpoint_files_get_the_permissions_of_any_new_file(tmp_path, umask):
    """Not the owner-only 0600 of the temporary file they are written through: checkpoints are shared."""
    previous = os.umask(umask)
    try:
        save_checkpoint({"actor": {"w": torch.zeros(1)}}, tmp_path / "state.pt")
        (tmp_path / "plain").write_bytes(b"")  # what open() gives a new file under this umask
    finally:
        os.umask(previous)
    assert stat.S_IMODE((tmp_path / "state.pt").stat().st_mode) == stat.S_IMODE((tmp_path / "plain").stat().st_mode)
    assert stat.S_IMODE((tmp_path / "state.pt").stat().st_mode) == 0o666 & ~umask
