"""Measure how many search row-decisions share an (episode, action history) prefix."""
import sys, torch, tempfile, types
from agrl.config import compose_config, load_config
from agrl.rl.trainer import Trainer
from agrl.rl import reuse as R
from agrl.core.termination import Outcome

stats = {"rows": 0, "unique": 0}
orig = R.PolicyReuseTransform._search_wave

def wave(self, start_rows, trajectory, motion, pending, wave, spacing, best, arrival, record):
    device = trajectory.device
    size = wave.numel()
    episode = pending.repeat_interleave(size)
    candidate = wave.repeat(pending.numel())
    budget = self.env.params.max_decisions
    target_step = self.candidates[candidate]
    stop = torch.minimum((target_step + spacing).clamp(max=budget), budget - start_rows["step_count"][episode])
    steps = int(stop.max())
    predicted = trajectory[episode, target_step]
    aircraft = start_rows["aircraft_state"][episode]
    destination = start_rows["destination_state"][episode]
    last_action = start_rows["last_action"][episode].long()
    reduce = "amin" if self.keep == "earliest" else "amax"
    history = torch.zeros_like(episode)
    for step in range(steps):
        if episode.numel() == 0:
            break
        # prefix key before this step's simulation: (episode, history of actions incl. this one)
        action = self._baseline_mode(self._predicted_observation(aircraft, predicted, last_action))
        history = (history * 1000003 + action + 1) % (2**61 - 1)
        key = episode * (2**20) + (history % (2**20))
        stats["rows"] += episode.numel(); stats["unique"] += torch.unique(torch.stack([episode, history]), dim=1).shape[1]
        result = self._simulate(aircraft, destination, motion[episode, step, 0], motion[episode, step, 1], action)
        success = result.outcome == Outcome.SUCCESS
        if bool(success.any()):
            arrival[episode[success], candidate[success]] = step + 1
            best.scatter_reduce_(0, episode[success], candidate[success], reduce=reduce)
        running = (result.outcome == Outcome.RUNNING) & (step + 1 < stop)
        running &= candidate < best[episode] if self.keep == "earliest" else candidate > best[episode]
        aircraft, destination, last_action = result.aircraft_state, result.destination_state, action
        keep = running.nonzero().squeeze(-1)
        episode, candidate, predicted, stop, history = (f[keep] for f in (episode, candidate, predicted, stop, history))
        aircraft, destination, last_action = aircraft[keep], destination[keep], last_action[keep]

R.PolicyReuseTransform._search_wave = wave
torch.set_num_threads(2)
overrides = sys.argv[1:] + ["method=reuse", "progress=false"]
config = load_config(compose_config(*overrides))
with tempfile.TemporaryDirectory() as d:
    trainer = Trainer(config, d)
    batch = next(iter(trainer.collector))
    trainer.collector.shutdown()
    with torch.no_grad():
        rows = trainer.advantage(batch).reshape(-1)
    for waves_mode in ["default", "one"]:
        if waves_mode == "one":
            R.candidate_waves = lambda c, keep: [torch.arange(c)]
        stats.update(rows=0, unique=0)
        trainer.reuse.selection_factor = 1.0
        trainer.reuse.relabel(rows)
        print(waves_mode, stats, stats["unique"] / stats["rows"], trainer.reuse.last_statistics()["train/reuse_episodes_relabelled"] if "train/reuse_episodes_relabelled" in trainer.reuse.last_statistics() else "")
