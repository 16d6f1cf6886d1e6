"""Smoke tests of the benchmarks beside the package (``python -m benchmarks.bench --quick``, ``bench_peer``,
``bench_race``): output format only, no timing assertions. Those that run stable-baselines3 skip without it (the
``bench`` extra, which ``make install`` installs)."""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from benchmarks.bench import parse_args

#: ``python -m benchmarks.<name>`` imports the benchmarks from the repository root.
REPO = Path(__file__).resolve().parents[1]
REQUIRED = {"name", "value", "unit"}


#: ``python -m benchmarks.bench_peer`` at a tiny geometry, up to its list of trainers.
PEER_RUN = ("benchmarks.bench_peer", "--num-envs", "16", "--steps", "8", "--iterations", "2", "--minibatch", "64",
            "--no-compile", "--threads", "1", "--trainers")
#: {--trainers name: (its record's trainer, its ratio's name or None for the reference, SB3)}.
PEER_TRAINERS = {"agrl": ("agrl", "ratio_agrl_over_sb3"),
                 "agrl-compiled": ("agrl (compiled loss)", "ratio_agrl_compiled_over_sb3"),
                 "stable-baselines3": ("stable-baselines3", None),
                 "floor": ("floor (plain PyTorch)", "ratio_floor_over_sb3"),
                 "floor-equal-work": ("floor, equal work (plain PyTorch)", "ratio_floor_equal_work_over_sb3")}
#: The floors' --trainers names, in the order of their target lines.
FLOORS = ("floor", "floor-equal-work")

#: The benchmark runs tested here: {name: ``python -m`` arguments}; the last two need stable-baselines3.
BENCHMARK_RUNS = {
    "bench": ("benchmarks.bench", "--quick", "--batch-sizes", "8", "32", "--env-batch", "8", "--eval-episodes", "16"),
    "peer": (*PEER_RUN, "agrl", "stable-baselines3", "floor", "floor-equal-work", "--set", "agent.actor_hidden=[16,16]",
             "agent.critic_hidden=[16,16]"),
    "race": ("benchmarks.bench_race", "--budget-seconds", "2", "--eval-every", "1", "--eval-episodes", "8",
             "--max-decisions", "4", "--no-compile", "--threads", "1", "--sb3-geometry", "agrl", "--agrl-override",
             "ppo.num_envs=16", "ppo.steps_per_env=4", "ppo.minibatch_size=32",
             "ppo.compile_loss=false"),  # a 2-second budget: compiling the loss would fill it
    "profile": ("benchmarks.profile_iteration", "ppo.num_envs=16", "ppo.steps_per_env=8", "ppo.minibatch_size=64",
                "simulation.compile=false", "threads=1", "--warmup", "1", "--iterations", "2", "--top", "5"),
    "reset": ("benchmarks.bench_reset", "ppo.num_envs=64", "ppo.steps_per_env=8", "ppo.minibatch_size=128",
              "simulation.compile=false", "simulation.max_decisions=3", "threads=1", "--warmup", "1", "--pairs", "2"),
}
#: The runs that do not need stable-baselines3.
WITHOUT_SB3 = ("bench", "profile", "reset")


@pytest.fixture(scope="module")
def benchmark_runs(run_at_once) -> dict[str, subprocess.CompletedProcess]:
    """Each of :data:`BENCHMARK_RUNS` (those that need stable-baselines3 only with it), all at once."""
    import importlib.util

    names = [name for name in BENCHMARK_RUNS
             if name in WITHOUT_SB3 or importlib.util.find_spec("stable_baselines3") is not None]
    return run_at_once({name: [sys.executable, "-m", *BENCHMARK_RUNS[name]] for name in names}, REPO, timeout=600)


