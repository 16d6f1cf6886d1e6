"""The trainer's start-box curriculum (agrl.rl.trainer with agrl.rl.curriculum): promotion, the environment's
start box, and exact resume below scale 1.

The tiny runs of the rest of the suite turn the curriculum off (tests/conftest.py); these turn it on, as the
default recipe (``python -m agrl.train``) does.
"""

from __future__ import annotations

import pytest
import torch
from test_trainer import assert_bitwise_equal  # tests/rl is on sys.path (pytest's default import mode)

from agrl.report import read_metrics
from agrl.rl.checkpoint import load_checkpoint
from agrl.rl.trainer import Trainer

pytestmark = pytest.mark.usefixtures("torch_one_thread")

CURRICULUM_ON = {"curriculum.enabled": "true", "curriculum.initial_scale": "0.15", "curriculum.scale_step": "0.1",
                 "curriculum.promotion_success": "0.8"}
#: conf/simulation/paper.yaml's start box and success distance (m), as the expectations below are built from.
X_RANGE, Y_RANGE, Z_RANGE = (-9_500.0, 7_000.0), (-9_500.0, 9_500.0), (0.0, 5_000.0)
MIN_HORIZONTAL_DISTANCE, SUCCESS_DISTANCE = 2_000.0, 1_000.0


def expected_box(scale: float) -> dict[str, tuple[float, float] | float]:
    """The start box at ``scale`` for the fixed task (destination start at the origin), by hand: every bound
    of x and y times the scale, the altitude's height times the scale above the floor, the exclusion disc
    times the scale but never below the success distance."""
    return {
        "x_range": (scale * X_RANGE[0], scale * X_RANGE[1]),
        "y_range": (scale * Y_RANGE[0], scale * Y_RANGE[1]),
        "z_range": (Z_RANGE[0], Z_RANGE[0] + scale * (Z_RANGE[1] - Z_RANGE[0])),
        "min_horizontal_distance": max(scale * MIN_HORIZONTAL_DISTANCE, SUCCESS_DISTANCE),
    }


def assert_env_start_box(env, scale: float) -> None:
    distribution = env.params.initial_state
    for key, value in expected_box(scale).items():
        assert getattr(distribution, key) == pytest.approx(value, abs=1e-9), (scale, key)
    # The starts the environment actually draws lie in that box.
    starts = env.reset()["aircraft_state"]
    box = expected_box(scale)
    for column, key in ((0, "x_range"), (1, "y_range"), (2, "z_range")):
        low, high = box[key]
        assert float(starts[:, column].min()) >= low - 1e-3 and float(starts[:, column].max()) <= high + 1e-3, key
    assert float(torch.hypot(starts[:, 0], starts[:, 1]).min()) > box["min_horizontal_distance"]


@pytest.fixture
def curriculum_trainer(tmp_path, compose_train, tiny_args):
    config = compose_train(*tiny_args({**CURRICULUM_ON, "ppo.num_envs": 256, "ppo.total_frames": 256 * 16}))
    return Trainer(config, tmp_path / "run")


def test_training_starts_at_the_initial_scale_and_evaluation_uses_the_full_box(curriculum_trainer):
    assert curriculum_trainer.counters.curriculum_scale == 0.15
    assert_env_start_box(curriculum_trainer.env, 0.15)
    assert_env_start_box(curriculum_trainer.eval_env, 1.0)


