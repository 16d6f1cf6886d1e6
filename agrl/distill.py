"""``python -m agrl.distill TEACHER DESTINATION [--observation absolute]``: one agent's policy on another input.

Writes a checkpoint whose actor and critic read observation ``--observation`` (``agent.observation``) and
reproduce TEACHER's (a checkpoint, run directory or ``baseline``) on the teacher's own task: supervised
distillation with DAgger (:func:`agrl.rl.distill.distill`): each round flies the teacher's task with the
current student (the teacher in round 0, 10 % random decisions), the teacher labels every visited state with
its action probabilities and value, and the student's actor and critic are fitted to all rounds' labels.

Made for the paper's input interface (equation 4, ``--observation absolute``): PPO with it learns the fixed
destination far more slowly than with the relative observation (docs/policy_reuse.md, "The paper's
observation"), and both observations describe the same state when the destination is at the origin, so the
shipped baseline's policy can be re-expressed on equation 4's inputs. The student has only ever seen the
fixed destination, as the paper's baseline: what policy reuse needs to be tested as the paper ran it.
"""

from __future__ import annotations

import argparse
import sys

from agrl.config import ConfigError
from agrl.rl.checkpoint import CheckpointError
from agrl.rl.distill import distill


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m agrl.distill", description=__doc__.splitlines()[0])
    parser.add_argument("teacher", help="checkpoint, run directory or 'baseline'")
    parser.add_argument("destination", help="the student checkpoint to write")
    parser.add_argument("--observation", default="absolute", choices=("relative", "absolute"))
    parser.add_argument("--rounds", type=int, default=4, help="DAgger rounds (round 0 flies the teacher)")
    parser.add_argument("--envs", type=int, default=2048, help="episodes flown in parallel per round")
    parser.add_argument("--epochs", type=int, default=8, help="passes over all rounds' states per round")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    try:
        summary = distill(args.teacher, args.destination, observation=args.observation, rounds=args.rounds,
                          envs=args.envs, epochs=args.epochs, seed=args.seed)
    except (ConfigError, CheckpointError) as error:
        print(f"agrl.distill: error: {error}", file=sys.stderr)
        return 2
    evaluation = summary["evaluation"]
    print(f"wrote {args.destination}: agreement {summary['agreement']:.4f}, success {evaluation['success_rate']:.4f} "
          f"on {evaluation['episodes']} episodes of the teacher's task")
    return 0


if __name__ == "__main__":
    sys.exit(main())
