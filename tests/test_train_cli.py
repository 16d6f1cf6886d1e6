"""``python -m agrl.train`` end to end: outputs of a tiny run, Ctrl-C, resume, and command-line errors."""

from __future__ import annotations

import csv
import io
import json
import random
import signal
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

from agrl.report import read_metrics
from agrl.rl.checkpoint import CheckpointError, load_checkpoint
from agrl.rl.stop_signals import PREEMPTED_EXIT_CODE, PREEMPTED_MARKER
from agrl.rl.trainer import Trainer

TRAINING_STATE = ("actor", "critic", "optimizer", "counters", "carrier", "rng", "config")


def read_csv(path):
    with path.open(newline="") as file:
        return list(csv.DictReader(file))


def error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.strip()]


def periodic_success_of(checkpoint) -> float:
    """Success of a training checkpoint's actor on its run's periodic evaluation set (eval.periodic_episodes
    episodes from the evaluation seed, seed + 1000003), evaluated here from the saved actor and config."""
    from agrl.envs.guidance import GuidanceEnv
    from agrl.rl.evaluation import run_episodes, summarise
    from agrl.rl.models import load_agent

    actor, saved, _ = load_agent(str(checkpoint))
    env = GuidanceEnv.for_saved_agent(saved, saved["eval"]["periodic_episodes"], seed=saved["seed"] + 1_000_003,
                                      compile=False)
    return summarise(run_episodes(env, actor))["success_rate"]


# ---------------------------------------------------------------------------- the shared tiny run
def test_tiny_run_writes_checkpoints_metrics_and_evaluation(tiny_run):
    run = tiny_run.run_dir
    for name in ("latest", "best"):
        payload = load_checkpoint(run / "checkpoints" / f"{name}.pt", required=TRAINING_STATE)
        assert payload["run_dir"] == str(run)
    latest = load_checkpoint(run / "checkpoints" / "latest.pt")
    assert latest["counters"]["iteration"] == tiny_run.iterations
    assert latest["counters"]["frames"] == int(tiny_run.changes["ppo.total_frames"])
    assert latest["config"]["ppo"]["num_envs"] == 32
    assert not list((run / "checkpoints").glob("*.tmp")), "temporary checkpoint files left behind"

    rows = read_metrics(run)
    # Row 0: the evaluation of the initial policy, before any training.
    assert [int(row["iteration"]) for row in rows] == list(range(0, tiny_run.iterations + 1))
    assert [int(row["frames"]) for row in rows] == [512 * i for i in range(0, tiny_run.iterations + 1)]
    assert "train/success_rate" not in rows[0] and rows[0]["wall_time"] == 0.0
    # Periodic evaluation every 2 iterations (eval.interval=2), training success every iteration.
    assert ["eval/success_rate" in row for row in rows] == [True, False, True, False, True]
    # best.pt is the first iteration with the best periodic evaluation, and its counters record that success.
    evaluations = {int(row["iteration"]): row["eval/success_rate"] for row in rows[1:] if "eval/success_rate" in row}
    top = max(evaluations.values())
    best = load_checkpoint(run / "checkpoints" / "best.pt")
    assert best["counters"]["iteration"] == min(i for i, success in evaluations.items() if success == top)
    assert best["counters"]["best_success"] == pytest.approx(top, abs=1e-6)
    # The last periodic evaluation is the final actor's on the fixed periodic set: evaluate it again here.
    assert rows[-1]["eval/success_rate"] == periodic_success_of(run / "checkpoints" / "latest.pt")

    assert (run / "eval" / "trajectories.png").stat().st_size > 1000
    episodes = read_csv(run / "eval" / "episodes.csv")
    assert len(episodes) == 16  # eval.episodes: one row per episode
    assert [int(row["episode"]) for row in episodes] == list(range(16))
    assert {row["outcome"] for row in episodes} <= {"success", "out_of_airspace", "budget_exhausted"}
    assert all(1 <= int(row["decisions"]) <= 30 for row in episodes)  # simulation.max_decisions=30

    evaluation = json.loads((run / "eval" / "eval.json").read_text())
    assert evaluation["episodes"] == 16
    assert sum(evaluation["outcomes"].values()) == 16
    successes = sum(row["outcome"] == "success" for row in episodes)
    assert evaluation["success_rate"] == successes / 16
    assert evaluation["outcomes"]["success"] == successes
    mean_instructions = sum(int(row["instructions"]) for row in episodes) / 16
    assert evaluation["instructions_per_episode"] == pytest.approx(mean_instructions)
    assert evaluation["iterations"] == tiny_run.iterations


