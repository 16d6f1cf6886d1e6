"""``python -m agrl.report``: tables from run directories (hand-written run folders, the report's real input)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from agrl.report import find_runs, main, median_minutes_to, method_of, moving_tables, read_metrics, run_time_to_reach
from agrl.rl.metrics import MetricsLog


def write_scalars(run: Path, rows: list[dict[str, float]]) -> None:
    """Log ``rows`` (each with ``frames``) the way training does: TensorBoard scalars through MetricsLog."""
    log = MetricsLog(run)
    for row in rows:
        log.log({key: value for key, value in row.items() if key != "frames"}, row["frames"])
    log.tensorboard.experiment.close()


def write_run(root: Path, name: str, config: dict, evaluation: dict) -> Path:
    """A finished run's folder as training leaves it: its Hydra config and final evaluation (eval.json)."""
    run = root / name
    (run / ".hydra").mkdir(parents=True)
    (run / "eval").mkdir()
    OmegaConf.save(OmegaConf.create(config), run / ".hydra" / "config.yaml")
    (run / "eval" / "eval.json").write_text(json.dumps(evaluation))
    return run


def make_run(root: Path, name: str, method: str, speed: float, success: float, curve: list[tuple[float, float]],
             start_from_baseline: bool = False, training_seconds: float | None = None) -> Path:
    """A finished run: its Hydra config, eval.json and TensorBoard scalars of (wall seconds, evaluation success)."""
    config = {"task": {"name": "uniform", "speed": speed}, "reward": {"name": "both"},
              "method": {"name": method, "start_from_baseline": start_from_baseline}, "seed": 0}
    final = {"success_rate": success}
    if training_seconds is not None:
        final.update(training_wall_time_s=training_seconds, iterations=len(curve))
    run = write_run(root, name, config, final)
    # A point is (wall seconds, evaluation success) or (wall seconds, evaluation success, training success).
    write_scalars(run, [{"frames": i * 100, "train/iteration": i, "time/wall_time": point[0],
                         "eval/success_rate": point[1], "train/success_rate": point[-1]}
                        for i, point in enumerate(curve)])
    return run


def test_median_time_counts_a_run_that_never_got_there_as_infinitely_slow(tmp_path):
    make_run(tmp_path, "a", "scratch", 50, 0.99, [(0, 0.0), (60, 0.96)])
    make_run(tmp_path, "b", "scratch", 50, 0.50, [(0, 0.0), (60, 0.5)])
    runs = {run["dir"].name: run for run in find_runs(tmp_path)}
    assert median_minutes_to([runs["a"]], 0.95) == 1.0
    assert math.isinf(median_minutes_to([runs["a"], runs["b"]], 0.95))


def test_targets_compare_reuse_with_the_other_methods(tmp_path):
    # Reuse reaches 95 % after 2 minutes: faster than scratch (3), slower than pre-trained (1).
    # Training success (third value) gets there earlier: scratch at 1.5 minutes, reuse at 1.
    for name, method, seconds in (("s", "scratch", 180), ("p", "pretrained", 60), ("r", "reuse", 120)):
        make_run(tmp_path, name, method, 50, 0.995, [(0, 0.1), (seconds / 2, 0.5, 0.96), (seconds, 0.97)])
    make_run(tmp_path, "rb", "reuse", 50, 0.999, [(0, 0.9), (30, 0.99)], start_from_baseline=True)
    runs = find_runs(tmp_path)
    assert sorted(method_of(run) for run in runs) == ["pretrained", "reuse", "reuse_from_baseline", "scratch"]
    text = moving_tables(runs, figure_dir=None)
    target_row = next(line for line in text.splitlines() if line.startswith("| uniform 50 m/s"))
    assert target_row.split(" | ")[1:7] == ["3.00 / 1.50", "1.00 / 0.50", "2.00 / 1.00", "0.50 / 0.50",
                                            "yes / yes", "no / no"]
    assert "Policy reuse, Z starting from B" in text


