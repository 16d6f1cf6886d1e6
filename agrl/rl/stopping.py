"""Why a training run stops: a budget (decisions, minutes, the fine-tune's iterations) or a periodic evaluation at
``target_success``. Pure functions of the run's config, its counters and one iteration's metrics."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from agrl.config import TrainConfig
    from agrl.rl.run_state import Counters

__all__ = ["budget_spent", "target_reached"]


def budget_spent(cfg: TrainConfig, counters: Counters) -> str | None:
    """Which budget the run has used up, if any: ``ppo.total_frames``, ``ppo.max_minutes`` (0 = none) or, once the
    fine-tune has begun (``counters.finetune_from``), ``finetune.iterations``."""
    ppo, finetune = cfg.ppo, cfg.finetune
    if counters.frames >= ppo.total_frames:
        return f"reached ppo.total_frames={ppo.total_frames}"
    if ppo.max_minutes and counters.wall_time >= 60 * ppo.max_minutes:
        return f"reached ppo.max_minutes={ppo.max_minutes}"
    if counters.finetune_from and counters.iteration - counters.finetune_from >= finetune.iterations:
        return f"fine-tuned for finetune.iterations={finetune.iterations} at switch cost {finetune.switch_cost}"
    return None


def target_reached(cfg: TrainConfig, metrics: dict[str, float]) -> str | None:
    """Whether this iteration's periodic evaluation reached ``target_success`` (0 = never), on the confirmation
    episodes too when ``eval.confirm_episodes`` asks for them."""
    target, confirm = cfg.target_success, cfg.eval.confirm_episodes
    success = metrics.get("eval/confirm_success_rate" if confirm else "eval/success_rate")
    if target and success is not None and success >= target:
        confirmed = f", confirmed on {confirm} other episodes ({success:.4f})" if confirm else ""
        return f"periodic evaluation reached target_success={target}{confirmed}"
    return None
