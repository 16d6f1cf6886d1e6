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
@pytest.mark.parametrize("observation", ["relative", "absolute"])
def test_worker_batches_have_the_single_collectors_specs_and_the_current_weights(tmp_path, compose_train,
                                                                                 tiny_args, observation):
    """Same keys, shapes and dtypes as one Collector's batch; the workers step with the actor's latest weights
    (and compute the run's observation: its width is in the specs)."""
    single = Trainer(compose_train(*tiny_args({"curriculum.enabled": "false", "agent.observation": observation})),
                     tmp_path / "single")
    multi = Trainer(compose_train(*tiny_args({**WORKERS, "agent.observation": observation})), tmp_path / "multi")
    try:
        expected = batch_specs(next(iter(single.collector)))
        batches = iter(multi.collector)
        first = next(batches)
        # TorchRL's MultiSyncCollector always numbers episodes; the single collector only for a method reading them.
        assert batch_specs(first.exclude(("collector", "traj_ids"))) == expected
        # 32 envs in two workers of 16: every env's episode has its own id (what policy reuse reads).
        assert first["collector", "traj_ids"][:, 0].unique().numel() == 32
        # The actor changes (as after a PPO update): the next batch's actions were drawn by the changed actor, whose
        # log-probabilities of them the batch records.
        with torch.no_grad():
            for parameter in multi.actor.parameters():
                parameter.add_(0.5 * torch.randn_like(parameter))
        second = next(batches)
        with torch.no_grad():
            recomputed = multi.actor.get_dist(second.select(*multi.actor.in_keys).clone()).log_prob(second["action"])
        torch.testing.assert_close(second["action_log_prob"], recomputed)
        # Exact resume needs the single collector's carried rows: a worker run's checkpoint has none (and the
        # config refuses resume with workers, tests/test_config.py).
        assert single._state()["carrier"] is not None and multi._state()["carrier"] is None
    finally:
        single.collector.shutdown()
        multi.collector.shutdown()


@pytest.mark.slow  # four spawned worker processes: about 50 s on a loaded 2-core machine
def test_a_worker_run_is_reproducible_and_its_workers_fly_different_episodes(tmp_path, compose_train, tiny_args):
    """The same seed gives the same batches (starts and sampled actions); the two workers' starts differ."""
    batches = []
    for name in ("first", "second"):
        trainer = Trainer(compose_train(*tiny_args(WORKERS)), tmp_path / name)
        try:
            batches.append(next(iter(trainer.collector)))
        finally:
            trainer.collector.shutdown()
    first, second = batches
    assert torch.equal(first["action"], second["action"])
    assert torch.equal(first["aircraft_state"], second["aircraft_state"])
    starts = first["aircraft_state"][:, 0]  # 32 envs: the first 16 are worker 0's, the rest worker 1's
    assert not torch.equal(starts[:16], starts[16:])


