"""Which of 10 000 episodes (seed 777) the five fine-tunes' ensemble and the shipped baseline fail.

python docs/results/runs/switch_finetune/ensemble_2026-12-02/failures.py docs/results/runs/switch_finetune/ensemble_2026-12-02
"""
import sys, torch
from agrl.config import saved_agent_config, saved_guidance_parameters
from agrl.envs.guidance import GuidanceEnv
from agrl.evaluate import load_agent
from agrl.rl.evaluation import run_episodes
from agrl.rl.models import make_ensemble_actor
out = sys.argv[1]
def fails(actor, saved):
    env = GuidanceEnv(saved_guidance_parameters(saved), num_envs=10_000, seed=777)
    with torch.no_grad():
        r = run_episodes(env, actor)
    return r
members = [load_agent(f"{out}/ft_s{s}") for s in range(5)]
ens = make_ensemble_actor([m[0] for m in members]).eval()
r_ens = fails(ens, members[0][1])
base, bsaved, _ = load_agent("baseline")
r_base = fails(base, bsaved)
f_ens = r_ens.outcome != 1
f_base = r_base.outcome != 1
print("outcome codes", torch.unique(r_ens.outcome))
print("ensemble fails", int(f_ens.sum()), "baseline fails", int(f_base.sum()), "both", int((f_ens & f_base).sum()))
torch.set_printoptions(precision=0, sci_mode=False, linewidth=200)
print("ensemble failures: x y z v outcome instr decisions | baseline outcome")
for i in torch.nonzero(f_ens).flatten():
    s = r_ens.initial_aircraft_state[i]
    print([round(float(v)) for v in s[:4]], int(r_ens.outcome[i]), int(r_ens.instructions[i]), int(r_ens.decisions[i]), '|', int(r_base.outcome[i]))
