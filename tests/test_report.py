"""``python -m agrl.report``: extraction from run folders (hand-written, as training and evaluation leave them), the
tables and figures from data folders (a small tracked sample of real runs), and the pages' report blocks."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from agrl.report import (
    assemble_runs,
    extract,
    finished,
    load_data,
    main,
    median_minutes_to,
    moving_tables,
    read_metrics,
    run_time_to_reach,
)
from agrl.rl.metrics import MetricsLog

REPOSITORY = Path(__file__).resolve().parents[1]
SAMPLE = Path(__file__).parent / "data" / "report_sample"


def write_scalars(run: Path, rows: list[dict[str, float]]) -> None:
    """Log ``rows`` (each with ``frames``) the way training does: TensorBoard scalars through MetricsLog."""
    log = MetricsLog(run)
    for row in rows:
        log.log({key: value for key, value in row.items() if key != "frames"}, row["frames"])
    log.tensorboard.experiment.close()


def write_run(root: Path, name: str, config: dict, evaluation: dict, overrides: list[str] = ()) -> Path:
    """A finished run's folder as training leaves it: its Hydra config and overrides, and final evaluation."""
    run = root / name
    (run / ".hydra").mkdir(parents=True)
    (run / "eval").mkdir()
    OmegaConf.save(OmegaConf.create(config), run / ".hydra" / "config.yaml")
    OmegaConf.save(OmegaConf.create(list(overrides)), run / ".hydra" / "overrides.yaml")
    (run / "eval" / "eval.json").write_text(json.dumps(evaluation))
    return run


def write_evaluation(folder: Path, evaluation: dict, overrides: list[str]) -> Path:
    """An evaluation's folder as ``python -m agrl.evaluate ... hydra.run.dir=<folder>`` leaves it."""
    (folder / ".hydra").mkdir(parents=True)
    OmegaConf.save(OmegaConf.create({"checkpoint": "x", "episodes": evaluation.get("episodes", 0)}),
                   folder / ".hydra" / "config.yaml")
    OmegaConf.save(OmegaConf.create(overrides), folder / ".hydra" / "overrides.yaml")
    (folder / "eval.json").write_text(json.dumps(evaluation))
    return folder


def runs_below(root: Path) -> list[dict]:
    """The finished runs below ``root``, as the tables get them (extracted in memory)."""
    return finished(assemble_runs(extract(root)))


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


def read_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


