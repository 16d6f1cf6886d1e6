"""``python -m agrl.report``: :func:`agrl.report.cli.main`."""

from agrl.cli import run_command
from agrl.report.cli import main

if __name__ == "__main__":
    run_command(main)