def test_quick_run_prints_json_lines(benchmark_runs):
    completed = benchmark_runs["bench"]
    assert completed.returncode == 0, completed.stderr
    lines = [line for line in completed.stdout.splitlines() if line.strip()]
    records = [json.loads(line) for line in lines]  # every line is one JSON object
    assert all(isinstance(record, dict) and REQUIRED <= set(record) for record in records)
    names = [record["name"] for record in records]
    assert names == [
        "machine",
        "reference_decisions_per_second",
        "simulator_decisions_per_second",
        "simulator_decisions_per_second",
        "torchrl_env_decisions_per_second",
        "torchrl_env_decisions_per_second",
        "gym_vector_env_decisions_per_second",
        "gym_env_decisions_per_second",
        "evaluation_episodes_per_second",
        "guide_single_query_us",
        "guide_batch_us_per_query",
    ]
    guide_single, guide_batch = records[-2:]
    evaluation = records[-3]
    assert evaluation["unit"] == "episodes/s" and evaluation["value"] > 0 and evaluation["batch"] == 16
    assert evaluation["agent"] == "baseline" and evaluation["compiled"] is False
    assert 16 <= evaluation["decisions_flown"] <= 16 * 200  # each episode flies 1 to 200 decisions
    assert guide_single["unit"] == guide_batch["unit"] == "us/query" and guide_single["value"] > 0
    assert guide_single["batch"] == 1 and guide_batch["batch"] == 64 and guide_batch["guide"] == "checkpoint"
    records = records[:-3]
    for record in records[1:]:
        assert record["unit"] == "decisions/s" and record["value"] > 0
        assert record["substeps"] == 150 and record["compiled"] is False
        assert {"batch", "device"} <= set(record)
    assert [record["batch"] for record in records[2:]] == [8, 32, 8, 8, 8, 1]
    assert [record.get("actions") for record in records[4:6]] == ["maneuvers", "targets"]
    assert all(record["speedup_vs_reference"] > 0 for record in records[2:])


def test_profile_lists_the_top_functions_of_each_phase(benchmark_runs):
    completed = benchmark_runs["profile"]
    assert completed.returncode == 0, completed.stderr
    for phase in ("collection", "update"):
        header = re.search(rf"^{phase}: ([0-9.]+) s per iteration \(median of 2\), ([0-9.]+) s profiled$",
                           completed.stdout, re.MULTILINE)
        assert header and float(header[1]) > 0 and float(header[2]) > 0, completed.stdout
    rows = [line.split("|") for line in completed.stdout.splitlines() if line.startswith("| `")]
    assert len(rows) == 2 * 5  # --top 5 per phase
    assert all(int(row[2]) > 0 and 0 <= int(row[3].strip().removesuffix(" %")) <= 100 for row in rows)
    assert "agrl/rl/trainer.py" in completed.stdout  # the update is the package's own Trainer.learn


def test_reset_benchmark_times_both_resets_in_pairs(benchmark_runs):
    """``python -m benchmarks.bench_reset``: a machine line, each reset's median batch time over its pairs (episodes
    end every 3 decisions there, so both resets run), then the median of the pairs' ratios."""
    completed = benchmark_runs["reset"]
    assert completed.returncode == 0, completed.stderr
    records = [json.loads(line) for line in completed.stdout.splitlines()]
    assert records[0]["name"] == "machine"
    batches = {record["reset"]: record for record in records if record["name"] == "collector_batch_seconds"}
    assert set(batches) == {"agrl", "torchrl"}
    for record in batches.values():
        assert record["shape"] == "64x8" and record["pairs"] == 2 and len(record["each_s"]) == 2
        assert record["value"] == pytest.approx(statistics.median(record["each_s"]), abs=1e-4)
    (ratio,) = [record for record in records if record["name"] == "ratio_reset_agrl_over_torchrl"]
    pairs = [new / old for new, old in zip(batches["agrl"]["each_s"], batches["torchrl"]["each_s"], strict=True)]
    assert ratio["value"] == pytest.approx(statistics.median(pairs), rel=5e-2)  # from the rounded seconds


def test_profile_refuses_a_count_below_one(capsys):
    from benchmarks.profile_iteration import main

    with pytest.raises(SystemExit):
        main(["--top", "0"])
    assert "--top=0 is not allowed: a positive integer" in capsys.readouterr().err


