"""A decoding rule, not a trained change: fly the previous maneuver unless another beats it by a margin.

The deterministic policy is the argmax of log-probabilities; here the maneuver being flown gets ``bonus`` added
to its log-probability first (the last maneuver is the one-hot at the end of the policy input), so the agent
changes maneuver only when the network prefers another by more than a factor e^bonus. bonus 0 is the agent as
trained. Usage:

    python hold.py <output.json> <seed> <checkpoint> [<checkpoint> ...]

evaluates each checkpoint on 10 000 episodes from ``seed`` for bonus 0, 0.25, 0.5, 1 and 2.
"""

import json
import sys

import torch
from torch import nn

from agrl.config import TaskConfig, saved_agent_config, saved_guidance_parameters, validated_section
from agrl.envs.guidance import NUM_ACTIONS, GuidanceEnv
from agrl.evaluate import load_agent
from agrl.rl.evaluation import run_episodes, summarise
from agrl.rl.models import _categorical_actor, logits_network

BONUSES = (0.0, 0.25, 0.5, 1.0, 2.0)


class HoldBonus(nn.Module):
    def __init__(self, network: nn.Module, bonus: float):
        super().__init__()
        self.network, self.bonus = network, bonus

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        last_maneuver = observation[..., -NUM_ACTIONS:]  # one-hot, the last features of either observation
        return self.network(observation).log_softmax(-1) + self.bonus * last_maneuver


def main(output: str, seed: int, checkpoints: list[str]) -> None:
    rows = []
    for checkpoint in checkpoints:
        actor, saved, _ = load_agent(checkpoint)
        task = validated_section(TaskConfig, saved["task"])
        params = saved_guidance_parameters(saved, task)
        for bonus in BONUSES:
            env = GuidanceEnv(params, num_envs=10_000, seed=seed, observation=saved_agent_config(saved).observation)
            summary = summarise(run_episodes(env, _categorical_actor(HoldBonus(logits_network(actor), bonus))))
            row = {"checkpoint": checkpoint, "seed": seed, "bonus": bonus, "success_rate": summary["success_rate"],
                   "instructions_per_episode": summary["instructions_per_episode"],
                   "decisions_per_episode": summary["decisions_per_episode"], "outcomes": summary["outcomes"]}
            print(json.dumps(row), flush=True)
            rows.append(row)
    with open(output, "w") as file:
        json.dump(rows, file, indent=1)


if __name__ == "__main__":
    torch.set_num_threads(1)
    main(sys.argv[1], int(sys.argv[2]), sys.argv[3:])
