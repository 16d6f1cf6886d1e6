"""``python -m agrl.evaluate``: the paper's evaluation of a trained agent (Hydra entry point).

Runs ``episodes`` deterministic episodes in one batch, prints the summary as one
JSON object on the last line of stdout, and writes ``eval.json``, ``episodes.csv``
and ``trajectories.png``. See ``conf/evaluate.yaml``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import hydra
import torch
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from agrl.cli import run_checked, writable_folder
from agrl.config import (
    ConfigError,
    TaskConfig,
    load_config,
    task_label,
    validated_section,
)
from agrl.rl.checkpoint import CheckpointError


def check_inputs(config) -> None:
    """What the evaluation reads and writes, checked before Hydra runs (agrl.cli.run_checked calls this): the
    checkpoint loads, and ``output_dir`` (if given) can be written (checked last: it creates the folder)."""
    from agrl.rl.models import load_agent

    load_agent(config.checkpoint)
    if config.output_dir:
        try:
            writable_folder(Path(config.output_dir) / "eval.json")
        except ConfigError as error:
            raise ConfigError(f"output_dir={config.output_dir} is not allowed: {error}") from None


def evaluate(cfg) -> dict[str, Any]:
    from agrl.envs.guidance import GuidanceEnv
    from agrl.plots import plot_trajectories
    from agrl.rl.evaluation import instruction_latency_ms, run_episodes, summarise, write_evaluation
    from agrl.rl.models import load_agent

    device = torch.device(cfg.device)
    if cfg.threads is not None:
        torch.set_num_threads(cfg.threads)
    output = Path(cfg.output_dir or HydraConfig.get().runtime.output_dir)
    writable_folder(output / "eval.json")  # before the episodes, not after them
    actor, saved, path = load_agent(cfg.checkpoint, device)
    task = cfg.task if cfg.task is not None else validated_section(TaskConfig, saved["task"])
    env = GuidanceEnv.for_saved_agent(saved, cfg.episodes, task=task, device=device, seed=cfg.seed)
    records = run_episodes(env, actor, trajectories=cfg.trajectories)
    summary = summarise(records)
    summary["ms_per_instruction"] = instruction_latency_ms(env, actor)
    summary.update({"checkpoint": str(path), "task": task.name, "speed": task.speed, "radius": task.radius,
                    "seed": cfg.seed, "trained_task": saved["task"]["name"], "method": saved["method"]["name"]})
    write_evaluation(output, summary, records)
    if cfg.trajectories:
        plot_trajectories(records, output / "trajectories.png", env.params.simulation.airspace, cfg.trajectories,
                          title=f"{task_label(task)}, agent from {path.name}")
    return summary


@hydra.main(version_base="1.3", config_path="pkg://agrl.conf", config_name="evaluate")
def main(cfg: DictConfig) -> None:
    try:
        config = load_config(cfg)
        summary = evaluate(config)
    except (ConfigError, CheckpointError) as error:
        print(f"agrl.evaluate: error: {error}", file=sys.stderr)
        sys.exit(2)
    print(json.dumps(summary))


if __name__ == "__main__":
    run_checked(main, "agrl.evaluate", "evaluate", check_inputs)