def test_arguments():
    full = parse_args([])
    assert full.batch_sizes == [1024, 4096, 16384] and full.modes == ["eager", "compiled"]
    assert full.repeats == 5 and str(full.device) == "cpu" and full.threads is None  # torch's default
    quick = parse_args(["--quick", "--repeats", "3"])
    assert quick.modes == ["eager"] and quick.repeats == 3 and max(quick.batch_sizes) <= 256
    assert parse_args(["--threads", "1"]).threads == 1
    for bad in (["--batch-sizes", "0"], ["--modes", "jit"], ["--repeats", "-1"], ["--threads", "0"]):
        with pytest.raises(SystemExit):
            parse_args(bad)


def test_stable_baselines3_sees_the_vector_env_through_the_adapter():
    """python -m benchmarks.bench_peer's adapter: SB3's VecEnv contract (same-step reset, terminal_observation)."""
    PPO = pytest.importorskip("stable_baselines3").PPO

    from benchmarks.bench_peer import make_sb3_vector_env

    env = make_sb3_vector_env(4, compile=False, seed=0, task="fixed", max_decisions=2)
    observations = env.reset()
    assert observations.shape == (4, 23) and env.num_envs == 4
    env.step_async(np.zeros(4, dtype=np.int64))
    _, rewards, dones, infos = env.step_wait()
    assert rewards.dtype == np.float32 and not dones.any() and infos == [{}] * 4
    env.step_async(np.ones(4, dtype=np.int64))
    observations, _, dones, infos = env.step_wait()
    assert dones.all()  # the 2-decision budget
    for row, info in enumerate(infos):  # the returned observation already starts the next episode
        assert info["terminal_observation"].shape == (23,) and info["TimeLimit.truncated"] is False
        assert not np.allclose(info["terminal_observation"], observations[row])
    model = PPO("MlpPolicy", env, n_steps=4, batch_size=8, n_epochs=1, device="cpu", seed=0)
    model.learn(total_timesteps=16)
    assert model.num_timesteps == 16
    env.close()


def test_iteration_record_reports_the_median_split():
    from benchmarks.bench_peer import iteration_record

    record = iteration_record("agrl", collection=[1.0, 3.0, 2.0], update=[4.0, 1.0, 2.0], decisions=100)
    assert record["collection_s"] == 2.0 and record["update_s"] == 2.0
    assert record["value"] == 4.0  # median of the totals 5, 4, 4 (not the sum of the two medians)
    assert record["decisions_per_second"] == 25.0 and record["iterations_timed"] == 3


def test_peer_benchmark_prints_the_split_for_each_trainer_and_the_ratios(benchmark_runs):
    """``python -m benchmarks.bench_peer`` at a tiny geometry: one iteration line per trainer (agrl, SB3 and the
    plain PyTorch floor, bare and doing equal work), then each one's ratio to SB3, then agrl's two speed-target lines
    against each floor. With the compiled loss too: the slow test below (its compilation takes longer than the rest
    of the run; the compiled loss itself is tests/rl/test_ppo.py's)."""
    pytest.importorskip("stable_baselines3")
    assert_peer_records(benchmark_runs["peer"], ["agrl", "stable-baselines3", "floor", "floor-equal-work"],
                        settings=["agent.actor_hidden=[16,16]", "agent.critic_hidden=[16,16]"])


@pytest.mark.parametrize("setting", ["ppo.num_envs=64", "ppo.compile_loss=true", "reward.gamma=0.9", "ppo.epochs"])
def test_peer_benchmark_refuses_a_setting_its_options_own_or_outside_agent_and_ppo(setting, capsys):
    from benchmarks.bench_peer import main

    with pytest.raises(SystemExit) as stopped:
        main(["--set", setting])
    assert stopped.value.code == 2
    assert f"--set {setting} is not allowed: KEY=VALUE with an agent.* or ppo.* key" in capsys.readouterr().err


