"""``python -m agrl.evaluate``: reproducible results, its output files, task overrides, threads, bad checkpoints and
bad command lines."""

from __future__ import annotations

import csv
import json

import pytest
import torch

from agrl.evaluate import evaluate
from agrl.report import read_metrics
from agrl.rl.checkpoint import load_checkpoint

pytestmark = pytest.mark.usefixtures("torch_one_thread")

TIMING_FIELDS = ("ms_per_instruction",)


def without_timing(summary: dict) -> str:
    """The summary minus timings, as canonical JSON text (so that NaN compares equal to NaN)."""
    kept = {key: value for key, value in summary.items() if key not in TIMING_FIELDS}
    return json.dumps(kept, sort_keys=True)


def read_csv(path):
    with path.open(newline="") as file:
        return list(csv.DictReader(file))


@pytest.fixture(scope="module")
def cli_runs(tiny_run, run_cli, tmp_path_factory):
    """The evaluation CLI on the shared tiny run, on a corrupt checkpoint and on two bad command lines, run at once
    as real processes; the other bad command lines through the same checks in process (``run_cli.checks``: each
    is refused before Hydra runs, where a real process would add only its start-up)."""
    directory = tmp_path_factory.mktemp("evaluate_cli")
    truncated = directory / "truncated.pt"
    data = (tiny_run.run_dir / "checkpoints" / "best.pt").read_bytes()
    truncated.write_bytes(data[: len(data) // 3])
    refused = {case: ("evaluate", *arguments, f"hydra.run.dir={directory / case}")
               for case, (arguments, _) in ONE_LINE_ERRORS.items()}
    processes = run_cli.batch({
        "seed3": ("evaluate", f"checkpoint={tiny_run.run_dir}", "episodes=20", "seed=3",
                  f"hydra.run.dir={directory / 'seed3'}"),
        "truncated": ("evaluate", f"checkpoint={truncated}", f"hydra.run.dir={directory / 'truncated'}"),
        **{case: refused[case] for case in REAL_PROCESS_CASES},
    })
    in_process = {case: run_cli.checks(*job) for case, job in refused.items() if case not in REAL_PROCESS_CASES}
    return {"directory": directory, "truncated_file": truncated, **in_process, **processes}


#: Bad command lines and what their one-line error must say: {case: (arguments, fragments of the line)}.
ONE_LINE_ERRORS = {
    "no-checkpoint": ((), ("checkpoint is required", "a run directory, or a shipped agent (baseline, "
                           "baseline-first-search, baseline-two-stage, baseline-stage1, baseline-both-terms, "
                           "baseline-targets, baseline-absolute)")),
    "speed-without-task": (("checkpoint=baseline", "speed=50"),
                           ("speed=50.0 is not allowed without task=", "give task=uniform or curved")),
    "task-foo": (("checkpoint=baseline", "task=foo"), ("task=foo is not allowed: one of curved, fixed",)),
    "episodes-key": (("checkpoint=baseline", "episode=5"), ("episode=5 is not allowed", "no key 'episode'",
                                                            "episodes")),
    "zero-threads": (("checkpoint=baseline", "threads=0"), ("threads=0 is not allowed",)),
    "missing-checkpoint": (("checkpoint=no/such.pt",), ("checkpoint: no/such.pt: no such checkpoint file",)),
    "unwritable-output": (("checkpoint=baseline", "output_dir=/dev/null/evaluation"),
                          ("output_dir=/dev/null/evaluation is not allowed: /dev/null/evaluation/eval.json: cannot be "
                           "written: /dev/null is a file, not a folder",)),
}

#: Bad command lines that run as real processes too: a missing key, and an output folder that cannot be written.
REAL_PROCESS_CASES = ("no-checkpoint", "unwritable-output")


@pytest.mark.parametrize("case", sorted(ONE_LINE_ERRORS))
def test_bad_command_line_exits_2_with_one_line(cli_runs, case):
    result = cli_runs[case]
    assert result.returncode == 2, result.stderr[-3000:]
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, lines
    assert lines[0].startswith("agrl.evaluate: error: ")
    for fragment in ONE_LINE_ERRORS[case][1]:
        assert fragment in lines[0]
    assert not (cli_runs["directory"] / case).exists()


def test_threads_sets_torchs_intra_op_threads(tiny_run, compose_evaluate, tmp_path):
    # From two threads to the one asked for, so that the evaluation runs on one: two OpenMP threads on a busy
    # 2-core machine spin and wait (tests/conftest.py), and its 200 timed instructions would take seconds.
    config = compose_evaluate(f"checkpoint={tiny_run.run_dir}", "episodes=4", "trajectories=0", "threads=1",
                              f"output_dir={tmp_path}")
    torch.set_num_threads(2)
    try:
        evaluate(config)
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(1)  # this module's one thread (torch_one_thread)


def test_evaluate_cli_writes_summary_and_files(cli_runs, tiny_run):
    result = cli_runs["seed3"]
    assert result.returncode == 0, result.stderr[-3000:]
    output = cli_runs["directory"] / "seed3"
    summary = json.loads(result.stdout.strip().splitlines()[-1])
    assert json.dumps(summary) == json.dumps(json.loads((output / "eval.json").read_text()))
    for key in ("success_rate", "instructions_per_episode", "ms_per_instruction", "outcomes"):
        assert key in summary
    assert summary["episodes"] == 20
    assert summary["seed"] == 3
    assert summary["checkpoint"] == str(tiny_run.run_dir / "checkpoints" / "latest.pt")
    assert (summary["task"], summary["trained_task"], summary["method"]) == ("fixed", "fixed", "scratch")
    rows = read_csv(output / "episodes.csv")
    assert len(rows) == 20
    assert summary["outcomes"]["success"] == sum(row["outcome"] == "success" for row in rows)
    assert (output / "trajectories.png").stat().st_size > 1000


def test_same_seed_gives_the_same_evaluation(cli_runs, tiny_run, compose_evaluate, tmp_path):
    """The CLI run above and an in-process evaluation with the same arguments agree exactly."""
    assert cli_runs["seed3"].returncode == 0, cli_runs["seed3"].stderr[-3000:]
    cli_output = cli_runs["directory"] / "seed3"
    config = compose_evaluate(f"checkpoint={tiny_run.run_dir}", "episodes=20", "seed=3",
                              f"output_dir={tmp_path / 'again'}")
    again = evaluate(config)
    assert without_timing(again) == without_timing(json.loads((cli_output / "eval.json").read_text()))
    assert (tmp_path / "again" / "episodes.csv").read_bytes() == (cli_output / "episodes.csv").read_bytes()

    config = compose_evaluate(f"checkpoint={tiny_run.run_dir}", "episodes=20", "seed=4", "trajectories=0",
                              f"output_dir={tmp_path / 'other'}")
    evaluate(config)
    assert (tmp_path / "other" / "episodes.csv").read_bytes() != (cli_output / "episodes.csv").read_bytes()
    assert not (tmp_path / "other" / "trajectories.png").exists()  # trajectories=0: no figure


def test_task_override_is_honoured(cli_runs, tiny_run, compose_evaluate, tmp_path):
    config = compose_evaluate(f"checkpoint={tiny_run.run_dir}", "episodes=20", "seed=3", "task=uniform",
                              "speed=20", "trajectories=0", f"output_dir={tmp_path}")
    summary = evaluate(config)
    saved = json.loads((tmp_path / "eval.json").read_text())
    assert json.dumps(saved, sort_keys=True) == json.dumps(summary, sort_keys=True)
    assert (summary["task"], summary["speed"], summary["trained_task"]) == ("uniform", 20.0, "fixed")
    # A destination moving at 20 m/s changes the episodes' end points (same seed, same starts otherwise).
    fixed = read_csv(cli_runs["directory"] / "seed3" / "episodes.csv")
    moving = read_csv(tmp_path / "episodes.csv")
    assert [row["final_distance_m"] for row in moving] != [row["final_distance_m"] for row in fixed]


def test_corrupt_checkpoint_exits_2_with_one_line(cli_runs):
    result = cli_runs["truncated"]
    assert result.returncode == 2, result.stderr[-3000:]
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, lines
    assert lines[0].startswith("agrl.evaluate: error:")
    assert str(cli_runs["truncated_file"]) in lines[0]
    assert "not a readable checkpoint" in lines[0]
    assert not (cli_runs["directory"] / "truncated").exists()  # read before Hydra runs: nothing written


def test_evaluating_a_best_checkpoint_file(tiny_run, compose_evaluate, tmp_path):
    best = tiny_run.run_dir / "checkpoints" / "best.pt"
    summary = evaluate(compose_evaluate(f"checkpoint={best}", "episodes=8", "trajectories=0",
                                        f"output_dir={tmp_path}"))
    assert summary["checkpoint"] == str(best)
    assert summary["episodes"] == 8
    # Written at the best periodic evaluation: its recorded success is the highest logged.
    periodic = [row["eval/success_rate"] for row in read_metrics(tiny_run.run_dir)[1:] if "eval/success_rate" in row]
    assert load_checkpoint(best)["counters"]["best_success"] == max(periodic)