def test_tiny_run_prints_json_summary_on_last_line(tiny_run):
    summary = json.loads(tiny_run.stdout.strip().splitlines()[-1])
    for key in ("success_rate", "instructions_per_episode", "ms_per_instruction", "outcomes"):
        assert key in summary
    assert summary["ms_per_instruction"] > 0
    # The processor path and threads it was trained with: a run repeats bit for bit only on the same ones.
    machine = summary["machine"]
    assert (machine["cpu_capability"], machine["torch"]) == (torch.backends.cpu.get_cpu_capability(), torch.__version__)
    assert machine["cpu"] and isinstance(machine["threads"], int) and machine["threads"] >= 1
    # What a sweeper reads (the config's search section): this untrained run misses 99.5 %, so it pays 60 s per
    # point of success short (and per instruction over 7) on top of its seconds of training.
    short, over = 100 * max(0.0, 0.995 - summary["success_rate"]), max(0.0, summary["instructions_per_episode"] - 7)
    assert summary["search_objective"] == pytest.approx(summary["training_wall_time_s"] + 60 * (short + over))
    assert short > 0
    saved = json.loads((tiny_run.run_dir / "eval" / "eval.json").read_text())
    assert json.dumps(summary, sort_keys=True) == json.dumps(saved, sort_keys=True)  # NaN == NaN as text


def test_tiny_run_tensorboard_scalars(tiny_run):
    directory = tiny_run.run_dir / "tensorboard"
    assert list(directory.glob("events.out.tfevents.*"))
    events = EventAccumulator(str(directory), size_guidance={"scalars": 0})
    events.Reload()
    tags = set(events.Tags()["scalars"])
    for tag in ("train/success_rate", "loss/clip_fraction", "time/decisions_per_second", "eval/success_rate"):
        assert tag in tags, f"{tag} missing from {sorted(tags)}"
    assert "loss/clip_fraction_relabelled" not in tags  # a scratch run has no relabelled rows to measure
    steps = [event.step for event in events.Scalars("time/decisions_per_second")]
    assert steps == [512 * i for i in range(1, tiny_run.iterations + 1)]
    assert [event.step for event in events.Scalars("eval/success_rate")] == [0, 1024, 2048]
    # Training success is a count of successful episodes over the episodes that ended in the iteration.
    episodes = [event.value for event in events.Scalars("train/episodes")]
    successes = [rate.value * count for rate, count in zip(events.Scalars("train/success_rate"), episodes,
                                                             strict=True)]
    assert all(count >= 1 and count == int(count) for count in episodes), episodes
    assert all(abs(value - round(value)) < 1e-4 and 0 <= round(value) <= count
               for value, count in zip(successes, episodes, strict=True)), (successes, episodes)
    rows = read_metrics(tiny_run.run_dir)[1:]  # the report's rows: one per iteration, as TensorBoard has them
    assert [row["train/success_rate"] for row in rows] == [event.value
                                                            for event in events.Scalars("train/success_rate")]
    # The clip fraction of an iteration is the mean over its 4 minibatches of 128 rows (512 decisions, one
    # epoch) of a 0/1 flag per row: a whole number of 512ths.
    for event in events.Scalars("loss/clip_fraction"):
        assert event.value * 512 == round(event.value * 512) and 0 <= event.value <= 1, event.value