@pytest.mark.slow
def test_a_worker_run_learns(tmp_path, run_cli):
    """Pre-training on the 100 m/s destination with two collector workers, 10 iterations: the 256 evaluation
    episodes succeed more often after training than before. Seeded workers make the run reproducible (before they
    were, runs of the same code differed by as much as the margin asserted). The margin, measured with this command
    at seeds 0 / 1 / 2: +0.31 / +0.25 / +0.05 (0.23 -> 0.54, 0.23 -> 0.49, 0.18 -> 0.23): seed 2 needs more than 10
    iterations, so the test keeps seed 0 and its +0.2 stays 0.11 inside what that seed gives. It starts from the shipped
    baseline-both-terms, for which these 10 iterations were sized: from baseline-stage1, pre-training at 100 m/s
    spends a few more iterations running out of decisions before success rises (docs/training.md, "The slow
    suite"), so 10 iterations would not show the rise. The margins were measured with the eager loss, which the
    command keeps: with the compiled one (the default since) seed 0 gave 0.23 -> 0.43, +0.199."""
    run_dir = tmp_path / "run"
    result = run_cli("train", "task=uniform", "speed=100", "method=pretrained", "method.baseline=baseline-both-terms",
                     "seed=0", "ppo.collector_workers=2", "ppo.compile_loss=false",
                     "simulation.compile=false", "ppo.total_frames=327680", "ppo.max_minutes=0", "eval.interval=5",
                     "eval.periodic_episodes=256", "eval.episodes=256", "eval.trajectory_image=false",
                     "progress=false", f"hydra.run.dir={run_dir}", timeout=30 * 60)
    assert result.returncode == 0, f"{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    from agrl.report import read_metrics

    before = read_metrics(run_dir)[0]["eval/success_rate"]  # the initial evaluation, same 256 episodes
    final = json.loads((run_dir / "eval" / "eval.json").read_text())
    print({"before": before, "final": final["success_rate"], "seconds": final["training_wall_time_s"]})
    assert final["success_rate"] >= before + 0.2, (before, final)


def fresh_starts(batch, skip_first_column: bool) -> torch.Tensor:
    """Aircraft states of the rows where an episode starts (step count 0); ``skip_first_column`` leaves out the
    first row of each env, which the previous batch's last step may already have reset."""
    fresh = batch["step_count"].squeeze(-1) == 0
    if skip_first_column:
        fresh[:, 0] = False
    return batch["aircraft_state"][fresh]


def inside_box(states: torch.Tensor, box, scale: float) -> torch.Tensor:
    """Rows of ``states`` inside conf's start box shrunk by ``scale`` towards a destination at the origin: the
    horizontal bounds scale about 0, the altitude band from its floor (agrl.core.initial_states)."""
    slack = 0.01  # m: float32 draws on the box's edge
    x, y, z = states[:, 0], states[:, 1], states[:, 2]
    (x_low, x_high), (y_low, y_high), (z_low, z_high) = box.x_range, box.y_range, box.z_range
    return ((x >= scale * x_low - slack) & (x <= scale * x_high + slack) & (y >= scale * y_low - slack)
            & (y <= scale * y_high + slack) & (z >= z_low - slack) & (z <= z_low + scale * (z_high - z_low) + slack))


@pytest.mark.slow  # two spawned worker processes import torch and torchrl: about 25 s on a loaded 2-core machine
def test_a_curriculum_promotion_reaches_the_workers_next_resets(tmp_path, compose_train, tiny_args):
    """The workers' new episodes start in the trainer's current box: the initial box in the first batch, the
    promoted box in the batch after a promotion (episodes of 3 decisions: about 150 starts per batch)."""
    cfg = compose_train(*tiny_args({"ppo.collector_workers": "2", "curriculum.enabled": "true",
                                    "curriculum.initial_scale": "0.15", "curriculum.scale_step": "0.5",
                                    "simulation.max_decisions": "3"}))
    assert cfg.simulation.initial_state.x_range[0] < 0 < cfg.simulation.initial_state.x_range[1]
    trainer = Trainer(cfg, tmp_path / "run")
    try:
        batches = iter(trainer.collector)
        first = next(batches)
        trainer._advance_curriculum({"train/success_rate": 1.0})  # as after an iteration that earned a promotion
        assert trainer.counters.curriculum_scale == pytest.approx(0.65)
        second = next(batches)
    finally:
        trainer.collector.shutdown()
    box = cfg.simulation.initial_state
    before = fresh_starts(first, skip_first_column=False)
    assert before.shape[0] >= 100 and bool(inside_box(before, box, 0.15).all())
    after = fresh_starts(second, skip_first_column=True)
    assert after.shape[0] >= 100 and bool(inside_box(after, box, 0.65).all())
    # Not still the old box: most of the new box lies outside it.
    assert float((~inside_box(after, box, 0.15)).float().mean()) > 0.5
