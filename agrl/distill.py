"""``python -m agrl.distill TEACHER [TEACHER ...] DESTINATION [--observation absolute|relative]``: one network
from a teacher's policy, on another input or from an ensemble.

Writes a checkpoint whose actor and critic read observation ``--observation`` (``agent.observation``) and
reproduce TEACHER's (a checkpoint, run directory or shipped agent's name) on the teacher's own task: supervised
distillation with DAgger (:func:`agrl.rl.distill.distill`): each round flies the teacher's task with the
current student (the teacher in round 0, 10 % random decisions), the teacher labels every visited state with
its action probabilities and value, and the student's actor and critic are fitted to all rounds' labels.

Made for the paper's input interface (equation 4, ``--observation absolute``): PPO with it learns the fixed
destination far more slowly than with the relative observation (docs/policy_reuse.md, "The paper's
observation"), and both observations describe the same state when the destination is at the origin, so the
shipped baseline's policy can be re-expressed on equation 4's inputs (the shipped ``baseline-absolute`` was made
so). The student has only ever seen the fixed destination, as the paper's baseline: what policy reuse needs to be
tested as the paper ran it.

Several teachers make one ensemble teacher: the mean of their action probabilities (and of their values). With
``--observation relative`` this compresses agents fine-tuned from one start (``+experiment=switch_finetune``
seeds) into one network of the usual size, which ``method=pretrained`` and ``method=reuse`` can start from
(docs/results/switch_cost.md, "What did not get past 99.8 % at ≤ 7 instructions": such an ensemble flies as the
seeds' weight average does).
"""

from __future__ import annotations

import argparse
import sys

import torch

from agrl.cli import positive_int, run_command, writable_folder
from agrl.config import ConfigError
from agrl.rl.checkpoint import CheckpointError
from agrl.rl.distill import distill


def main(argv: list[str] | None = None) -> int:
    summary = " ".join(__doc__.split("\n\n")[0].split())  # the docstring's first paragraph
    parser = argparse.ArgumentParser(prog="python -m agrl.distill", description=summary,
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("teachers", nargs="+", metavar="TEACHER",
                        help="checkpoint, run directory or shipped agent (python -m agrl.baselines); several: "
                             "their ensemble is the teacher")
    parser.add_argument("destination", help="the student checkpoint to write")
    parser.add_argument("--observation", default="absolute", choices=("relative", "absolute"),
                        help="the student's input: equation 4's (absolute) or agrl's (relative)")
    parser.add_argument("--rounds", type=positive_int, default=4, help="DAgger rounds (round 0 flies the teacher)")
    parser.add_argument("--envs", type=positive_int, default=2048, help="episodes flown in parallel per round")
    parser.add_argument("--epochs", type=positive_int, default=8, help="passes over all rounds' states per round")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=positive_int, default=None,
                        help="torch's intra-op threads; None: torch's default, one per core")
    parser.add_argument("--init", metavar="CHECKPOINT",
                        help="start the student from this agent (same network and observation) instead of afresh")
    args = parser.parse_args(argv)
    if args.threads is not None:
        torch.set_num_threads(args.threads)
    try:
        writable_folder(args.destination)  # before the rounds, not after them
        summary = distill(args.teachers, args.destination, observation=args.observation, rounds=args.rounds,
                          envs=args.envs, epochs=args.epochs, seed=args.seed, init=args.init)
    except (ConfigError, CheckpointError) as error:
        print(f"agrl.distill: error: {error}", file=sys.stderr)
        return 2
    evaluation, teacher = summary["evaluation"], summary["teacher_evaluation"]
    print(f"wrote {args.destination}: agreement {summary['agreement']:.4f}; on the same {evaluation['episodes']} "
          f"episodes of the teacher's task, success {evaluation['success_rate']:.4f} at "
          f"{evaluation['instructions_per_episode']:.2f} instructions (the teacher: {teacher['success_rate']:.4f} at "
          f"{teacher['instructions_per_episode']:.2f})")
    return 0


if __name__ == "__main__":
    run_command(main)
