"""``python -m agrl.report``: tables from run directories (hand-written run folders, the report's real input)."""

from __future__ import annotations

import json
import math
from pathlib import Path

from omegaconf import OmegaConf

from agrl.report import find_runs, main, median_minutes_to, method_of, moving_tables, run_time_to_reach


def make_run(root: Path, name: str, method: str, speed: float, success: float, curve: list[tuple[float, float]],
             start_from_baseline: bool = False, training_seconds: float | None = None) -> Path:
    """A finished run: its Hydra config, eval.json and metrics.csv of (wall seconds, evaluation success)."""
    run = root / name
    (run / ".hydra").mkdir(parents=True)
    (run / "eval").mkdir()
    config = {"task": {"name": "uniform", "speed": speed}, "reward": {"name": "both"},
              "method": {"name": method, "start_from_baseline": start_from_baseline}, "seed": 0}
    OmegaConf.save(OmegaConf.create(config), run / ".hydra" / "config.yaml")
    final = {"success_rate": success}
    if training_seconds is not None:
        final.update(training_wall_time_s=training_seconds, iterations=len(curve))
    (run / "eval" / "eval.json").write_text(json.dumps(final))
    rows = ["iteration,frames,wall_time,eval/success_rate,train/success_rate"]
    # A point is (wall seconds, evaluation success) or (wall seconds, evaluation success, training success).
    rows += [f"{i},{i * 100},{point[0]},{point[1]},{point[-1]}" for i, point in enumerate(curve)]
    (run / "metrics.csv").write_text("\n".join(rows) + "\n")
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