@pytest.mark.slow
def test_peer_benchmark_with_the_compiled_loss():
    pytest.importorskip("stable_baselines3")
    trainers = ["agrl", "agrl-compiled", "stable-baselines3", "floor"]
    completed = subprocess.run([sys.executable, "-m", *PEER_RUN, *trainers], cwd=REPO, capture_output=True,
                               text=True, timeout=600)
    assert_peer_records(completed, trainers)


def assert_peer_records(completed: subprocess.CompletedProcess, trainers: list[str],
                        settings: list[str] | None = None) -> None:
    assert completed.returncode == 0, completed.stderr
    records = [json.loads(line) for line in completed.stdout.splitlines()]  # JSON lines only (TorchRL's: stderr)
    assert all(record.get("settings") == settings for record in records)  # each line says what it measured
    compared = [name for name in trainers if PEER_TRAINERS[name][1] is not None]
    iterations, ratios = records[:len(trainers)], records[len(trainers):]
    agrl_trainers = [name for name in ("agrl", "agrl-compiled") if name in trainers]
    targets = ratios[len(compared):]  # with a floor: each agrl trainer's two target lines against it
    ratios = ratios[:len(compared)]
    assert [record["name"] for record in iterations] == ["ppo_iteration_seconds"] * len(trainers)
    assert [record["name"] for record in ratios] == [PEER_TRAINERS[name][1] for name in compared]
    floors = [floor for floor in FLOORS if floor in trainers]
    expected_targets = [f"{kind}_{name.replace('-', '_')}_over_{floor.replace('-', '_')}" for floor in floors
                        for name in agrl_trainers for kind in ("ratio", "collection_time")]
    assert [record["name"] for record in targets] == expected_targets
    assert [record["trainer"] for record in iterations] == [PEER_TRAINERS[name][0] for name in trainers]
    for record in iterations:
        assert record["decisions_per_iteration"] == 128 and record["iterations_timed"] == 2
        assert record["shape"] == "16x8"  # --num-envs x --steps
        assert 0 < record["collection_s"] and 0 < record["update_s"] and record["unit"] == "s/iteration"
    by_name = dict(zip(trainers, iterations, strict=True))
    sb3 = by_name["stable-baselines3"]
    for ratio, name in zip(ratios, compared, strict=True):
        trainer = by_name[name]
        assert ratio["value"] == pytest.approx(paired(trainer, sb3, "total"), abs=1e-3) and ratio["threads"] == 1
        assert ratio["update_ratio"] == pytest.approx(paired(trainer, sb3, "update"), abs=1e-3)
        assert ratio["collection_ratio"] == pytest.approx(paired(trainer, sb3, "collection"), abs=1e-3)
    pairs = iter(zip(targets[::2], targets[1::2], strict=True))
    for floor_name in floors:
        floor = by_name[floor_name]
        for name in agrl_trainers:
            speed, collection_time = next(pairs)
            trainer = by_name[name]
            assert speed["value"] == pytest.approx(paired(trainer, floor, "total"), abs=1e-3)
            assert speed["collection_ratio"] == pytest.approx(paired(trainer, floor, "collection"), abs=1e-3)
            assert collection_time["value"] == pytest.approx(paired(floor, trainer, "collection"), abs=1e-3)
            assert collection_time["unit"] == "x time" and collection_time["threads"] == 1


def paired(trainer: dict, reference: dict, part: str) -> float:
    """The median over rounds of the reference's seconds over the trainer's (``part``: collection, update or total)."""
    def seconds(record: dict) -> list[float]:
        if part == "total":
            return [c + u for c, u in zip(record["collection_each_s"], record["update_each_s"], strict=True)]
        return record[f"{part}_each_s"]

    return statistics.median(r / t for r, t in zip(seconds(reference), seconds(trainer), strict=True))