# ---------------------------------------------------------------------------- extraction
def test_extract_writes_a_row_per_run_evaluation_and_periodic_evaluation(tmp_path, capsys):
    runs = tmp_path / "runs"
    run = write_run(runs / "sweep", "reuse_s1",
                    {"task": {"name": "uniform", "speed": 50.0, "radius": 1000.0},
                     "reward": {"name": "switch", "switch_cost": 0.1, "use_continuous_action": False},
                     "method": {"name": "reuse", "start_from_baseline": True}, "seed": 1, "ppo": {}},
                    {"episodes": 1000, "success_rate": 0.987654321, "success_rate_ci95": [0.97, 0.99],
                     "instructions_per_episode": 7.123456, "decisions_per_episode": 30.5, "ms_per_instruction": 0.3,
                     "evaluation_seed": 1000004, "iterations": 3, "training_wall_time_s": 70.04},
                    ["task=uniform", "speed=50", "method=reuse", "seed=1"])
    # Three iterations of 8, 3 and 2 s (relabelling 2.5, 0.5, 0.25); periodic evaluations at 0 s and 70 s; training
    # success first at or above 95 % at iteration 2 (50 s).
    write_scalars(run, [
        {"frames": 0, "train/iteration": 0, "time/wall_time": 0.0, "eval/success_rate": 0.004},
        {"frames": 100, "train/iteration": 1, "time/wall_time": 20.0, "time/iteration_seconds": 8.0,
         "time/reuse_seconds": 2.5, "train/success_rate": 0.5},
        {"frames": 200, "train/iteration": 2, "time/wall_time": 50.0, "time/iteration_seconds": 3.0,
         "time/reuse_seconds": 0.5, "train/success_rate": 0.96},
        {"frames": 300, "train/iteration": 3, "time/wall_time": 70.0, "time/iteration_seconds": 2.0,
         "time/reuse_seconds": 0.25, "train/success_rate": 0.97, "eval/success_rate": 0.97,
         "eval/instructions_per_episode": 7.5}])
    # Two independent evaluations: one inside the run, one beside it that names the run's checkpoint.
    write_evaluation(run / "eval_777", {"episodes": 10000, "success_rate": 0.9983, "seed": 777,
                                        "instructions_per_episode": 6.9, "outcomes": {"out_of_airspace": 9}},
                     ["checkpoint=baseline", "seed=777"])
    write_evaluation(runs / "sweep" / "eval_s1_4242",
                     {"episodes": 10000, "success_rate": 0.9979, "seed": 4242, "instructions_per_episode": 7.0,
                      "checkpoint": "/elsewhere/runs/sweep/reuse_s1/checkpoints/latest.pt"},
                     ["checkpoint=runs/sweep/reuse_s1", "seed=4242"])
    # An evaluation of a checkpoint outside the folder belongs to no run.
    write_evaluation(runs / "shipped_eval", {"episodes": 100, "success_rate": 1.0, "seed": 5,
                                             "checkpoint": "agrl/baselines/fixed_baseline.pt"}, ["seed=5"])
    # The folder's own small result files are copied; scripts, logs, a too-large table and a checkpoint are not.
    (runs / "sitting.sh").write_text("python -m agrl.train\n")
    (runs / "sitting.log").write_text("commit abc\n")
    (runs / "bench.jsonl").write_text('{"name": "x", "value": 1}\n')
    (runs / "huge.csv").write_text("x" * 200_001)
    (runs / "soup.pt").write_bytes(b"\0")
    assert main(["extract", str(runs), str(tmp_path / "data")]) == 0
    assert capsys.readouterr().out.strip() == f"{tmp_path / 'data'}: 1 runs, 4 evaluations, 2 curve points, 1 " \
                                              "files copied"
    data = tmp_path / "data"
    assert sorted(path.name for path in data.iterdir()) == ["bench.jsonl", "curves.csv", "evaluations.csv",
                                                             "runs.csv"]
    [row] = read_rows(data / "runs.csv")
    assert {key: row[key] for key in ("run", "task", "speed", "radius", "method", "reward", "switch_cost", "seed",
                                      "actions", "overrides")} == {
        "run": "sweep/reuse_s1", "task": "uniform", "speed": "50", "radius": "", "method": "reuse_from_baseline",
        "reward": "switch (k = 0.1, no continuous-action term)", "switch_cost": "0.1", "seed": "1",
        "actions": "maneuvers",  # the run's config has no actions group: written before it existed
        "overrides": "task=uniform speed=50 method=reuse seed=1"}
    assert {key: row[key] for key in ("training_seconds", "iterations", "episodes", "success", "success_low",
                                      "instructions", "evaluation_seed")} == {
        "training_seconds": "70", "iterations": "3", "episodes": "1000", "success": "0.98765", "success_low": "0.97",
        "instructions": "7.1235", "evaluation_seed": "1000004"}
    # Costs: the first iteration, then the median of the others; relabelling also over all iterations.
    assert {key: row[key] for key in ("iterations_logged", "iteration_seconds_first", "iteration_seconds_median",
                                      "relabel_seconds_first", "relabel_seconds_median",
                                      "relabel_seconds_median_all", "train_95_iteration", "train_95_seconds")} == {
        "iterations_logged": "3", "iteration_seconds_first": "8", "iteration_seconds_median": "2.5",
        "relabel_seconds_first": "2.5", "relabel_seconds_median": "0.375", "relabel_seconds_median_all": "0.5",
        "train_95_iteration": "2", "train_95_seconds": "50"}
    evaluations = {row["evaluation"]: row for row in read_rows(data / "evaluations.csv")}
    assert list(evaluations) == ["shipped_eval", "sweep/eval_s1_4242", "sweep/reuse_s1/eval",
                                 "sweep/reuse_s1/eval_777"]  # by run ('' first), then folder
    assert [evaluations[name]["run"] for name in evaluations] == ["", "sweep/reuse_s1", "sweep/reuse_s1",
                                                                  "sweep/reuse_s1"]
    assert [evaluations[name]["final"] for name in evaluations] == ["0", "0", "1", "0"]
    assert evaluations["sweep/reuse_s1/eval"]["seed"] == "1000004"
    assert (evaluations["sweep/reuse_s1/eval_777"]["seed"], evaluations["sweep/reuse_s1/eval_777"]["success"],
            evaluations["sweep/reuse_s1/eval_777"]["out_of_airspace"]) == ("777", "0.9983", "9")
    assert evaluations["sweep/eval_s1_4242"]["overrides"] == "checkpoint=runs/sweep/reuse_s1 seed=4242"
    # Only the periodic evaluations are curve points; the training success is the iteration's they followed.
    assert [(row["iteration"], row["seconds"], row["success"], row["instructions"], row["train_success"])
            for row in read_rows(data / "curves.csv")] == [("0", "0", "0.004", "", ""),
                                                            ("3", "70", "0.97", "7.5", "0.97")]
    # A table from the data folder equals the table from the runs folder (extracted in memory).
    assert main(["summary", str(data), "--by", "method"]) == 0
    from_data = capsys.readouterr().out
    assert main(["summary", str(runs), "--by", "method"]) == 0
    assert capsys.readouterr().out == from_data
    assert "| reuse_from_baseline | 1 | 98.77 % | 7.12 | 70.0 | 3 | 99.83 %, 6.90 (1/1) | 99.79 %, 7.00 (1/1) |" \
        in from_data
    # A path below a data folder is its runs below that path, named from there, as from the runs folder.
    assert main(["runs", str(data / "sweep"), "--independent", "777"]) == 0
    [line] = capsys.readouterr().out.strip().splitlines()[2:]
    assert line.startswith("| reuse_s1 | 0.4 % |") and line.endswith("| 99.83 %, 6.90 |")
    assert load_data(data / "sweep")["evaluations.csv"][0]["evaluation"] == "eval_s1_4242"
    # Grouped by a column of the evaluations alone, the summary is one of evaluations (here, each its own).
    assert main(["summary", str(data), "--by", "evaluation"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == ("| evaluation | evaluations | episodes | success | instructions | decisions | "
                        "out of airspace | budget exhausted |")
    assert lines[2:4] == ["| shipped_eval | 1 | 100 | 100.00 % | - | - | - | - |",
                          "| sweep/eval_s1_4242 | 1 | 10000 | 99.79 % | 7.00 | - | - | - |"]


def test_an_oldest_run_keeps_its_config_in_hydra_and_its_evaluation_and_metrics_csv_beside_it(tmp_path):
    root = tmp_path / "baseline_old"
    (root / "hydra").mkdir(parents=True)
    OmegaConf.save(OmegaConf.create({"task": {"name": "fixed"}, "reward": {"name": "both"},
                                     "method": {"name": "scratch"}, "seed": 0, "ppo": {}}),
                   root / "hydra" / "config.yaml")
    (root / "eval.json").write_text(json.dumps({"success_rate": 0.99, "instructions_per_episode": 19.0,
                                                "training_wall_time_s": 600.0}))
    (root / "metrics.csv").write_text("iteration,frames,wall_time,train/success_rate,eval/success_rate\n"
                                      "0,0,0.0,,0.5\n1,100,10.0,0.6,\n2,200,20.0,0.97,0.98\n")
    data = extract(root)
    [run] = data["runs.csv"]
    assert (run["run"], run["task"], run["reward"], run["success"], run["train_95_seconds"]) == \
        (".", "fixed", "both", 0.99, 20.0)
    assert [(row["seconds"], row["success"]) for row in data["curves.csv"]] == [(0.0, 0.5), (20.0, 0.98)]
    assert [row["evaluation"] for row in data["evaluations.csv"]] == ["."]


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


# ---------------------------------------------------------------------------- moving destinations
def test_median_time_counts_a_run_that_never_got_there_as_infinitely_slow(tmp_path):
    make_run(tmp_path, "a", "scratch", 50, 0.99, [(0, 0.0), (60, 0.96)])
    make_run(tmp_path, "b", "scratch", 50, 0.50, [(0, 0.0), (60, 0.5)])
    runs = {run["run"]: run for run in runs_below(tmp_path)}
    assert median_minutes_to([runs["a"]], 0.95) == 1.0
    assert math.isinf(median_minutes_to([runs["a"], runs["b"]], 0.95))


def test_targets_compare_reuse_with_the_other_methods(tmp_path):
    # Reuse reaches 95 % after 2 minutes: faster than scratch (3), slower than pre-trained (1).
    # Training success (third value) gets there earlier: scratch at 1.5 minutes, reuse at 1.
    for name, method, seconds in (("s", "scratch", 180), ("p", "pretrained", 60), ("r", "reuse", 120)):
        make_run(tmp_path, name, method, 50, 0.995, [(0, 0.1), (seconds / 2, 0.5, 0.96), (seconds, 0.97)])
    make_run(tmp_path, "rb", "reuse", 50, 0.999, [(0, 0.9), (30, 0.99)], start_from_baseline=True)
    runs = runs_below(tmp_path)
    assert sorted(run["method"] for run in runs) == ["pretrained", "reuse", "reuse_from_baseline", "scratch"]
    text = moving_tables(runs, figure_dir=None)
    target_row = next(line for line in text.splitlines() if line.startswith("| uniform 50 m/s"))
    assert target_row.split(" | ")[1:7] == ["3.00 / 1.50", "1.00 / 0.50", "2.00 / 1.00", "0.50 / 0.50",
                                            "yes / yes", "no / no"]
    assert "Policy reuse, Z starting from B" in text


def test_an_empty_folder_is_a_one_line_error(tmp_path, capsys):
    assert main(["moving", str(tmp_path)]) == 2
    error = capsys.readouterr().err
    assert str(tmp_path) in error and len(error.strip().splitlines()) == 1


def test_a_missing_folder_bad_times_and_a_bad_key_are_refused_naming_them(tmp_path, capsys):
    for arguments, message in (
            (["runs", str(tmp_path / "nowhere")],
             f"{tmp_path / 'nowhere'}: no such folder; allowed: a data folder, a path below one, or a folder "
             "containing runs"),
            (["runs", str(tmp_path), "--times", "60", "-5"], "--times 60 -5 is not allowed: seconds > 0"),
            (["summary", str(tmp_path), "--by", "colour"], "--by colour is not allowed: one of run, task,")):
        with pytest.raises(SystemExit) as exited:
            main(arguments)
        assert exited.value.code == 2
        assert capsys.readouterr().err.strip().splitlines()[-1].startswith(f"python -m agrl.report: error: {message}")


def test_a_setting_no_seed_got_to_95_percent_says_so_and_without_reuse_there_is_no_comparison(tmp_path):
    make_run(tmp_path, "p", "pretrained", 50, 0.90, [(0, 0.0), (120, 0.9)])
    text = moving_tables(runs_below(tmp_path), figure_dir=None)
    assert "| Pre-trained algorithm | 90.0 % (n=1); 95 % evaluation success not reached (0/1); paper 99.2 % |" in text
    assert "Against the targets" not in text  # no reuse run: nothing to compare


def test_figures_are_linked_from_their_own_folder_and_checked_first(tmp_path, capsys):
    make_run(tmp_path / "runs", "r", "reuse", 20, 0.97, [(0, 0.0), (120, 0.96)])
    text = moving_tables(runs_below(tmp_path / "runs"), figure_dir=tmp_path / "figs")
    assert "![uniform 20](figs/uniform_20.png)" in text and (tmp_path / "figs" / "uniform_20.png").is_file()
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    assert main(["moving", str(tmp_path / "runs"), "--figures", str(blocker / "figs")]) == 2
    assert capsys.readouterr().err.strip().startswith(f"agrl.report: error: --figures: {blocker / 'figs'}")


def test_a_method_not_run_shows_as_a_dash_not_a_comparison(tmp_path):
    make_run(tmp_path, "p", "pretrained", 100, 0.99, [(0, 0.0), (240, 0.96)])
    make_run(tmp_path, "r", "reuse", 100, 0.98, [(0, 0.0), (300, 0.96)])
    text = moving_tables(runs_below(tmp_path), figure_dir=None)
    target_row = next(line for line in text.splitlines() if line.startswith("| uniform 100 m/s"))
    assert target_row.split(" | ")[1:7] == ["- / -", "4.00 / 4.00", "5.00 / 5.00", "- / -", "- / -", "no / no"]


def test_the_final_evaluation_is_the_last_point_when_no_periodic_one_got_there(tmp_path):
    # Periodic evaluations stopped at 90 %; the final 1000-episode evaluation after 180 s found 97 %.
    make_run(tmp_path, "late", "reuse", 20, 0.97, [(0, 0.0), (120, 0.9, 0.96)], training_seconds=180.0)
    make_run(tmp_path, "never", "reuse", 20, 0.80, [(0, 0.0), (120, 0.9)], training_seconds=180.0)
    runs = {run["run"]: run for run in runs_below(tmp_path)}
    assert run_time_to_reach(runs["late"], 0.95) == (2, 180.0)
    assert run_time_to_reach(runs["never"], 0.95) is None
    # Training success has no final point: it is what the training episodes measured.
    assert run_time_to_reach(runs["late"], 0.95, "train/success_rate") == (1, 120.0)
    assert run_time_to_reach(runs["never"], 0.95, "train/success_rate") is None


def test_the_irregular_destination_is_named_without_a_speed(tmp_path):
    run = make_run(tmp_path, "i", "reuse", 0, 0.99, [(0, 0.1), (60, 0.96)])
    OmegaConf.save(OmegaConf.create({"task": {"name": "irregular", "speed": None}, "reward": {"name": "both"},
                                     "method": {"name": "reuse", "start_from_baseline": False}, "seed": 0}),
                   run / ".hydra" / "config.yaml")
    text = moving_tables(runs_below(tmp_path), figure_dir=None)
    assert any(line.startswith("| irregular | ") for line in text.splitlines()), text
    assert "| Method | Irregular |" in text


def test_the_sample_rebuilds_its_table_and_figure(tmp_path, capsys):
    """Real runs (uniform 50 m/s, 4 methods, 3 seeds, from docs/results/data/tables45_two_stage_2026-12-03) as CSVs:
    the moving-destination table is the one kept beside them, and each setting's figure is drawn, the same bytes
    twice."""
    assert main(["moving", str(SAMPLE), "--figures", str(tmp_path / "figures")]) == 0
    assert capsys.readouterr().out == (SAMPLE / "moving.md").read_text()
    figure = tmp_path / "figures" / "uniform_50.png"
    first = figure.read_bytes()
    assert first[:8] == b"\x89PNG\r\n\x1a\n" and len(first) > 10_000
    assert main(["moving", str(SAMPLE), "--figures", str(tmp_path / "figures")]) == 0
    assert figure.read_bytes() == first


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
    def evaluation(success, instructions, **others):
        return {"success_rate": success, "instructions_per_episode": instructions, "ms_per_instruction": 0.3,
                **others}

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
            write_evaluation(run / "eval_777", evaluation(success, instructions, seed=777, episodes=10000),
                             ["seed=777"])
    assert main(["table3", str(tmp_path), "--independent", "eval_777"]) == 0
    by_folder = capsys.readouterr().out
    assert main(["table3", str(tmp_path), "--independent", "777"]) == 0  # the same evaluations, by seed
    assert capsys.readouterr().out == by_folder
    lines = by_folder.strip().splitlines()
    assert lines[0].endswith("| seed 777 (10 000): success, instructions | Paper: success, instructions, ms |")
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


# ---------------------------------------------------------------------------- runs, summary, bench
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
    assert main(["runs", str(tmp_path), "--runs", "reuse_*"]) == 0  # a pattern keeps some runs
    assert [line.split(" | ")[0] for line in capsys.readouterr().out.strip().splitlines()[2:]] == ["| reuse_s0"]


def test_the_summary_groups_seeds_by_variant_and_series(tmp_path, capsys):
    for name, seed, lr, success in (("lr1e-3_s0", 0, "1e-3", 0.99), ("lr1e-3_s1", 1, "1e-3", 0.97),
                                    ("lr2e-3_s0", 0, "2e-3", 0.98)):
        write_run(tmp_path, name, {"task": {"name": "fixed"}, "reward": {"name": "both"},
                                   "method": {"name": "scratch"}, "seed": seed, "ppo": {}},
                  {"success_rate": success, "instructions_per_episode": 10.0 + seed, "training_wall_time_s": 30.0,
                   "iterations": 20}, [f"ppo.lr={lr}", f"seed={seed}", "hydra.run.dir=x"])
    for key, first_cell in (("variant", "`ppo.lr=1e-3`"), ("series", "lr1e-3")):
        assert main(["summary", str(tmp_path), "--by", key]) == 0
        lines = capsys.readouterr().out.strip().splitlines()
        assert lines[0] == f"| {key} | runs | final success | instructions | training s | iterations |"
        assert lines[2] == f"| {first_cell} | 2 | 98.00 ± 1.41 % | 10.50 ± 0.71 | 30.0 ± 0.0 | 20 ± 0 |"
        assert len(lines) == 4


def test_the_bench_table_has_a_line_per_measurement(tmp_path, capsys):
    results = tmp_path / "bench.jsonl"
    results.write_text('{"name": "machine", "value": 2, "unit": "torch threads", "cpu": "AMD"}\n'
                       "library logging, not a result\n"
                       '{"name": "simulator_decisions_per_second", "value": 16265.5, "unit": "decisions/s", '
                       '"batch": 1024, "compiled": false, "repeats": 5, "speedup_vs_reference": 1.3217}\n'
                       '{"name": "ppo_iteration_seconds", "value": 1.959, "unit": "s/iteration", "trainer": "agrl", '
                       '"collection_s": 0.419, "update_s": 1.541}\n')
    assert main(["bench", str(results)]) == 0
    assert capsys.readouterr().out.strip().splitlines() == [
        "| name | setting | value | unit | × the reference | collection s | update s | first call s |",
        "|---|---|---:|---|---:|---:|---:|---:|",
        "| simulator_decisions_per_second | batch=1024, compiled=false | 16,266 | decisions/s | 1.322 | - | - | - |",
        "| ppo_iteration_seconds | trainer=agrl | 1.959 | s/iteration | - | 0.419 | 1.541 | - |"]


# ---------------------------------------------------------------------------- pages
def test_pages_replace_a_block_and_check_finds_a_stale_one(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # block paths are relative to the folder pages runs from
    (tmp_path / "bench.jsonl").write_text('{"name": "guide_us", "value": 2, "unit": "us"}\n')
    page = tmp_path / "page.md"
    page.write_text("# Title\n\ntext\n<!-- report: bench bench.jsonl -->\nold table\n<!-- /report -->\nmore text\n")
    assert main(["pages", "--check", str(page)]) == 1
    assert capsys.readouterr().err.strip() == f"{page}:4: report block `bench bench.jsonl` is out of date " \
                                              "(text differs)"
    assert "old table" in page.read_text()  # --check writes nothing
    assert main(["pages", str(page)]) == 0
    assert page.read_text() == ("# Title\n\ntext\n<!-- report: bench bench.jsonl -->\n"
                                "| name | setting | value | unit | × the reference | collection s | update s | "
                                "first call s |\n"
                                "|---|---|---:|---|---:|---:|---:|---:|\n"
                                "| guide_us | - | 2 | us | - | - | - | - |\n<!-- /report -->\nmore text\n")
    assert main(["pages", "--check", str(tmp_path)]) == 0  # a folder: its pages
    (tmp_path / "bench.jsonl").write_text('{"name": "guide_us", "value": 4, "unit": "us"}\n')
    assert main(["pages", "--check", str(page)]) == 1  # the data changed: the block is stale


def test_a_bad_block_is_a_one_line_error_naming_the_file_and_line(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    page = tmp_path / "page.md"
    text = "# Title\n\n<!-- report: table3 no_such_folder -->\n<!-- /report -->\n<!-- report: bench x -->\n"
    page.write_text(text)
    assert main(["pages", str(page)]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert errors == [f"agrl.report: error: {page}:3: report block `table3 no_such_folder` failed: python -m "
                      "agrl.report: error: no_such_folder: no such folder; allowed: a data folder, a path below "
                      "one, or a folder containing runs",
                      f"agrl.report: error: {page}:5: report block without its closing <!-- /report -->"]
    assert page.read_text() == text  # a failed block is left as it was


def test_every_report_block_of_the_documentation_is_current(monkeypatch, capsys):
    monkeypatch.chdir(REPOSITORY)
    assert main(["pages", "--check"]) == 0, capsys.readouterr().err


def test_a_run_holding_targets_is_extracted_with_its_action_set(tiny_targets_run):
    from agrl.report.extract import extract

    data = extract(tiny_targets_run.run_dir.parent)
    [row] = [row for row in data["runs.csv"] if row["run"] == tiny_targets_run.run_dir.name]
    assert row["actions"] == "targets" and row["task"] == "fixed" and row["iterations"] == tiny_targets_run.iterations