def test_promotion_grows_the_scale_by_the_step_up_to_1(curriculum_trainer):
    trainer = curriculum_trainer
    # min(1, 0.15 + 0.1 k): eight promotions reach 0.95, the ninth 1.0 (not 1.05), later ones change nothing.
    expected = [0.15 + 0.1 * k for k in range(1, 8 + 1)] + [1.0, 1.0]
    seen = []
    for scale in expected:
        # Just below the threshold: no promotion.
        below = {"train/success_rate": 0.8 - 1e-6}
        before = trainer.counters.curriculum_scale
        trainer._advance_curriculum(below)
        assert trainer.counters.curriculum_scale == before
        assert below["train/curriculum_scale"] == before
        # At the threshold: promoted, and the training env's start box follows.
        metrics = {"train/success_rate": 0.8}
        trainer._advance_curriculum(metrics)
        assert trainer.counters.curriculum_scale == pytest.approx(scale, abs=1e-9)
        assert metrics["train/curriculum_scale"] == trainer.counters.curriculum_scale
        assert_env_start_box(trainer.env, scale)
        seen.append(trainer.counters.curriculum_scale)
    assert seen[-2:] == [1.0, 1.0]
    # An iteration in which no episode ended has no success rate: no promotion.
    trainer.counters.curriculum_scale = 0.45
    trainer._advance_curriculum({"train/episodes": 0})
    assert trainer.counters.curriculum_scale == 0.45
    assert_env_start_box(trainer.eval_env, 1.0)  # evaluation never follows the curriculum


@pytest.mark.parametrize(("method", "uses_curriculum"), [("scratch", True), ("pretrained", False)])
def test_methods_from_a_baseline_train_on_the_full_box(compose_train, tiny_args, tmp_path, method, uses_curriculum):
    config = compose_train(*tiny_args(CURRICULUM_ON), f"method={method}")
    trainer = Trainer(config, tmp_path / "run")
    scale = 0.15 if uses_curriculum else 1.0
    assert trainer.counters.curriculum_scale == scale
    assert_env_start_box(trainer.env, scale)


# ---------------------------------------------------------------------------- exact resume below scale 1
#: Tiny runs with the curriculum on, promoted at 5 % training success: with seed 0, promotions after
#: iterations 1 and 2 (checked below), so the resume point (1) is at scale 0.25 and the resumed iteration
#: is promoted again. A periodic evaluation after every iteration: one in each half (the trajectory images,
#: not compared here, are not drawn); the final evaluation, after the last checkpoint, flies 4 episodes.
RESUME_CHANGES = {**CURRICULUM_ON, "curriculum.promotion_success": "0.05", "eval.interval": "1",
                  "eval.trajectory_image": "false", "eval.episodes": "4"}
ITERATIONS = 2


def test_resume_below_scale_1_matches_an_uninterrupted_run_bitwise(tmp_path, compose_train, tiny_args, run_cli):
    straight_dir, run = tmp_path / "straight", tmp_path / "run"
    Trainer(compose_train(*tiny_args({**RESUME_CHANGES, "ppo.total_frames": ITERATIONS * 512})), straight_dir).train()
    straight = load_checkpoint(straight_dir / "checkpoints" / "latest.pt")

    Trainer(compose_train(*tiny_args({**RESUME_CHANGES, "ppo.total_frames": ITERATIONS // 2 * 512})), run).train()
    half = load_checkpoint(run / "checkpoints" / "latest.pt")["counters"]
    # Preconditions: the run is interrupted between promotions, below scale 1, and is promoted after resuming.
    assert half["iteration"] == ITERATIONS // 2
    assert 0.15 < half["curriculum_scale"] < straight["counters"]["curriculum_scale"] < 1.0, (
        half["curriculum_scale"], straight["counters"]["curriculum_scale"])

    result = run_cli("train", f"resume={run}", f"ppo.total_frames={ITERATIONS * 512}",
                     f"hydra.run.dir={tmp_path / 'resume_hydra'}")
    assert result.returncode == 0, result.stderr[-3000:]
    resumed = load_checkpoint(run / "checkpoints" / "latest.pt")
    for key in ("actor", "critic", "optimizer", "carrier", "rng"):
        assert_bitwise_equal(resumed[key], straight[key], key)
    for key in ("iteration", "frames", "best_success", "curriculum_scale"):
        assert resumed["counters"][key] == straight["counters"][key], key
    columns = ("iteration", "frames", "train/success_rate", "eval/success_rate", "train/instructions_per_episode")
    rows = [[row.get(c) for c in columns] for row in read_metrics(run)]
    assert rows == [[row.get(c) for c in columns] for row in read_metrics(straight_dir)]