def test_trainers_alternate_after_one_warm_up_each():
    from benchmarks.bench_peer import alternate

    order = []

    def trainer(name: str):
        iteration = 0
        while True:
            order.append(name)
            yield float(iteration), 10.0 + iteration
            iteration += 1

    timed = alternate({"a": trainer("a"), "b": trainer("b")}, rounds=3)
    assert order == ["a", "b"] * 4  # the warm-ups first, then a round of one each
    assert timed == {"a": ([1.0, 2.0, 3.0], [11.0, 12.0, 13.0]), "b": ([1.0, 2.0, 3.0], [11.0, 12.0, 13.0])}


def test_a_ratio_is_the_median_of_the_rounds_ratios():
    """Each round compares two iterations run one after the other; the median of those ratios (3 here) is what a
    ratio line reports, not the ratio of the two medians (1.5), which a machine's drift between rounds moves."""
    from benchmarks.bench_peer import collection_time_record, iteration_record, ratio_record

    a = iteration_record("a", [1.0, 2.0, 3.0], [1.0, 2.0, 3.0], decisions=100)
    b = iteration_record("b", [3.0, 2.0, 9.0], [3.0, 2.0, 9.0], decisions=100)
    args = argparse.Namespace(num_envs=4, steps=25, compile=False, set=[])
    ratio = ratio_record("ratio_a_over_b", a, b, args, threads=1, load=0.0)
    assert ratio["value"] == 3.0 and ratio["update_ratio"] == 3.0 and ratio["collection_ratio"] == 3.0
    assert collection_time_record("collection_time_a_over_b", a, b, args, threads=1, load=0.0)["value"] == 0.333
    # An even number of rounds: the time ratio is the median of A's seconds over B's (0.5, 0.25, 0.5, 0.25: 0.375),
    # not the inverse of the speed ratio's median (1 / 3).
    a = iteration_record("a", [1.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0], decisions=100)
    b = iteration_record("b", [2.0, 4.0, 2.0, 4.0], [2.0, 4.0, 2.0, 4.0], decisions=100)
    assert ratio_record("ratio_a_over_b", a, b, args, threads=1, load=0.0)["value"] == 3.0
    assert collection_time_record("collection_time_a_over_b", a, b, args, threads=1, load=0.0)["value"] == 0.375


def test_race_prints_both_trainers_evaluations_and_results(benchmark_runs):
    """``python -m benchmarks.bench_race`` with a budget of seconds: both trainers train, both fly the same evaluation
    set."""
    pytest.importorskip("stable_baselines3")
    completed = benchmark_runs["race"]
    assert completed.returncode == 0, completed.stderr
    records = [json.loads(line) for line in completed.stdout.splitlines() if line.strip()]  # JSON lines only
    assert all(REQUIRED <= set(record) for record in records)
    assert records[-1]["name"] == "race_summary"
    results = {record["trainer"]: record for record in records if record["name"] == "race_result"}
    assert list(results) == ["agrl", "stable-baselines3"]
    for trainer, result in results.items():
        evaluations = [r for r in records if r["name"] == "race_evaluation" and r["trainer"] == trainer]
        # one at the start (nothing trained yet), one at the end (the final one), none after it
        assert len(evaluations) >= 2 and evaluations[0]["decisions"] == 0 and not evaluations[0]["final"]
        assert evaluations[-1]["final"] and [r["final"] for r in evaluations].count(True) == 1
        assert evaluations[-1]["decisions"] > 0 and evaluations[-1]["training_seconds"] >= 2
        seconds = [r["training_seconds"] for r in evaluations]
        assert seconds == sorted(seconds)
        assert all(0.0 <= r["success_rate"] <= 1.0 and r["decisions_per_episode"] <= 4 for r in evaluations)
        assert result["evaluations"] == len(evaluations)
        assert result["final_success_rate"] == evaluations[-1]["success_rate"]
        assert result["best_success_rate"] == max(r["success_rate"] for r in evaluations)
        assert result["decisions_per_second"] == pytest.approx(
            evaluations[-1]["decisions"] / evaluations[-1]["training_seconds"], rel=1e-2)
        assert {"seconds_to_95", "seconds_to_99", "decisions_to_95", "decisions_to_99"} <= set(result)
    assert results["stable-baselines3"]["settings"]["n_steps"] == 4  # --sb3-geometry agrl: agrl's geometry
    assert results["stable-baselines3"]["settings"]["num_envs"] == 16
    summary = records[-1]
    assert {"speedup_to_95", "speedup_to_99", "load_average_1min_at_start"} <= set(summary)
    assert summary["threads"] == 1 and summary["eval_episodes"] == 8