def test_an_empty_folder_is_a_one_line_error(tmp_path, capsys):
    assert main(["moving", str(tmp_path)]) == 2
    assert str(tmp_path) in capsys.readouterr().err


def test_a_missing_folder_and_bad_times_are_refused_naming_them(tmp_path, capsys):
    for arguments, message in (
            (["runs", str(tmp_path / "nowhere")],
             f"{tmp_path / 'nowhere'}: no such folder; allowed: a folder containing finished runs"),
            (["runs", str(tmp_path), "--times", "60", "-5"], "--times 60 -5 is not allowed: seconds > 0")):
        with pytest.raises(SystemExit) as exited:
            main(arguments)
        assert exited.value.code == 2
        assert capsys.readouterr().err.strip().splitlines()[-1] == f"python -m agrl.report: error: {message}"


def test_a_setting_no_seed_got_to_95_percent_says_so_and_without_reuse_there_is_no_comparison(tmp_path):
    make_run(tmp_path, "p", "pretrained", 50, 0.90, [(0, 0.0), (120, 0.9)])
    text = moving_tables(find_runs(tmp_path), figure_dir=None)
    assert "| Pre-trained algorithm | 90.0 % (n=1); 95 % evaluation success not reached (0/1); paper 99.2 % |" in text
    assert "Against the targets" not in text  # no reuse run: nothing to compare


def test_figures_are_linked_from_their_own_folder_and_checked_first(tmp_path, capsys):
    make_run(tmp_path / "runs", "r", "reuse", 20, 0.97, [(0, 0.0), (120, 0.96)])
    text = moving_tables(find_runs(tmp_path / "runs"), figure_dir=tmp_path / "figs")
    assert "![uniform 20](figs/uniform_20.png)" in text and (tmp_path / "figs" / "uniform_20.png").is_file()
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    assert main(["moving", str(tmp_path / "runs"), "--figures", str(blocker / "figs")]) == 2
    assert capsys.readouterr().err.strip().startswith(f"agrl.report: error: --figures: {blocker / 'figs'}")


def test_a_method_not_run_shows_as_a_dash_not_a_comparison(tmp_path):
    make_run(tmp_path, "p", "pretrained", 100, 0.99, [(0, 0.0), (240, 0.96)])
    make_run(tmp_path, "r", "reuse", 100, 0.98, [(0, 0.0), (300, 0.96)])
    text = moving_tables(find_runs(tmp_path), figure_dir=None)
    target_row = next(line for line in text.splitlines() if line.startswith("| uniform 100 m/s"))
    assert target_row.split(" | ")[1:7] == ["- / -", "4.00 / 4.00", "5.00 / 5.00", "- / -", "- / -", "no / no"]


def test_the_final_evaluation_is_the_last_point_when_no_periodic_one_got_there(tmp_path):
    # Periodic evaluations stopped at 90 %; the final 1000-episode evaluation after 180 s found 97 %.
    make_run(tmp_path, "late", "reuse", 20, 0.97, [(0, 0.0), (120, 0.9, 0.96)], training_seconds=180.0)
    make_run(tmp_path, "never", "reuse", 20, 0.80, [(0, 0.0), (120, 0.9)], training_seconds=180.0)
    runs = {run["dir"].name: run for run in find_runs(tmp_path)}
    assert run_time_to_reach(runs["late"], 0.95) == (2, 180.0)
    assert run_time_to_reach(runs["never"], 0.95) is None
    # Training success has no final point: it is what the training episodes measured.
    assert run_time_to_reach(runs["late"], 0.95, "train/success_rate") == (1, 120.0)
    assert run_time_to_reach(runs["never"], 0.95, "train/success_rate") is None