def test_tiny_run_tensorboard_trajectory_images(tiny_run):
    """Each periodic evaluation (before training, after iterations 2 and 4) logs its trajectory figure."""
    events = EventAccumulator(str(tiny_run.run_dir / "tensorboard"), size_guidance={"images": 0})
    events.Reload()
    images = events.Images("eval/trajectories")
    assert [image.step for image in images] == [0, 1024, 2048]
    for image in images:
        picture = np.asarray(Image.open(io.BytesIO(image.encoded_image_string)).convert("RGB"))
        assert picture.shape == (image.height, image.width, 3) and min(image.height, image.width) >= 300
        # A drawn figure (box, paths in outcome colours, legend), not a blank canvas: its distinct colours, each
        # packed into one integer (np.unique of the pixel rows, axis=0, counts the same, fifty times slower).
        colours = (picture[..., 0].astype(np.int32) << 16) | (picture[..., 1].astype(np.int32) << 8) | picture[..., 2]
        assert len(np.unique(colours)) > 50


# ---------------------------------------------------------------------------- Ctrl-C and pre-emption
#: Iterations of a pre-empted run (the signal comes after the first; the same command finishes the rest). The run
#: stops after the iteration the signal arrives in, the second or third: the others are a margin for a busy machine.
PREEMPTED_ITERATIONS = 6
#: The signals sent, each to its own run: Ctrl-C, and SIGTERM, what Slurm sends before a pre-emption or a time limit.
#: SIGUSR1 and SIGUSR2 take SIGTERM's path through the trainer (one StopSignals flag): that each of them sets it is
#: tested in tests/rl/test_stop_signals.py, and SIGUSR2 end to end under submitit in tests/test_submitit_requeue.py.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


#: Seconds a run may take to exit after its signal (a scheduler's grace period is about 30 s).
EXIT_WITHIN = {"SIGINT": 60, "SIGTERM": 30}


@dataclass
class StoppedRun:
    run: Path
    arguments: tuple[str, ...]
    signalled: float  # time.time() when the signal was sent
    code: int
    stderr: str
    checkpoints: Path  # a copy of run/checkpoints as the stopped run left it (times kept)
    again: subprocess.CompletedProcess | None = None  # the same command run again (not for SIGINT)


@pytest.fixture(scope="module")
def stopped_runs(run_cli, tiny_args, tmp_path_factory) -> dict[str, StoppedRun]:
    """One ``python -m agrl.train`` run per signal of :data:`STOP_SIGNALS`, all at once; each gets its signal as
    soon as its first iteration is logged, snapshot included. Then the pre-empted ones' commands run again, at
    once (after their checkpoints were copied). No periodic ``latest`` (checkpoint_interval=1000): a checkpoint
    must come from the signal."""
    import shutil

    folder = tmp_path_factory.mktemp("stopped")
    runs, processes, files = {}, {}, []
    try:
        for stop_signal in STOP_SIGNALS:
            name, run = stop_signal.name, folder / stop_signal.name / "run"
            (folder / name).mkdir()
            frames = 10**9 if stop_signal == signal.SIGINT else 512 * PREEMPTED_ITERATIONS
            arguments = (*tiny_args({"ppo.total_frames": frames, "checkpoint_interval": 1000}),
                         f"hydra.run.dir={run}")
            out, err = (folder / name / "stdout").open("w"), (folder / name / "stderr").open("w")
            files += [out, err]
            # Ctrl-C: the default SIGINT handler (KeyboardInterrupt), even if the test runner ignores SIGINT.
            default_sigint = (lambda: signal.signal(signal.SIGINT, signal.SIG_DFL)) if stop_signal == signal.SIGINT \
                else None
            processes[name] = (stop_signal, subprocess.Popen(
                run_cli.command("train", *arguments), cwd=run_cli.cwd, env=run_cli.environment(), stdout=out,
                stderr=err, preexec_fn=default_sigint))
            runs[name] = (run, arguments)
        deadline = time.monotonic() + 120
        signalled, event_bytes = {}, {}
        while len(signalled) < len(processes):
            for name, (stop_signal, process) in processes.items():
                if name in signalled:
                    continue
                run = runs[name][0]
                assert process.poll() is None, (folder / name / "stderr").read_text()[-3000:]
                # Parse the events only when they grew (parsing them 50 times a second would take a core).
                size = sum(path.stat().st_size for path in (run / "tensorboard").glob("events.out.tfevents.*"))
                if size == event_bytes.get(name, 0):
                    continue
                event_bytes[name] = size
                if len(read_metrics(run)) >= 2:  # two logged steps: iteration 1 is complete
                    assert not (run / "checkpoints" / "latest.pt").exists()
                    signalled[name] = time.time()
                    process.send_signal(stop_signal)
            assert time.monotonic() < deadline, "two iterations did not finish within 120 s"
            time.sleep(0.02)
        codes = {name: process.wait(timeout=max(signalled[name] + EXIT_WITHIN[name] - time.time(), 0.1))
                 for name, (_, process) in processes.items()}
    finally:
        for _, process in processes.values():
            if process.poll() is None:
                process.kill()
                process.wait()
        for file in files:
            file.close()
    stopped = {}
    for name, (run, arguments) in runs.items():
        checkpoints = shutil.copytree(run / "checkpoints", folder / name / "checkpoints_when_stopped")
        stopped[name] = StoppedRun(run, arguments, signalled[name], codes[name], (folder / name / "stderr").read_text(),
                                   checkpoints)
    again = run_cli.batch({name: ("train", *runs[name][1]) for name in runs if name != "SIGINT"})
    for name, result in again.items():
        stopped[name].again = result
    return stopped