def test_race_result_reports_when_each_target_was_first_reached():
    from agrl.envs.gym import gym_parameters
    from benchmarks.bench_race import RaceEvaluation, TrainingClock

    evaluation = RaceEvaluation(gym_parameters(), episodes=2, seed=0, clock=TrainingClock(),
                                targets=(0.95, 0.99), emit=lambda record: None)
    rates = [(0.0, 0.1, 0), (10.0, 0.96, 100), (20.0, 0.9, 200), (30.0, 0.995, 300), (40.0, 1.0, 400)]
    evaluation.history = [{"trainer": "agrl", "training_seconds": s, "success_rate": r, "decisions": d}
                          for s, r, d in rates]
    evaluation.history.insert(2, {"trainer": "other", "training_seconds": 15.0, "success_rate": 1.0, "decisions": 9})
    result = evaluation.result("agrl", settings={})
    assert result["seconds_to_95"] == 10.0 and result["decisions_to_95"] == 100
    assert result["seconds_to_99"] == 30.0 and result["decisions_to_99"] == 300
    assert result["final_success_rate"] == 1.0 and result["evaluations"] == 5
    assert result["decisions_per_second"] == 10.0  # 400 decisions in 40 s
    assert evaluation.reached_last_target("agrl") and not evaluation.reached_last_target("stable-baselines3")


def test_race_arguments():
    from benchmarks.bench_race import parse_args

    default = parse_args([])
    assert default.sb3_geometry == "sb3" and default.sb3_env == "single" and default.targets == [0.95, 0.99]
    assert parse_args(["--sb3-geometry", "agrl"]).sb3_env == "vector"
    for bad in (["--budget-seconds", "0"], ["--targets", "0.99", "0.95"], ["--targets", "1.5"], ["--eval-every", "-1"],
                ["--sb3-env", "subprocess"], ["--max-decisions", "0"]):
        with pytest.raises(SystemExit):
            parse_args(bad)


@pytest.mark.slow
def test_startup_benchmark_times_the_training_command_and_the_vector_env():
    """Five real processes (a compilation among them): the slow suite. Format and consistency, no timing claim."""
    completed = subprocess.run([sys.executable, "-m", "benchmarks.startup", "--repeats", "1", "--rows", "256"],
                               cwd=REPO, capture_output=True, text=True, timeout=900)
    assert completed.returncode == 0, completed.stderr[-2000:]
    records = [json.loads(line) for line in completed.stdout.splitlines() if line.startswith("{")]
    by_name = {(record["name"], record.get("compile_cache")): record for record in records}
    assert by_name[("machine", None)]
    empty, warm = (by_name[("train_first_iteration_seconds", cache)] for cache in ("empty", "warm"))
    assert 0 < warm["value"] and 0 < empty["value"] and warm["runs"] == 1
    start = by_name[("gym_vector_env_start_seconds", "warm")]
    speed = by_name[("gym_vector_env_decisions_per_second", "warm")]
    assert start["batch"] == speed["batch"] == 256 and speed["compiled"]  # compiled by default from 256 rows
    assert speed["value"] > 0