# ---------------------------------------------------------------------------- Table 3
def make_reward_run(root: Path, name: str, reward: str, evaluation: dict, curve: list[tuple[float, float]],
                    **reward_values) -> Path:
    """A finished fixed-task run of one reward setting (``reward_values``: its other reward fields): eval.json as
    the trainer writes it, TensorBoard scalars of (wall seconds, periodic evaluation success)."""
    reward_config = {"name": reward, **reward_values}
    config = {"task": {"name": "fixed"}, "reward": reward_config, "method": {"name": "scratch"}, "seed": 0}
    run = write_run(root, name, config, evaluation)
    write_scalars(run, [{"frames": i * 100, "train/iteration": i, "time/wall_time": seconds,
                         "eval/success_rate": success, "train/success_rate": success}
                        for i, (seconds, success) in enumerate(curve)])
    return run


def test_table3_rows_are_mean_and_spread_over_seeds_beside_the_paper(tmp_path, capsys):
    def evaluation(success, instructions, ms):
        return {"success_rate": success, "instructions_per_episode": instructions, "ms_per_instruction": ms}

    # Two seeds with both shaping terms: 95 % after 1 and 3 minutes (iteration 1 each), 99 % only in the first.
    make_reward_run(tmp_path, "both0", "both", evaluation(0.99, 7.0, 0.3), [(0, 0.1), (60, 0.96), (120, 0.995)])
    make_reward_run(tmp_path, "both1", "both", evaluation(0.97, 9.0, 0.5), [(0, 0.1), (180, 0.97)])
    # One seed without shaping, which never reaches 95 %.
    make_reward_run(tmp_path, "none0", "none", evaluation(0.5, 11.0, 0.25), [(0, 0.0), (60, 0.5)])
    assert main(["table3", str(tmp_path)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("| Reward | Seeds | Success rate | Instructions / episode | ms / instruction |")
    rows = {line.split(" | ")[0].lstrip("| "): line.strip("| ").split(" | ") for line in lines[2:]}
    assert list(rows) == ["none", "both"]  # the paper's row order; settings without runs are left out
    # Means and sample standard deviations by hand: success (99, 97) -> 98.0 ± sqrt(2) = 1.4; instructions
    # (7, 9) -> 8.00 ± 1.41; latency (0.3, 0.5) -> 0.40 ± 0.14; minutes to 95 % (1, 3) -> 2.0 ± 1.4.
    assert rows["both"] == ["both", "2", "98.0 ± 1.4 %", "8.00 ± 1.41", "0.40 ± 0.14", "1 ± 0 (2/2)", "2.0 ± 1.4",
                            "2 (1/2)", "2.0", "99.5 %, 7.22, 2.91 ms"]
    assert rows["none"] == ["none", "1", "50.0 %", "11.00", "0.25", "not reached (0/1)", "not reached",
                            "not reached (0/1)", "not reached", "98.6 %, 11.31, 2.98 ms"]


def test_table3_gives_each_switch_cost_its_row_and_independent_evaluations_their_column(tmp_path, capsys):
    def evaluation(success, instructions):
        return {"success_rate": success, "instructions_per_episode": instructions, "ms_per_instruction": 0.3}

    curve = [(0, 0.1), (60, 0.999)]
    runs = [make_reward_run(tmp_path, "k03_s0", "switch", evaluation(0.99, 7.0), curve, switch_cost=0.3),
            make_reward_run(tmp_path, "k03_s1", "switch", evaluation(0.99, 8.0), curve, switch_cost=0.3),
            make_reward_run(tmp_path, "k01_s0", "switch", evaluation(0.99, 10.0), curve, switch_cost=0.1),
            make_reward_run(tmp_path, "both_s0", "both", evaluation(0.99, 19.0), curve)]
    # A switch cost on the position term alone is a row of its own.
    make_reward_run(tmp_path, "k01_position_s0", "switch", evaluation(0.995, 9.0), curve,
                    switch_cost=0.1, use_continuous_action=False)
    # 10 000 independent episodes, as `python -m agrl.evaluate ... hydra.run.dir=<run>/eval_777` leaves them;
    # the second k = 0.3 seed has none: the cell says over how many runs it is.
    for run, success, instructions in zip(runs, (0.996, None, 0.998, 0.997), (6.5, None, 9.5, 18.5), strict=True):
        if success is not None:
            (run / "eval_777").mkdir()
            (run / "eval_777" / "eval.json").write_text(json.dumps(evaluation(success, instructions)))
    assert main(["table3", str(tmp_path), "--independent", "eval_777"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].endswith("| eval_777: success, instructions | Paper: success, instructions, ms |")
    assert lines[1].count("|") == lines[0].count("|")
    rows = {line.split(" | ")[0].lstrip("| "): line.strip("| ").split(" | ") for line in lines[2:]}
    assert list(rows) == ["both", "switch (k = 0.1)", "switch (k = 0.1, no continuous-action term)",
                          "switch (k = 0.3)"]  # the paper's rows, then by cost
    assert rows["switch (k = 0.1, no continuous-action term)"][2:4] == ["99.5 %", "9.00"]
    assert rows["switch (k = 0.1, no continuous-action term)"][-2] == "-"  # no independent evaluation
    assert rows["switch (k = 0.3)"][3] == "7.50 ± 0.71"
    assert rows["switch (k = 0.3)"][-2:] == ["99.60 %, 6.50 (1/2)", "not in the paper"]
    assert rows["switch (k = 0.1)"][-2:] == ["99.80 %, 9.50 (1/1)", "not in the paper"]
    assert rows["both"][-2:] == ["99.70 %, 18.50 (1/1)", "99.5 %, 7.22, 2.91 ms"]


def test_table3_is_the_fixed_destination_with_each_method_its_row(tmp_path, capsys):
    evaluation = {"success_rate": 0.99, "instructions_per_episode": 7.0, "ms_per_instruction": 0.3}
    curve = [(0, 0.1), (60, 0.999)]
    make_reward_run(tmp_path, "k01", "switch", evaluation, curve, switch_cost=0.1)
    tuned = make_reward_run(tmp_path, "k03_tuned", "switch", evaluation, curve, switch_cost=0.3)
    config = OmegaConf.load(tuned / ".hydra" / "config.yaml")
    config.method.name = "pretrained"
    OmegaConf.save(config, tuned / ".hydra" / "config.yaml")
    make_run(tmp_path, "moving", "reuse", 50, 0.9, [(0, 0.0), (60, 0.9)])  # another task: not a Table 3 row
    assert main(["table3", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    rows = [line.split(" | ")[0].lstrip("| ") for line in captured.out.strip().splitlines()[2:]]
    assert rows == ["switch (k = 0.1)", "switch (k = 0.3), pre-trained algorithm"]
    assert captured.err.strip() == "agrl.report: 1 run of other tasks left out: Table 3 is the fixed destination"


def test_metrics_rows_come_back_from_tensorboard_one_per_step(tmp_path):
    run = tmp_path / "run"
    # An older run's initial evaluation (step 0) carried no iteration or wall time; a resumed session repeats
    # iteration 2 (step 200) from the last checkpoint: its last value counts.
    write_scalars(run, [{"frames": 0, "eval/success_rate": 0.25},
                        {"frames": 100, "train/iteration": 1, "time/wall_time": 12.5, "train/success_rate": 0.5},
                        {"frames": 200, "train/iteration": 2, "time/wall_time": 25.0, "train/success_rate": 0.75}])
    write_scalars(run, [{"frames": 200, "train/iteration": 2, "time/wall_time": 26.0, "train/success_rate": 0.625,
                         "eval/success_rate": 0.875}])
    assert read_metrics(run) == [
        {"iteration": 0.0, "frames": 0.0, "wall_time": 0.0, "eval/success_rate": 0.25},
        {"iteration": 1.0, "frames": 100.0, "wall_time": 12.5, "train/iteration": 1.0, "time/wall_time": 12.5,
         "train/success_rate": 0.5},
        {"iteration": 2.0, "frames": 200.0, "wall_time": 26.0, "train/iteration": 2.0, "time/wall_time": 26.0,
         "train/success_rate": 0.625, "eval/success_rate": 0.875},
    ]
    assert read_metrics(tmp_path / "no_run") == []


def test_the_runs_table_gives_each_runs_curve_and_costs(tmp_path, capsys):
    run = write_run(tmp_path, "reuse_s0", {"task": {"name": "uniform", "speed": 50.0}, "method": {"name": "reuse"}},
                    {"success_rate": 0.987, "instructions_per_episode": 11.84})
    # The initial evaluation (no iteration yet), then three iterations of 8, 3 and 2 s (relabelling 2.5, 0.5, 0.25);
    # evaluations at 20 s (60 %) and 70 s (97 %).
    write_scalars(run, [
        {"frames": 0, "train/iteration": 0, "time/wall_time": 0.0, "eval/success_rate": 0.004},
        {"frames": 100, "train/iteration": 1, "time/wall_time": 20.0, "time/iteration_seconds": 8.0,
         "time/reuse_seconds": 2.5, "eval/success_rate": 0.6},
        {"frames": 200, "train/iteration": 2, "time/wall_time": 50.0, "time/iteration_seconds": 3.0,
         "time/reuse_seconds": 0.5},
        {"frames": 300, "train/iteration": 3, "time/wall_time": 70.0, "time/iteration_seconds": 2.0,
         "time/reuse_seconds": 0.25, "eval/success_rate": 0.97}])
    # A pre-trained run logs no relabelling time: its cells say so ("-"), not a median of zeros.
    plain = write_run(tmp_path, "pretrained_s0",
                      {"task": {"name": "uniform", "speed": 50.0}, "method": {"name": "pretrained"}},
                      {"success_rate": 0.995, "instructions_per_episode": 10.0, "episodes": 16})
    write_scalars(plain, [
        {"frames": 0, "train/iteration": 0, "time/wall_time": 0.0, "eval/success_rate": 0.9},
        {"frames": 100, "train/iteration": 1, "time/wall_time": 5.0, "time/iteration_seconds": 4.0},
        {"frames": 200, "train/iteration": 2, "time/wall_time": 7.0, "time/iteration_seconds": 1.5,
         "eval/success_rate": 0.99}])
    assert main(["runs", str(tmp_path), "--times", "60", "120"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("| run | evaluation before training | best evaluation by 60 / 120 s | s to 95 % |")
    assert "| final success (episodes) |" in lines[0]
    assert lines[2] == "| pretrained_s0 | 90.0 % | 99 / 99 % | 7 | 99.5 % (16) | 10.0 | 2 | 1.50 (-) | 4.0 (-) |"
    # Best by 60 s: 60 % (the 97 % came at 70 s); medians over iterations 2-3: 2.5 s and 0.375 s of relabelling.
    assert lines[3] == "| reuse_s0 | 0.4 % | 60 / 97 % | 70 | 98.7 % | 11.8 | 3 | 2.50 (0.38) | 8.0 (2.5) |"


def test_the_irregular_destination_is_named_without_a_speed(tmp_path):
    run = make_run(tmp_path, "i", "reuse", 0, 0.99, [(0, 0.1), (60, 0.96)])
    OmegaConf.save(OmegaConf.create({"task": {"name": "irregular", "speed": None}, "reward": {"name": "both"},
                                     "method": {"name": "reuse", "start_from_baseline": False}, "seed": 0}),
                   run / ".hydra" / "config.yaml")
    text = moving_tables(find_runs(tmp_path), figure_dir=None)
    assert any(line.startswith("| irregular | ") for line in text.splitlines()), text
    assert "| Method | Irregular |" in text
