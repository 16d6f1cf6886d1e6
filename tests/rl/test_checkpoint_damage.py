"""Checkpoints survive what happens to files: the previous one kept, a kill -9 mid-write, a full disk, and a
damaged ``latest.pt`` that a resume steps over."""

from __future__ import annotations

import json
import multiprocessing
import os
import random
import resource
import shutil
import signal
import time

import pytest
import torch

from agrl.rl.checkpoint import (
    CheckpointError,
    load_checkpoint,
    load_latest_checkpoint,
    previous_checkpoint_path,
    save_checkpoint,
)


@pytest.fixture(scope="module")
def writers():
    """A multiprocessing context whose processes fork from a clean server that has imported the checkpoint code
    once: each writer starts at once, and none inherits the test process's threads (a plain fork of a process
    with torch's and TensorBoard's threads running can deadlock)."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["agrl.rl.checkpoint"])
    return context


def payload(step: int, size: int = 1000) -> dict:
    return {"actor": {"weight": torch.full((size,), float(step))}, "counters": {"iteration": step}}


def test_the_replaced_latest_is_kept_as_previous(tmp_path):
    latest = tmp_path / "latest.pt"
    save_checkpoint(payload(1), latest, keep_previous=True)
    assert not previous_checkpoint_path(latest).exists()  # nothing replaced yet
    save_checkpoint(payload(2), latest, keep_previous=True)
    save_checkpoint(payload(3), latest, keep_previous=True)
    assert load_checkpoint(latest)["counters"]["iteration"] == 3
    assert load_checkpoint(previous_checkpoint_path(latest))["counters"]["iteration"] == 2
    assert sorted(path.name for path in tmp_path.iterdir()) == ["latest.previous.pt", "latest.pt"]


def test_a_truncated_latest_is_stepped_over_with_one_line(tmp_path):
    latest = tmp_path / "latest.pt"
    for step in (1, 2):
        save_checkpoint(payload(step), latest, keep_previous=True)
    latest.write_bytes(latest.read_bytes()[:500])
    path, read, note = load_latest_checkpoint(latest)
    assert path == previous_checkpoint_path(latest) and read["counters"]["iteration"] == 1
    assert note == (f"{latest}: not a readable checkpoint (corrupt or truncated?): "
                    f"{note.split('truncated?): ', 1)[1].split(';')[0]}; going on from the checkpoint before it, "
                    f"{previous_checkpoint_path(latest)}")
    assert "\n" not in note


def test_a_readable_latest_is_read_without_a_note(tmp_path):
    latest = tmp_path / "latest.pt"
    for step in (1, 2):
        save_checkpoint(payload(step), latest, keep_previous=True)
    assert load_latest_checkpoint(latest)[0::2] == (latest, None)


def test_two_damaged_checkpoints_are_one_line_naming_both(tmp_path):
    latest = tmp_path / "latest.pt"
    for step in (1, 2):
        save_checkpoint(payload(step), latest, keep_previous=True)
    latest.write_bytes(b"garbage")
    previous_checkpoint_path(latest).unlink()
    previous_checkpoint_path(latest).write_bytes(b"garbage")  # a separate file now, not the link
    with pytest.raises(CheckpointError) as error:
        load_latest_checkpoint(latest)
    message = str(error.value)
    assert "\n" not in message and str(latest) in message and str(previous_checkpoint_path(latest)) in message


def test_without_a_previous_checkpoint_the_damage_is_the_error(tmp_path):
    latest = tmp_path / "latest.pt"
    latest.write_bytes(b"garbage")
    with pytest.raises(CheckpointError, match="not a readable checkpoint"):
        load_latest_checkpoint(latest)


def _write_forever(path: str) -> None:
    """Save checkpoints as fast as possible, numbered on from the last one written (as a resumed run would)."""
    step = load_checkpoint(path)["counters"]["iteration"] if os.path.exists(path) else 0
    while True:
        step += 1
        save_checkpoint(payload(step, size=200_000), path, keep_previous=True)  # about 0.8 MB a file


@pytest.mark.parametrize("kills", [12])
def test_a_kill_9_at_any_moment_of_a_write_leaves_loadable_checkpoints(tmp_path, kills, writers):
    """A writer saving as fast as it can is killed (SIGKILL) at random moments; after each kill ``latest.pt`` and
    ``latest.previous.pt`` load, their iterations are in order, and the next writer clears the temporary file."""
    latest = tmp_path / "latest.pt"
    generator = random.Random(0)
    last_seen = 0
    for _ in range(kills):
        writer = writers.Process(target=_write_forever, args=(str(latest),))
        writer.start()
        deadline = time.monotonic() + 30
        while not latest.exists():
            assert time.monotonic() < deadline and writer.is_alive(), "the writer wrote nothing"
            time.sleep(0.005)
        time.sleep(generator.uniform(0.0, 0.15))
        os.kill(writer.pid, signal.SIGKILL)
        writer.join()
        step = load_checkpoint(latest)["counters"]["iteration"]
        assert step >= last_seen
        previous = previous_checkpoint_path(latest)
        if previous.exists():
            assert load_checkpoint(previous)["counters"]["iteration"] <= step
        last_seen = step
    assert len(list(tmp_path.glob(".latest.pt.*.tmp"))) <= 1  # at most the killed write's own


def _save_under_a_file_size_limit(path: str, limit: int, result) -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # as python -m agrl.train does: the write fails, no kill
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    try:
        save_checkpoint(payload(2, size=100_000), path, keep_previous=True)
        result.put("written")
    except CheckpointError as error:
        result.put(str(error))


def test_a_full_disk_is_one_line_and_keeps_the_previous_checkpoint(tmp_path, writers):
    latest = tmp_path / "latest.pt"
    save_checkpoint(payload(1, size=1000), latest, keep_previous=True)
    before = latest.read_bytes()
    result = writers.Queue()
    writer = writers.Process(target=_save_under_a_file_size_limit, args=(str(latest), 100_000, result))
    writer.start()
    writer.join(timeout=60)
    message = result.get(timeout=5)
    assert message.startswith(f"{latest}: could not write the checkpoint (") and "\n" not in message, message
    assert message.endswith("; the files there before are kept")
    assert latest.read_bytes() == before
    assert not list(tmp_path.glob(".*.tmp"))


# ---------------------------------------------------------------------------- resume through the command line
def test_resume_steps_over_a_truncated_latest(tmp_path, tiny_run, run_cli):
    """A copy of a finished tiny run whose latest.pt was cut short resumes from latest.previous.pt, saying so in
    one line, and trains on from that iteration."""
    run = tmp_path / "run"
    shutil.copytree(tiny_run.run_dir, run)
    latest = run / "checkpoints" / "latest.pt"
    previous = previous_checkpoint_path(latest)
    iteration = load_checkpoint(previous)["counters"]["iteration"]
    assert iteration == tiny_run.iterations - 1  # checkpoint_interval=1: the one before the last
    latest.write_bytes(latest.read_bytes()[: latest.stat().st_size // 2])
    frames = load_checkpoint(previous)["counters"]["frames"]
    # Two more iterations (the second replaces the first's latest, so the kept previous is whole again); no
    # periodic evaluation and a 4-episode final one, which this test does not read (eval.* may change on resume).
    result = run_cli("train", f"resume={run}", f"ppo.total_frames={frames + 2 * 512}", "eval.interval=0",
                     "eval.episodes=4")
    assert result.returncode == 0, result.stderr[-3000:]
    # Hydra's log: the console (standard output) and the run's train.log.
    for log in (result.stdout, (run / "train.log").read_text()):
        notes = [line for line in log.splitlines() if "going on from the checkpoint before it" in line]
        assert len(notes) == 1 and str(latest) in notes[0] and "truncated" in notes[0], log[-3000:]
        assert notes[0].endswith(f"(the damaged file is kept as {latest}.damaged)")
    assert json.loads(result.stdout.splitlines()[-1])["iterations"] == iteration + 2
    assert load_checkpoint(latest)["counters"]["iteration"] == iteration + 2
    assert load_checkpoint(previous)["counters"]["iteration"] == iteration + 1  # whole again, not the damaged one
