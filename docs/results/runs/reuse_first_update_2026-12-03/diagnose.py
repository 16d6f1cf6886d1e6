"""Why does reuse + B's first PPO update move the policy so far? One collector batch of a moving-destination task,
relabelled as training does (Algorithm 1, Z starting from B), then the first update, measured on the rows stored:
advantages, probabilities and the change of greedy action, for own and relabelled rows separately; the same for
pre-training (no relabelling) from the same batch as a control. Untimed; one torch thread.

    python docs/results/runs/reuse_first_update_2026-12-03/diagnose.py task=uniform speed=50 [seed=0] [more overrides]

Prints one JSON object per method.
"""

from __future__ import annotations

import json
import sys
import tempfile

import torch

torch.set_num_threads(1)

from agrl.config import compose_config, load_config  # noqa: E402
from agrl.rl.ppo import ppo_update  # noqa: E402
from agrl.rl.trainer import Trainer  # noqa: E402


def describe(rows, actor, name: str) -> dict:
    """Advantage, old probability of the stored action, and whether it is the actor's greedy action."""
    with torch.no_grad():
        distribution = actor.get_dist(rows)
        greedy = distribution.probs.argmax(-1)
        action = rows["action"]
        action_index = action.argmax(-1) if action.dim() > greedy.dim() else action
    advantage = rows["advantage"].reshape(-1)
    return {
        f"{name}_rows": int(rows.numel()),
        f"{name}_advantage_mean": round(float(advantage.mean()), 4),
        f"{name}_advantage_std": round(float(advantage.std()), 4),
        f"{name}_advantage_negative_fraction": round(float((advantage < 0).float().mean()), 3),
        f"{name}_action_is_greedy_fraction": round(float((action_index == greedy).float().mean()), 3),
        f"{name}_action_probability_mean": round(float(rows["action_log_prob"].exp().mean()), 3),
        f"{name}_value_error_mean": round(float((rows["value_target"] - rows["state_value"]).mean()), 4),
    }


def first_update(overrides: list[str]) -> dict:
    config = load_config(compose_config(*overrides, "progress=false", "threads=1"))
    with tempfile.TemporaryDirectory() as run_dir:
        trainer = Trainer(config, run_dir)
        data = next(iter(trainer.collector))
        with torch.no_grad():
            data = trainer.advantage(data)
        trainer.buffer.empty()
        trainer.buffer.extend(trainer._buffer_rows(data))
        rows = trainer.buffer[:]
        record = {"overrides": overrides}
        if "relabelled" in rows.keys():
            relabelled = rows["relabelled"].reshape(-1)
            flat = rows.reshape(-1)
            record.update(describe(flat[~relabelled], trainer.actor, "own"))
            record.update(describe(flat[relabelled], trainer.actor, "relabelled"))
        else:
            record.update(describe(rows.reshape(-1), trainer.actor, "own"))
        # The states the agent really meets on this task: the batch's own observations (real destination).
        states = data.reshape(-1)[:: max(1, data.numel() // 8192)].select("observation").clone()
        with torch.no_grad():
            before = trainer.actor.get_dist(states).probs
        losses = ppo_update(trainer.update_loss, trainer.optimizer, trainer.buffer, config.ppo.epochs,
                            config.ppo.max_grad_norm, where="diagnosis", target_kl=config.ppo.target_kl)
        with torch.no_grad():
            after = trainer.actor.get_dist(states).probs
        kl = (before * (before.clamp_min(1e-12).log() - after.clamp_min(1e-12).log())).sum(-1)
        record.update({
            "update_kl_approx": round(losses["kl_approx"], 4),
            "update_clip_fraction": round(losses["clip_fraction"], 3),
            "update_minibatches": int(losses["minibatches"]),
            "real_states_kl_mean": round(float(kl.mean()), 4),
            "real_states_greedy_changed_fraction": round(float((before.argmax(-1) != after.argmax(-1)).float().mean()),
                                                         3),
        })
        trainer.collector.shutdown()
        return record


if __name__ == "__main__":
    task = sys.argv[1:] or ["task=uniform", "speed=50"]
    for method in (["method=pretrained"], ["method=reuse", "method.start_from_baseline=true"]):
        print(json.dumps(first_update([*task, *method])), flush=True)
