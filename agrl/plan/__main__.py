"""``python -m agrl.plan``: the instructions a trained agent gives an aircraft from a start (see :mod:`agrl.plan`)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from agrl.cli import run_command
from agrl.config import ConfigError
from agrl.plan import (
    AIRCRAFT_FIELDS,
    DESTINATION_FIELDS,
    PlanError,
    checked_states,
    plan,
    state_numbers,
    task_parameters,
)
from agrl.plan.figure import draw_plan


class _OneLineParser(argparse.ArgumentParser):
    def error(self, message: str):
        raise PlanError(message)


def _parser() -> argparse.ArgumentParser:
    parser = _OneLineParser(prog="python -m agrl.plan", description="The instructions a trained agent gives an "
                            "aircraft from a start, in order with their times. Arguments with '=' are task "
                            "overrides, as python -m agrl.evaluate takes them: task=uniform speed=50.")
    parser.add_argument("--aircraft", nargs="+", required=True, metavar="N",
                        help="the start: X Y Z (m) V (m/s) THETA PSI PHI (rad)")
    parser.add_argument("--destination", nargs="+", metavar="N",
                        help="X Y Z (m) PSI (rad) (default: the task's destination start)")
    parser.add_argument("--checkpoint", default="baseline",
                        help="a shipped agent's name, a checkpoint, a run directory, a .onnx or .pt2 export "
                        "(default: baseline)")
    parser.add_argument("--figure", metavar="F", help="write the plan's figure to this PNG file")
    parser.add_argument("--json", action="store_true", help="print the plan as one JSON object")
    return parser


def split_arguments(argv: Sequence[str]) -> tuple[list[str], list[str]]:
    """(options for argparse, task overrides): a ``key=value`` argument that is no option's value is an override,
    and a negative number after ``--aircraft``/``--destination`` is a number, not an option."""
    options, overrides, expects = [], [], None
    for argument in argv:
        if expects == "value":
            options.append(argument)
            expects = None
        elif argument.startswith("--"):
            options.append(argument)
            name = argument.split("=", 1)[0]
            expects = ("value" if name in ("--checkpoint", "--figure") and "=" not in argument
                       else "numbers" if name in ("--aircraft", "--destination") else None)
        elif "=" in argument:
            overrides.append(argument)
            expects = None
        else:  # argparse takes an argument with a leading space as a value, never as an option
            options.append(f" {argument}" if expects == "numbers" and argument.startswith("-") else argument)
    return options, overrides


def _checked_figure(figure: str | None) -> Path | None:
    if figure is not None and Path(figure).suffix.lower() != ".png":
        raise PlanError(f"--figure={figure} is not allowed: a .png file")
    return None if figure is None else Path(figure)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m agrl.plan``; returns the exit status (2 and one line on stderr for bad input, nothing written)."""
    from agrl.cli import writable_folder
    from agrl.guide import Guide, GuideError
    from agrl.rl.checkpoint import CheckpointError

    try:
        options, overrides = split_arguments(sys.argv[1:] if argv is None else argv)
        arguments = _parser().parse_args(options)
        figure = _checked_figure(arguments.figure)
        aircraft = state_numbers(arguments.aircraft, AIRCRAFT_FIELDS, "--aircraft")
        destination = arguments.destination and state_numbers(arguments.destination, DESTINATION_FIELDS,
                                                              "--destination")
        guide = Guide.load(arguments.checkpoint)
        params = task_parameters(guide, overrides)
        destination = destination or params.destination.start
        checked_states(params, aircraft, destination, ("--aircraft", "--destination"))
        if figure is not None:
            writable_folder(figure)
    except (PlanError, ConfigError, GuideError, CheckpointError) as error:  # one line each
        print(f"agrl.plan: error: {' '.join(str(error).split())}", file=sys.stderr)
        return 2
    result = plan(guide, params, aircraft, destination)
    print(result.to_json() if arguments.json else "\n".join(result.lines()))
    if figure is not None:
        draw_plan(result, params, figure, f"{Path(guide.source).name}, task={params.destination.name.value}")
    return 0


if __name__ == "__main__":
    run_command(main)
