"""``ppo.collector_workers``: TorchRL's MultiSyncCollector (env processes) in place of the single Collector."""

from __future__ import annotations

import json

import pytest
import torch

from agrl.rl.trainer import Trainer

WORKERS = {"curriculum.enabled": "false", "ppo.collector_workers": "2"}


def batch_specs(batch) -> dict:
    return {key: (tuple(value.shape), value.dtype)
            for key, value in batch.items(include_nested=True, leaves_only=True)}


@pytest.mark.slow  # two spawned worker processes import torch and torchrl: about 25 s on a loaded 2-core machine
def test_worker_batches_have_the_single_collectors_specs_and_the_current_weights(tmp_path, compose_train,
                                                                                 tiny_args):
    """Same keys, shapes and dtypes as one Collector's batch; the workers step with the actor's latest weights."""
    single = Trainer(compose_train(*tiny_args({"curriculum.enabled": "false"})), tmp_path / "single")
    multi = Trainer(compose_train(*tiny_args(WORKERS)), tmp_path / "multi")
    try:
        expected = batch_specs(next(iter(single.collector)))
        batches = iter(multi.collector)
        first = next(batches)
        assert batch_specs(first) == expected
        # 32 envs in two workers of 16: every env's trajectory has its own id.
        assert first["collector", "traj_ids"][:, 0].unique().numel() == 32
        # The actor changes (as after a PPO update): the next batch's logits are the changed actor's.
        with torch.no_grad():
            for parameter in multi.actor.parameters():
                parameter.add_(0.5 * torch.randn_like(parameter))
        second = next(batches)
        with torch.no_grad():
            recomputed = multi.actor(second.select(*multi.actor.in_keys).clone())["logits"]
        torch.testing.assert_close(second["logits"], recomputed)
        # Exact resume needs the single collector's carried rows: a worker run's checkpoint has none (and the
        # config refuses resume with workers, tests/test_config.py).
        assert single._state()["carrier"] is not None and multi._state()["carrier"] is None
    finally:
        single.collector.shutdown()
        multi.collector.shutdown()


@pytest.mark.slow
def test_a_worker_run_learns(tmp_path, run_cli):
    """Pre-training from the shipped baseline on the 100 m/s destination with two collector workers, 10 iterations:
    the 256 evaluation episodes succeed more often after training than before (measured 2026-12-01, seed 0:
    22.7 % -> 50.4 %, about 10 minutes on a loaded 2-core machine)."""
    run_dir = tmp_path / "run"
    result = run_cli("train", "task=uniform", "speed=100", "method=pretrained", "seed=0", "ppo.collector_workers=2",
                     "simulation.compile=false", "ppo.total_frames=327680", "ppo.max_minutes=0", "eval.interval=5",
                     "eval.periodic_episodes=256", "eval.episodes=256", "eval.trajectory_image=false",
                     "progress=false", f"hydra.run.dir={run_dir}", timeout=30 * 60)
    assert result.returncode == 0, f"{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    from agrl.report import read_metrics

    before = read_metrics(run_dir)[0]["eval/success_rate"]  # the initial evaluation, same 256 episodes
    final = json.loads((run_dir / "eval" / "eval.json").read_text())
    print({"before": before, "final": final["success_rate"], "seconds": final["training_wall_time_s"]})
    assert final["success_rate"] >= before + 0.2, (before, final)