@pytest.mark.usefixtures("torch_one_thread")
def test_ctrl_c_saves_latest_and_resume_continues(stopped_runs, compose_train, tiny_args):
    stopped = stopped_runs["SIGINT"]
    run = stopped.run
    latest = run / "checkpoints" / "latest.pt"
    assert stopped.code == 130, stopped.stderr[-3000:]
    assert "interrupted: saved the last completed iteration" in (run / "train.log").read_text()
    payload = load_checkpoint(latest, required=TRAINING_STATE)
    iteration, frames = payload["counters"]["iteration"], payload["counters"]["frames"]
    assert iteration >= 1 and frames == 512 * iteration
    assert not list((run / "checkpoints").glob("*.tmp"))

    # A tiny continuation (in process; the command-line resume is tested in tests/rl/test_trainer.py).
    config = compose_train(*tiny_args({"ppo.total_frames": frames + 512, "checkpoint_interval": 1000}))
    summary = Trainer(config, run, resume_payload=payload).train()
    assert summary["iterations"] == iteration + 1
    after = load_checkpoint(latest)
    assert after["counters"]["iteration"] == iteration + 1
    assert after["counters"]["frames"] == frames + 512
    assert [int(row["iteration"]) for row in read_metrics(run)][-1] == iteration + 1


@pytest.mark.parametrize("stop_signal", [signal.SIGTERM], ids=["SIGTERM"])
def test_a_stop_signal_saves_latest_and_the_same_command_resumes(stopped_runs, stop_signal):
    """What Slurm and submitit send before a pre-emption or a time limit: a checkpoint newer than the signal, a
    distinct exit code within 30 s, one line saying how to resume; the same command run again (a requeued job)
    resumes the run and finishes it."""
    stopped = stopped_runs[stop_signal.name]
    run = stopped.run
    latest = run / "checkpoints" / "latest.pt"
    assert stopped.code == PREEMPTED_EXIT_CODE, stopped.stderr[-3000:]
    # What the stopped run left (a copy made before the command ran again):
    assert (stopped.checkpoints / "latest.pt").stat().st_mtime >= stopped.signalled
    line = f"agrl.train: stopped by {stop_signal.name}: saved the last completed iteration to {latest}; " \
           f"resume with: python -m agrl.train resume={run}"
    assert line in stopped.stderr.splitlines(), stopped.stderr[-3000:]
    stopped_at = load_checkpoint(stopped.checkpoints / "latest.pt", required=TRAINING_STATE)["counters"]["iteration"]
    assert 1 <= stopped_at < PREEMPTED_ITERATIONS
    assert json.loads((stopped.checkpoints / PREEMPTED_MARKER).read_text()) == {"signal": stop_signal.name,
                                                                                  "iteration": stopped_at}

    again = stopped.again
    marker = run / "checkpoints" / PREEMPTED_MARKER
    assert again.returncode == 0, again.stderr[-3000:]
    assert f"{run} was pre-empted: resuming it from its last checkpoint" in again.stdout
    assert f"resumed from {latest} after iteration {stopped_at}" in again.stdout
    assert json.loads(again.stdout.splitlines()[-1])["iterations"] == PREEMPTED_ITERATIONS
    assert not marker.exists()


