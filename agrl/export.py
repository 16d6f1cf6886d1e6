"""``python -m agrl.export SOURCE DESTINATION [--evaluation eval.json]``: slim a checkpoint for sharing.

Keeps the actor, critic, resolved config and counters (no optimiser, RNG or
collector state), e.g. to ship a baseline usable as ``method.baseline=<file>``.
"""

from __future__ import annotations

import argparse
import json
import sys

from agrl.rl.checkpoint import CheckpointError, export_agent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m agrl.export", description=__doc__.splitlines()[0])
    parser.add_argument("source", help="a checkpoint file or a run directory")
    parser.add_argument("destination", help="where to write the slim checkpoint")
    parser.add_argument("--evaluation", help="an eval.json to embed (its summary travels with the agent)")
    args = parser.parse_args(argv)
    extra = {}
    if args.evaluation:
        with open(args.evaluation) as file:
            extra["evaluation"] = json.load(file)
    try:
        path = export_agent(args.source, args.destination, **extra)
    except (CheckpointError, OSError, json.JSONDecodeError) as error:
        print(f"agrl.export: error: {error}", file=sys.stderr)
        return 2
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
