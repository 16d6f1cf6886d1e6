"""Smoke test of ``python -m benchmarks.bench_reuse --quick``: output format and counts, no timing assertions."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.bench_reuse import parse_args

#: The benchmarks run in a temporary folder and import from the repository root.
REPO = Path(__file__).resolve().parents[1]


#: The runs of ``python -m benchmarks.bench_reuse`` tested here: {name: its arguments}.
QUICK_RUNS = {"candidates": ("--quick", "--candidates", "2", "4"),
              "after_training": ("--quick", "--candidates", "2", "--iterations", "1")}


@pytest.fixture(scope="module")
def quick_runs(tmp_path_factory, run_at_once) -> dict[str, subprocess.CompletedProcess]:
    """Each of :data:`QUICK_RUNS`, all at once, each in its own temporary folder."""
    # Small tensors: one thread (see conftest).
    environment = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    commands = {name: [sys.executable, "-m", "benchmarks.bench_reuse", *arguments]
                for name, arguments in QUICK_RUNS.items()}
    folders = {name: tmp_path_factory.mktemp(name) for name in QUICK_RUNS}
    return run_at_once(commands, folders, environment, timeout=600)


def test_quick_run_times_each_candidate_count(quick_runs):
    completed = quick_runs["candidates"]
    assert completed.returncode == 0, completed.stderr
    records = [json.loads(line) for line in completed.stdout.splitlines() if line.strip()]
    assert [record["name"] for record in records] == ["machine", "reuse_relabel", "reuse_relabel"]
    timed = records[1:]
    assert [record["candidates"] for record in timed] == [2, 4]
    for record in timed:
        assert record["unit"] == "s per batch" and record["value"] > 0 and record["cpu_seconds"] > 0
        # Every relabelled episode is simulated at least once in the search and once in the replay.
        assert record["simulated_row_decisions"] >= 2 * record["episodes_relabelled"]
        assert record["batch_rows"] == 64 * 16
        # e = 1: every episode starting in the batch is selected, and the untrained agent's are short.
        assert record["episodes_selected"] >= 64
        assert 0 <= record["episodes_relabelled"] <= record["episodes_selected"]
        assert 0.0 <= record["reuse_fraction"] <= 1.0 and record["rows_stored"] > 0
        assert sum(record["row_decisions_by_call_rows"].values()) == record["simulated_row_decisions"]
        assert 0 < record["time_loop_steps"] <= record["simulated_row_decisions"]
        assert record["episodes_searched"] == record["episodes_selected"] and record["episodes_carried"] == 0


def test_after_training_iterations_the_batch_continues_episodes_of_the_one_before(quick_runs):
    completed = quick_runs["after_training"]
    assert completed.returncode == 0, completed.stderr
    # JSON lines only: the trainer's replay buffer logs a line when it first fills, which goes to stderr.
    records = [json.loads(line) for line in completed.stdout.splitlines()]
    assert "Initialized LazyTensorStorage" in completed.stderr
    assert [record["name"] for record in records] == ["machine", "reuse_training_iteration", "reuse_relabel"]
    trained, record = records[1:]
    # The training iteration's relabelling is counted like the timed one (the collection's steps are not).
    assert trained["iteration"] == 1 and trained["episodes_carried"] == 0 and trained["cpu_seconds"] > 0
    assert sum(trained["row_decisions_by_call_rows"].values()) == trained["simulated_row_decisions"] > 0
    assert record["selection_factor"] == trained["selection_factor"]
    assert record["iterations_before"] == 1
    assert record["selection_factor"] < 1.0, "e as the first iteration left it, not reset to 1"
    # 16 decisions per env per batch: episodes that began in the first batch continue in the second.
    assert record["episodes_carried"] > 0


def test_arguments():
    default = parse_args([])
    assert default.candidates == [8, 16, 32] and default.repeats == 3
    assert default.iterations == 0 and default.selection_factor == 1.0
    assert parse_args(["--iterations", "3"]).selection_factor is None, "with iterations: the e training reached"
    assert default.overrides == ["task=uniform", "speed=50", "method=reuse", "progress=false"]
    custom = parse_args(["task=curved", "radius=500", "--candidates", "16", "--selection-factor", "0.5"])
    assert custom.overrides[:2] == ["task=curved", "radius=500"] and custom.selection_factor == 0.5


@pytest.mark.parametrize("argv", [["--selection-factor", "1.5"], ["--candidates", "0"], ["--iterations", "-1"]])
def test_bad_arguments_are_one_line_errors(argv, capsys):
    with pytest.raises(SystemExit):
        parse_args(argv)
    assert "is not allowed" in capsys.readouterr().err
