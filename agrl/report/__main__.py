"""``python -m agrl.report``: :func:`agrl.report.cli.main`."""

import sys

from agrl.report.cli import main

if __name__ == "__main__":
    sys.exit(main())
