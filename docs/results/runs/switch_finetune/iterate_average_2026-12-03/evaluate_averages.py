"""python evaluate_averages.py <run dir> <out.json> <seed> [<seed> ...]: the live iterate against averages of iterates."""
import json, sys
from pathlib import Path
import torch
from agrl.config import TaskConfig, saved_agent_config, saved_guidance_parameters, validated_section
from agrl.envs.guidance import GuidanceEnv
from agrl.evaluate import load_agent
from agrl.rl.evaluation import run_episodes, summarise

run_dir, output, seeds = Path(sys.argv[1]), sys.argv[2], [int(s) for s in sys.argv[3:]]
torch.set_num_threads(1)
iterates = torch.load(run_dir / "iterates.pt", weights_only=True)
actor, saved, _ = load_agent(str(run_dir))
task = validated_section(TaskConfig, saved["task"])
params = saved_guidance_parameters(saved, task)
observation = saved_agent_config(saved).observation

def ema(decay, start=0):
    average = None
    for state in iterates[start:]:
        if average is None:
            average = {k: v.clone().float() for k, v in state["actor"].items()}
        else:
            for k, v in state["actor"].items():
                if v.is_floating_point():
                    average[k].mul_(decay).add_(v, alpha=1 - decay)
    return average

def mean_last(n):
    states = [s["actor"] for s in iterates[-n:]]
    return {k: (torch.stack([s[k].float() for s in states]).mean(0) if states[0][k].is_floating_point() else states[-1][k]) for k in states[0]}

variants = {"live": iterates[-1]["actor"], "ema0.8": ema(0.8), "ema0.9": ema(0.9), "ema0.95": ema(0.95),
            "mean_last10": mean_last(10), "mean_last20": mean_last(20)}
rows = []
for name, state in variants.items():
    actor.load_state_dict(state)
    for seed in seeds:
        env = GuidanceEnv(params, num_envs=10_000, seed=seed, observation=observation)
        s = summarise(run_episodes(env, actor))
        row = {"run": str(run_dir), "variant": name, "seed": seed, "success_rate": s["success_rate"],
               "instructions_per_episode": round(s["instructions_per_episode"], 3), "outcomes": s["outcomes"]}
        print(json.dumps(row), flush=True)
        rows.append(row)
json.dump(rows, open(output, "w"), indent=1)
