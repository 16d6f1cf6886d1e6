"""``finetune``: a run that reaches ``target_success`` trains ``finetune.iterations`` more at
``finetune.switch_cost`` (and ``finetune.learning_rate``) instead of stopping, and resumes inside that phase."""

from __future__ import annotations

import logging

import pytest
import torch

from agrl.report import read_metrics
from agrl.rl.checkpoint import load_checkpoint
from agrl.rl.trainer import Trainer

pytestmark = pytest.mark.usefixtures("torch_one_thread")

#: The shipped baseline succeeds in some of these short episodes from the start: a target of one success in 32
#: periodic episodes is met at once. Phase one pays no switch cost, the fine-tune 0.5 per instruction.
FINETUNE = {"ppo.total_frames": 10 * 512, "eval.interval": 1, "eval.periodic_episodes": 32, "target_success": 1 / 32,
            "reward.switch_cost": 0.0, "finetune.iterations": 3, "finetune.switch_cost": 0.5,
            "finetune.learning_rate": 1e-4, "eval.episodes": 4}


def test_the_target_starts_the_finetune_at_its_switch_cost_and_rate(tmp_path, compose_train, tiny_args, caplog):
    caplog.set_level(logging.INFO, logger="agrl.train")
    trainer = Trainer(compose_train(*tiny_args(FINETUNE), "method=pretrained"), tmp_path / "run")
    summary = trainer.train()
    rows = read_metrics(tmp_path / "run")[1:]  # row 0: before training
    first = next(index for index, row in enumerate(rows) if row["eval/success_rate"] >= 1 / 32) + 1
    assert summary["iterations"] == first + 3 == trainer.counters.finetune_from + 3
    before, during = rows[:first], rows[first:]
    assert all(row["train/reward_switch_cost"] == 0.0 for row in before)
    assert all(row["train/reward_switch_cost"] < 0.0 for row in during)  # the baseline changes maneuver often
    assert all(row["train/learning_rate"] == pytest.approx(1e-4) for row in during)
    assert all("eval/success_rate" not in row for row in during)  # the stop has fired: no more periodic evaluations
    assert trainer.env.params.reward.switch_cost == 0.5
    stops = [record.getMessage() for record in caplog.records if record.getMessage().startswith("training stopped")]
    assert stops == ["training stopped: fine-tuned for finetune.iterations=3 at switch cost 0.5"]


def test_an_annealed_rate_decays_the_finetunes_rate_once_it_has_begun(tmp_path, compose_train, tiny_args):
    trainer = Trainer(compose_train(*tiny_args(FINETUNE), "method=pretrained", "ppo.anneal_lr=true"), tmp_path / "run")
    trainer.train()
    rows = read_metrics(tmp_path / "run")[1:]
    total, start = FINETUNE["ppo.total_frames"], trainer.counters.finetune_from
    assert start and len(rows) > start
    for row in rows:  # a rate is set before its iteration's update, from the frames trained until then
        initial = 1e-4 if row["train/iteration"] > start else trainer.cfg.ppo.learning_rate
        frames_before = row["frames"] - 512
        assert row["train/learning_rate"] == pytest.approx(initial * (1 - frames_before / total)), row


def test_a_run_resumed_in_its_finetune_matches_an_uninterrupted_one_bitwise(tmp_path, compose_train, tiny_args,
                                                                             run_cli):
    straight = tmp_path / "straight"
    Trainer(compose_train(*tiny_args(FINETUNE), "method=pretrained"), straight).train()
    expected = load_checkpoint(straight / "checkpoints" / "latest.pt")
    start = expected["counters"]["finetune_from"]

    halted = tmp_path / "halted"  # the frame budget ends it one iteration into the fine-tune
    Trainer(compose_train(*tiny_args({**FINETUNE, "ppo.total_frames": (start + 1) * 512}), "method=pretrained"),
            halted).train()
    assert load_checkpoint(halted / "checkpoints" / "latest.pt")["counters"]["finetune_from"] == start
    result = run_cli("train", f"resume={halted}", f"ppo.total_frames={FINETUNE['ppo.total_frames']}",
                     f"hydra.run.dir={tmp_path / 'resume_hydra'}")
    assert result.returncode == 0, result.stderr[-3000:]
    resumed = load_checkpoint(halted / "checkpoints" / "latest.pt")
    assert resumed["counters"]["iteration"] == expected["counters"]["iteration"] == start + 3
    for part in ("actor", "critic"):
        for key, value in expected[part].items():
            assert torch.equal(resumed[part][key], value), f"{part}.{key}"
