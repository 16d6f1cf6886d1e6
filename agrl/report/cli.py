"""The command line, ``python -m agrl.report``: ``pages`` here, every other command in :mod:`agrl.report.commands`."""

from __future__ import annotations

import sys

from agrl.config import ConfigError
from agrl.report.columns import ReportError
from agrl.report.commands import _parser, run_command
from agrl.report.pages import page_files, update_pages


def main(argv: list[str] | None = None, draw: bool = True) -> int:
    """The command line; ``draw=False`` links figures without drawing them (``pages --check``)."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.kind != "pages":
        return run_command(args, parser, draw)
    try:
        stale, failed = update_pages(page_files(args.targets), args.check)
        for line in failed:
            print(f"agrl.report: error: {line}", file=sys.stderr)
        if args.check:
            for line in stale:
                print(line, file=sys.stderr)
        return 2 if failed else (1 if args.check and stale else 0)
    except (ConfigError, ReportError) as error:
        print(f"agrl.report: error: {error}", file=sys.stderr)
        return 2
