"""``python -m agrl.train``: train a guidance agent (Hydra entry point).

Examples::

    python -m agrl.train                                   # fixed destination, position shaping + switch cost
    python -m agrl.train task=uniform speed=50 method=reuse
    python -m agrl.train reward=none seed=2 ppo.max_minutes=10
    python -m agrl.train resume=runs/fixed/scratch/<date>_seed0 ppo.total_frames=20000000
"""

from __future__ import annotations

import json
import logging
import signal
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf, open_dict

from agrl.cli import RESUMABLE_OVERRIDES, refuse_unresumable, run_checked
from agrl.config import ConfigError, load_config, override_key
from agrl.machine import other_path
from agrl.rl.checkpoint import (
    CheckpointError,
    checkpoint_run_directory,
    load_latest_checkpoint,
    resolve_checkpoint_path,
    set_aside_damaged,
)
from agrl.rl.stop_signals import PREEMPTED_EXIT_CODE, PREEMPTED_MARKER, Preempted

log = logging.getLogger("agrl.train")


def _resume_config(cfg: DictConfig, reference: str, requeued: bool = False) -> tuple[DictConfig, dict, Path]:
    """The saved config of the checkpoint ``reference`` names, its payload and its run directory. The command
    line may change only :data:`RESUMABLE_OVERRIDES`; a ``requeued`` run (the pre-empted command run again) takes
    none of its overrides, which are the ones the checkpoint was made with."""
    latest = resolve_checkpoint_path(reference)
    path, payload, note = load_latest_checkpoint(
        latest, required=("actor", "critic", "optimizer", "counters", "carrier", "rng", "config"))
    if note:
        log.warning("%s (the damaged file is kept as %s)", note, set_aside_damaged(latest))
        path = latest
    payload["_path"] = str(path)
    if differing := other_path(payload.get("machine")):
        log.warning("resuming on another processor path than the checkpoint's (%s): the run goes on, but not bit for "
                    "bit as it would have (make train's path: README)", differing)
    # The composed config carries the typed group schemas; the run's saved values go on top. The method section
    # is the saved one whole (another method than the command line's default has other keys); checkpoints
    # written when all methods shared one schema hold None for the keys their method does not have.
    saved_values = dict(payload["config"])
    method = {key: value for key, value in saved_values.pop("method").items() if value is not None}
    saved = OmegaConf.merge(cfg, saved_values)
    with open_dict(saved):
        saved.method = method
    given = [] if requeued else list(HydraConfig.get().overrides.task)
    refuse_unresumable(given)  # checked before Hydra ran too (agrl.cli); here for callers of main() itself
    overrides = [override for override in given if override_key(override).startswith(RESUMABLE_OVERRIDES)]
    saved = OmegaConf.merge(saved, OmegaConf.from_dotlist(overrides))
    saved.resume = str(reference)
    return saved, payload, checkpoint_run_directory(path, payload)


def run(cfg: DictConfig) -> dict:
    """Train one run, or with ``search.seeds`` > 1 one run per seed; the summary the command prints and returns."""
    run_dir = Path(HydraConfig.get().runtime.output_dir)
    if cfg.search.seeds == 1:
        return _train(cfg, run_dir)
    load_config(cfg)  # its one-line errors before the first seed's run
    return _seeds_summary(cfg, run_dir)


def _seeds_summary(cfg: DictConfig, run_dir: Path) -> dict:
    """A trial of ``search.seeds`` runs, one after another, each in ``<run_dir>/seed_<n>``, summarised in
    ``<run_dir>/trial.json``: each run's summary and the worst run's cost as the trial's. A requeued trial keeps the
    runs that finished (their ``eval/eval.json``) and resumes the one it was pre-empted in."""
    runs = {}
    for seed in range(cfg.seed, cfg.seed + cfg.search.seeds):
        seed_dir = run_dir / f"seed_{seed}"
        finished = seed_dir / "eval" / "eval.json"
        if finished.is_file():
            log.info("%s finished before: its evaluation is kept", seed_dir)
            runs[seed] = json.loads(finished.read_text())
            continue
        runs[seed] = _train(OmegaConf.merge(cfg, {"seed": seed, "search": {"seeds": 1}}), seed_dir)
    worst = max(runs, key=lambda seed: runs[seed]["search_objective"])
    summary = {"seeds": list(runs), "worst_seed": worst, "search_objective": runs[worst]["search_objective"],
               "runs": {str(seed): runs[seed] for seed in runs}}
    (run_dir / "trial.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def _train(cfg: DictConfig, run_dir: Path) -> dict:
    from agrl.rl.trainer import Trainer  # heavy imports after argument checks

    payload = None
    if cfg.get("resume"):
        cfg, payload, run_dir = _resume_config(cfg, cfg.resume)
    elif (run_dir / "checkpoints" / PREEMPTED_MARKER).is_file():  # a requeued job, or the same command again
        log.warning("%s was pre-empted: resuming it from its last checkpoint", run_dir)
        cfg, payload, run_dir = _resume_config(cfg, str(run_dir), requeued=True)
    config = load_config(cfg)
    trainer = Trainer(config, run_dir, resume_payload=payload)
    (run_dir / "checkpoints" / PREEMPTED_MARKER).unlink(missing_ok=True)  # resumed: written again if stopped again
    log.info("run directory: %s (tensorboard --logdir %s)", run_dir, run_dir)
    if payload is not None:
        log.info("resumed from %s after iteration %d (%d decisions)", payload["_path"],
                 payload["counters"]["iteration"], payload["counters"]["frames"])
    return trainer.train()


@hydra.main(version_base="1.3", config_path="pkg://agrl.conf", config_name="config")
def main(cfg: DictConfig) -> float:
    """Train, print the final evaluation, and return the run's cost to a sweeper (``search``; lower is better)."""
    if hasattr(signal, "SIGXFSZ"):  # over a file-size limit (ulimit -f): a failed write (one line), not a kill
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    try:
        summary = run(cfg)
    except (ConfigError, CheckpointError, ValueError) as error:  # ConfigError is a ValueError too
        print(f"agrl.train: error: {error}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        sys.exit(130)
    except Preempted as stopped:  # SIGTERM / SIGUSR1: a scheduler's pre-emption or time limit
        print(f"agrl.train: {stopped}", file=sys.stderr)
        sys.exit(PREEMPTED_EXIT_CODE)
    except Exception as error:
        from agrl.rl.trainer import TrainingDiverged

        if isinstance(error, TrainingDiverged):
            print(f"agrl.train: error: {error}", file=sys.stderr)
            sys.exit(3)
        raise
    print(json.dumps(summary))
    return summary["search_objective"]


def check_inputs(config) -> None:
    """Read the files the run will read, as it will (agrl.cli.run_checked calls this before Hydra runs)."""
    from agrl.config import method_class

    method_class(config.method.name).check_inputs(config)


if __name__ == "__main__":
    run_checked(main, "agrl.train", "config", check_inputs)
