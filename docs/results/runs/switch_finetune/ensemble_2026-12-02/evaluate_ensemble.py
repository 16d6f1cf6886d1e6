"""The mixture of several fine-tuned agents' policies (agrl.rl.models.make_ensemble_actor) on 10 000 episodes.

python docs/results/runs/switch_finetune/ensemble_2026-12-02/evaluate_ensemble.py SEED OUT.json RUN [RUN ...]
"""
import json
import sys

import torch

from agrl.config import saved_agent_config, saved_guidance_parameters
from agrl.envs.guidance import GuidanceEnv
from agrl.evaluate import load_agent
from agrl.rl.evaluation import run_episodes, summarise
from agrl.rl.models import make_ensemble_actor

seed, output, runs = int(sys.argv[1]), sys.argv[2], sys.argv[3:]
members = [load_agent(run) for run in runs]
actor = make_ensemble_actor([member[0] for member in members]).eval()
saved = members[0][1]
params = saved_guidance_parameters(saved)
env = GuidanceEnv(params, num_envs=10_000, seed=seed, observation=saved_agent_config(saved).observation)
with torch.no_grad():
    summary = summarise(run_episodes(env, actor))
summary.update({"members": [str(member[2]) for member in members], "seed": seed})
with open(output, "w") as file:
    json.dump(summary, file, indent=1)
print(json.dumps({key: summary[key] for key in ("success_rate", "instructions_per_episode", "decisions_per_episode",
                                                  "outcomes")}))