# ---------------------------------------------------------------------------- command-line errors
#: Bad command lines and what their one-line error must say: {case: (arguments, fragments of the line)}.
ONE_LINE_ERRORS = {
    "sped": (("sped=5",), ("sped=5 is not allowed", "the config has no key 'sped'", "speed")),
    "added-key": (("+ppo.learning_rat=0.001",), ("+ppo.learning_rat=0.001 is not allowed", "ppo has no key",
                                                  "learning_rate")),
    "ppo-key": (("ppo.num_env=64",), ("ppo.num_env=64 is not allowed", "ppo has no key 'num_env'", "num_envs")),
    "task-foo": (("task=foo",), ("task=foo is not allowed: one of curved, fixed, irregular, uniform",)),
    "experiment-foo": (("+experiment=fsat",),
                       ("+experiment=fsat is not allowed: one of fast, recipe_search, switch_finetune",)),
    "seed-type": (("seed=abc",), ("seed=abc is not allowed", "could not be converted to Integer")),
    "negative-speed": (("task=uniform", "speed=-5"), ("speed=-5.0 is not allowed", "in (0, 1000] m/s")),
    "zero-envs": (("ppo.num_envs=0",), ("ppo.num_envs=0 is not allowed",)),
    "unused-speed": (("speed=50",), ("speed=50.0 is not allowed: task=fixed has no destination speed",
                                     "only task=uniform or curved")),
    "unused-radius": (("task=uniform", "radius=500"), ("radius=500.0 is not allowed", "only task=curved")),
    "sweep-value": (("-m", "task=uniform", "speed=10,-20"), ("speed=-20.0 is not allowed",)),
    "sweep-without-m": (("seed=0,1",), ("seed=0,1 is not allowed: a sweep needs -m",)),
    "missing-baseline": (("method=pretrained", "method.baseline=no/such.pt"),
                         ("method.baseline: no/such.pt: no such checkpoint file or run directory; allowed: a "
                          "checkpoint file, a run directory, or a shipped agent (baseline, baseline-first-search, "
                          "baseline-two-stage, baseline-stage1, baseline-both-terms, baseline-targets, "
                          "baseline-absolute)",)),
    "resume-missing": (("resume=no/such/run",), ("resume: no/such/run: no such checkpoint file or run directory",)),
    "resume-shipped-agent": (("resume=baseline",),
                             ("resume=baseline is not allowed: baseline is a shipped agent, not a training run",
                              "method=pretrained method.baseline=baseline")),
}


#: Refused command lines that run as real processes, at once, one for each stage a refusal can come from: a mistyped
#: key (agrl.cli's checks of the overrides), a file the checks load (the entry point's input checks, which import
#: more), and the corrupt checkpoint of a resume (read once Hydra runs). The others are refused at the first two
#: stages, before Hydra runs, and run them in process (``run_cli.checks``, agrl.cli.run_checked as the module's
#: ``__main__`` calls it): a real process would add only its start-up, the same as its stage's real process has.
REAL_PROCESS_CASES = ("sped", "baseline-random-bytes", "resume-random-bytes")


