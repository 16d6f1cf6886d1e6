"""python evaluate_soups.py <out.json> <iterations,...> <seeds,...> <run dir> [<run dir> ...]

The weight average of several runs' actors taken at the same iteration (each run's iterates.pt, written by
train_keep_iterates.py), for each given iteration, on 10 000 episodes from each evaluation seed."""
import json, sys
from pathlib import Path
import torch
from agrl.config import TaskConfig, saved_agent_config, saved_guidance_parameters, validated_section
from agrl.envs.guidance import GuidanceEnv
from agrl.evaluate import load_agent
from agrl.rl.evaluation import run_episodes, summarise

def parse(item):  # "48" = that iteration; "41-50" = every iteration from 41 to 50 averaged too
    first, _, last = item.partition("-")
    return list(range(int(first), int(last or first) + 1))
output, iterations, seeds = sys.argv[1], [parse(i) for i in sys.argv[2].split(",")], [int(s) for s in sys.argv[3].split(",")]
runs = [Path(r) for r in sys.argv[4:]]
torch.set_num_threads(1)
iterates = [torch.load(run / "iterates.pt", weights_only=True) for run in runs]
actor, saved, _ = load_agent(str(runs[0]))
params = saved_guidance_parameters(saved, validated_section(TaskConfig, saved["task"]))
observation = saved_agent_config(saved).observation
rows = []
for iteration in iterations:
    states = [run_iterates[i - 1]["actor"] for run_iterates in iterates for i in iteration]
    actor.load_state_dict({k: torch.stack([s[k].float() for s in states]).mean(0) if states[0][k].is_floating_point()
                           else states[0][k] for k in states[0]})
    for seed in seeds:
        s = summarise(run_episodes(GuidanceEnv(params, num_envs=10_000, seed=seed, observation=observation), actor))
        row = {"runs": [str(r) for r in runs], "iterations": iteration, "seed": seed, "success_rate": s["success_rate"],
               "instructions_per_episode": round(s["instructions_per_episode"], 3), "outcomes": s["outcomes"]}
        print(json.dumps(row), flush=True)
        rows.append(row)
json.dump(rows, open(output, "w"), indent=1)