def test_the_equal_work_floors_gae_is_torchrls():
    """``floor-equal-work``'s GAE (every episode end a termination; the value after an end is the next episode's
    first and unused) equals TorchRL's ``generalized_advantage_estimate``, which agrl's trainer runs."""
    import torch
    from torchrl.objectives.value.functional import generalized_advantage_estimate

    from benchmarks.bench_peer import plain_gae

    generator = torch.Generator().manual_seed(0)
    steps, rows = 12, 5
    rewards = torch.randn(steps, rows, generator=generator)
    dones = torch.rand(steps, rows, generator=generator) < 0.3
    values = torch.randn(steps + 1, rows, generator=generator)
    advantages, targets = plain_gae(rewards, dones, values, gamma=0.97, lmbda=0.9)
    # TorchRL's layout: [batch, time, 1], the next values of a done step anything (here the next episode's first).
    as_torchrl = lambda tensor: tensor.T.unsqueeze(-1)  # noqa: E731
    expected, expected_targets = generalized_advantage_estimate(
        0.97, 0.9, as_torchrl(values[:-1]), as_torchrl(values[1:]), as_torchrl(rewards), as_torchrl(dones))
    torch.testing.assert_close(as_torchrl(advantages), expected)
    torch.testing.assert_close(as_torchrl(targets), expected_targets)
    assert not torch.allclose(advantages, plain_gae(rewards, torch.zeros_like(dones), values, 0.97, 0.9)[0])


@pytest.mark.parametrize("budget_reached", [False, True])
def test_the_equal_work_floors_decision_end_is_the_envs(budget_reached):
    """``floor-equal-work``'s reward and episode end of a decision are the env's (its budget's end included)."""
    import torch

    from agrl.config import guidance_parameters
    from agrl.envs.guidance import GuidanceEnv
    from benchmarks.bench_peer import plain_decision_end

    params = guidance_parameters("reward=switch")
    env = GuidanceEnv(params, num_envs=64, seed=3)
    state = env.reset()
    generator = torch.Generator().manual_seed(1)
    for _ in range(3):  # a few decisions in, so that the last two actions differ between rows
        state["action"] = torch.randint(0, env.num_actions, (64,), generator=generator)
        state = env.step(state)["next"].exclude("reward", "done", "terminated")
    if budget_reached:
        state["step_count"] = torch.full((64,), params.max_decisions - 1)
    state["action"] = torch.randint(0, env.num_actions, (64,), generator=generator)
    result = env.simulator(state["aircraft_state"], state["destination_state"], state["destination_speed"],
                           state["destination_turn_rate"], state["action"])
    expected = env.complete_transition(state, result, state["destination_speed"], state["destination_turn_rate"])
    reward, done = plain_decision_end(params, state["step_count"] + 1, state["aircraft_state"],
                                      state["destination_state"], state["last_action"], state["action_before_last"],
                                      state["action"], result)
    torch.testing.assert_close(reward, expected["reward"].squeeze(-1), rtol=0, atol=0)
    assert torch.equal(done, expected["done"].squeeze(-1))
    assert bool(done.all()) == budget_reached


def test_make_train_benchmark_tells_the_shipped_agent_from_another(tmp_path):
    """``benchmarks.make_train`` marks a run's agent as the shipped one only if actor and critic match bit for bit."""
    import torch

    from benchmarks.make_train import SHIPPED_AGENT, same_agent

    shipped = REPO / SHIPPED_AGENT
    assert same_agent(shipped, shipped)
    assert not same_agent(shipped, REPO / "agrl/baselines/fixed_baseline_stage1.pt")
    nudged = torch.load(shipped, map_location="cpu", weights_only=True)
    name = next(iter(nudged["critic"]))
    nudged["critic"][name] = torch.nextafter(nudged["critic"][name], torch.tensor(float("inf")))
    torch.save(nudged, tmp_path / "nudged.pt")
    assert not same_agent(shipped, tmp_path / "nudged.pt")


def test_make_train_benchmark_reads_the_runs_last_line():
    from benchmarks.make_train import parse_args, run_summary

    assert run_summary('iter 1 | ...\n{"success_rate": 0.999, "iterations": 124}\n') == {
        "success_rate": 0.999, "iterations": 124}
    assert parse_args([]).arms == ["install", "empty"]
    with pytest.raises(SystemExit):
        parse_args(["--arms", "hot"])