@pytest.fixture(scope="module")
def bad_invocations(run_cli, tmp_path_factory):
    """Every failing invocation of this module: {case: CompletedProcess}, and ``directory``: each case's run (and
    sweep) directory is ``directory / case``, which must not be created."""
    directory = tmp_path_factory.mktemp("bad_train")
    bad = directory / "random.pt"
    bad.write_bytes(random.Random(7).randbytes(4096))
    jobs = {case: ("train", *arguments, f"hydra.run.dir={directory / case}", f"hydra.sweep.dir={directory / case}")
            for case, (arguments, _) in ONE_LINE_ERRORS.items()}
    jobs["resume-random-bytes"] = ("train", f"resume={bad}", f"hydra.run.dir={directory / 'run'}")
    jobs["baseline-random-bytes"] = ("train", "method=pretrained", f"method.baseline={bad}",
                                     f"hydra.run.dir={directory / 'baseline-random-bytes'}")
    in_process = {case: run_cli.checks(*job) for case, job in jobs.items() if case not in REAL_PROCESS_CASES}
    processes = run_cli.batch({case: jobs[case] for case in REAL_PROCESS_CASES})
    return {"bad_file": bad, "directory": directory, **in_process, **processes}


@pytest.mark.parametrize("case", sorted(ONE_LINE_ERRORS))
def test_bad_command_line_exits_2_with_one_line_naming_it(bad_invocations, case):
    """Mistyped keys, options and values, and overrides the task would ignore, stop before Hydra runs: one line
    naming the override and what is allowed, exit code 2, and no run directory."""
    result = bad_invocations[case]
    assert result.returncode == 2, result.stderr[-3000:]
    lines = error_lines(result.stderr)
    assert len(lines) == 1, lines
    assert lines[0].startswith("agrl.train: error: ")
    for fragment in ONE_LINE_ERRORS[case][1]:
        assert fragment in lines[0]
    assert not (bad_invocations["directory"] / case).exists()


def test_a_baseline_that_is_not_a_checkpoint_stops_before_hydra_runs(bad_invocations):
    result = bad_invocations["baseline-random-bytes"]
    assert result.returncode == 2, result.stderr[-3000:]
    assert error_lines(result.stderr) == [f"agrl.train: error: method.baseline: {bad_invocations['bad_file']}: not a "
                                          "readable checkpoint (corrupt or truncated?)"]
    assert not (bad_invocations["directory"] / "baseline-random-bytes").exists()


def test_resume_from_corrupt_checkpoint_exits_2_naming_the_file(bad_invocations):
    result = bad_invocations["resume-random-bytes"]
    assert result.returncode == 2, result.stderr[-3000:]
    lines = error_lines(result.stderr)
    assert len(lines) == 1, lines
    assert lines[0].startswith("agrl.train: error:")
    assert str(bad_invocations["bad_file"]) in lines[0]


# ---------------------------------------------------------------------------- bad inputs of runs that start
@pytest.fixture(scope="module")
def bad_runs(run_cli, tiny_run, tiny_args, tmp_path_factory):
    """Invocations that get past the config's schema and fail when the run starts, and refusals of a method's
    and a resume's settings."""
    import shutil

    import torch

    from agrl.rl.checkpoint import save_checkpoint

    directory = tmp_path_factory.mktemp("bad_runs")
    # A baseline whose critic holds a NaN: the value targets and hence the first PPO loss are NaN.
    payload = load_checkpoint(tiny_run.run_dir / "checkpoints" / "latest.pt")
    critic = {key: value.clone() for key, value in payload["critic"].items()}
    next(iter(critic.values())).view(-1)[0] = float("nan")
    nan_baseline = save_checkpoint({**payload, "critic": critic}, directory / "nan_critic.pt")
    assert not torch.isfinite(next(iter(critic.values()))).all()
    # A copy of the shared tiny run to resume (the shared one stays read-only).
    resumable = directory / "resumable"
    shutil.copytree(tiny_run.run_dir, resumable)
    # Refused when the run starts: real processes, at once.
    started = run_cli.batch({
        "diverges": ("train", *tiny_args(), "method=pretrained", f"method.baseline={nan_baseline}",
                     f"hydra.run.dir={directory / 'diverges'}"),
        "stride-over-budget": ("train", *tiny_args(), "method=reuse", "method.candidate_stride=31",
                               f"hydra.run.dir={directory / 'stride'}"),
    })
    # Refused before Hydra runs: agrl.cli's checks, in process (as most of ONE_LINE_ERRORS).
    refused = {
        "reuse-without-baseline": run_cli.checks("train", *tiny_args(), "method=reuse", "method.baseline=null",
                                                 f"hydra.run.dir={directory / 'no_baseline'}"),
        "resume-other-num-envs": run_cli.checks("train", f"resume={resumable}", "ppo.num_envs=64",
                                                f"hydra.run.dir={directory / 'resume_hydra'}"),
    }
    return {"directory": directory, "resumable": resumable, **started, **refused}


def single_error_line(result, code: int) -> str:
    assert result.returncode == code, result.stderr[-3000:]
    lines = error_lines(result.stderr)
    assert len(lines) == 1, lines
    return lines[0]


def test_divergence_exits_3_with_the_iteration_and_what_is_kept(bad_runs):
    line = single_error_line(bad_runs["diverges"], 3)
    # It diverged in its first iteration: no checkpoint to point at (a later one names the folder it kept).
    assert line == ("agrl.train: error: non-finite loss (nan) at iteration 1, update 1; "
                    "no checkpoint yet: the run stopped before its first (every checkpoint_interval=1 iterations)")
    assert not (bad_runs["directory"] / "diverges" / "checkpoints" / "latest.pt").exists()


def test_reuse_without_a_baseline_is_one_line(bad_runs):
    line = single_error_line(bad_runs["reuse-without-baseline"], 2)
    assert line == ("agrl.train: error: method.baseline=None is not allowed: "
                    "method=reuse needs a baseline checkpoint (a path, or a shipped agent: baseline, "
                    "baseline-first-search, baseline-two-stage, baseline-stage1, baseline-both-terms, "
                    "baseline-targets, baseline-absolute)")


def test_candidate_stride_beyond_the_decision_budget_is_one_line(bad_runs):
    # tiny_args: simulation.max_decisions=30, so t_n = 31 is never reached.
    line = single_error_line(bad_runs["stride-over-budget"], 2)
    assert line == "agrl.train: error: candidate_stride=31 is not allowed: between 1 and max_decisions=30"


def test_resuming_with_another_num_envs_is_refused_and_leaves_the_run_alone(bad_runs, tiny_run):
    line = single_error_line(bad_runs["resume-other-num-envs"], 2)
    assert line == ("agrl.train: error: ppo.num_envs=64 is not allowed with resume: a resumed run keeps its "
                    "saved config; only ppo.total_frames, ppo.max_minutes, ppo.compile_loss, target_success, progress, "
                    "device, threads, checkpoint_interval, eval.* may be given")
    latest = bad_runs["resumable"] / "checkpoints" / "latest.pt"
    assert latest.read_bytes() == (tiny_run.run_dir / "checkpoints" / "latest.pt").read_bytes()
    assert not (bad_runs["directory"] / "resume_hydra").exists()  # refused before Hydra ran


def test_a_resume_continues_in_its_run_directory_and_log(tiny_run, run_cli, tmp_path):
    """Without hydra.run.dir, a resumed run writes nowhere else: Hydra's log goes on in the run's train.log, and
    its .hydra/ record of the original command stays."""
    import shutil

    run, elsewhere = tmp_path / "run", tmp_path / "working_directory"
    shutil.copytree(tiny_run.run_dir, run)
    elsewhere.mkdir()
    log = (run / "train.log").read_text()
    record = {path.name: path.read_bytes() for path in (run / ".hydra").iterdir()}
    frames = 5 * 512  # 1 iteration more
    result = subprocess.run(run_cli.command("train", f"resume={run}", f"ppo.total_frames={frames}"), cwd=elsewhere,
                            env=run_cli.environment(), capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    assert list(elsewhere.iterdir()) == []
    assert load_checkpoint(run / "checkpoints" / "latest.pt")["counters"]["frames"] == frames
    resumed_log = (run / "train.log").read_text()
    assert resumed_log.startswith(log)
    appended = resumed_log[len(log):]
    assert f"resumed from {run / 'checkpoints' / 'latest.pt'} after iteration 4 (2048 decisions)" in appended
    assert f"training stopped: reached ppo.total_frames={frames}" in appended
    assert "another processor path" not in appended  # the checkpoint's own
    assert {path.name: path.read_bytes() for path in (run / ".hydra").iterdir()} == record


def test_a_resume_on_another_processor_path_says_so(tiny_run, run_cli, tmp_path):
    """Checkpoints record the processor path (agrl.machine.processor_record); a resume on another goes on, with one
    warning that it is no longer bit for bit."""
    import shutil

    native = torch.backends.cpu.get_cpu_capability()
    if native == "DEFAULT":
        pytest.skip("torch's kernels use no vector instructions here: no other path to resume on")
    run = tmp_path / "run"
    shutil.copytree(tiny_run.run_dir, run)
    assert load_checkpoint(run / "checkpoints" / "latest.pt")["machine"]["cpu_capability"] == native
    result = subprocess.run(run_cli.command("train", f"resume={run}", f"ppo.total_frames={5 * 512}"),
                            env={**run_cli.environment(), "ATEN_CPU_CAPABILITY": "default"},
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    (warning,) = [line for line in (run / "train.log").read_text().splitlines() if "another processor path" in line]
    assert f"cpu_capability '{native}' there, 'DEFAULT' here" in warning


def test_a_trial_of_several_seeds_trains_each_as_its_own_run_and_returns_the_worst(run_cli, tiny_args, tmp_path):
    """search.seeds=2 trains seeds 1 and 2 one after another in one process, each exactly as its own run would be
    (the second seed's agent and episodes equal a separate seed=2 run's), and returns the worse run's cost; the
    same command again (a requeued trial) keeps the finished runs instead of training them again."""
    trial, alone = tmp_path / "trial", tmp_path / "alone"
    changes = {"ppo.total_frames": 1024, "eval.episodes": 8}
    trial_command = ("train", *tiny_args({**changes, "seed": 1}), "search.seeds=2", f"hydra.run.dir={trial}")
    results = run_cli.batch({"trial": trial_command,
                             "alone": ("train", *tiny_args({**changes, "seed": 2}), f"hydra.run.dir={alone}")})
    for result in results.values():
        assert result.returncode == 0, result.stderr[-3000:]
    record = json.loads((trial / "trial.json").read_text())
    assert record["seeds"] == [1, 2]
    runs = {seed: json.loads((trial / f"seed_{seed}" / "eval" / "eval.json").read_text()) for seed in (1, 2)}
    assert [runs[seed]["seed"] for seed in (1, 2)] == [1, 2]
    assert record["search_objective"] == max(run["search_objective"] for run in runs.values())
    assert record["search_objective"] == runs[record["worst_seed"]]["search_objective"]
    assert json.loads(results["trial"].stdout.strip().splitlines()[-1]) == record
    assert ((trial / "seed_2" / "eval" / "episodes.csv").read_text()
            == (alone / "eval" / "episodes.csv").read_text())
    second, separate = (load_checkpoint(run / "checkpoints" / "latest.pt")["actor"]
                        for run in (trial / "seed_2", alone))
    assert all(torch.equal(second[key], separate[key]) for key in separate)

    again = run_cli(*trial_command)
    assert again.returncode == 0, again.stderr[-3000:]
    assert again.stdout.count("finished before: its evaluation is kept") == 2
    assert json.loads((trial / "trial.json").read_text()) == record


@pytest.mark.usefixtures("torch_one_thread")
def test_a_checkpoint_of_another_num_envs_is_refused_by_the_trainer(tiny_run, compose_train, tiny_args, tmp_path):
    latest = tiny_run.run_dir / "checkpoints" / "latest.pt"
    payload = {**load_checkpoint(latest), "_path": str(latest)}
    config = compose_train(*tiny_args({"ppo.num_envs": 64}))
    with pytest.raises(CheckpointError) as raised:
        Trainer(config, tmp_path / "run", resume_payload=payload)
    assert str(raised.value) == f"{latest}: checkpoint has 32 environments, this run has 64"
