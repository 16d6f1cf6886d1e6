"""The fixed-destination baseline agent shipped with agrl (``checkpoint=baseline``)."""

from __future__ import annotations

from pathlib import Path

BASELINE_FILE = Path(__file__).with_name("fixed_baseline.pt")


def baseline_checkpoint_path() -> Path:
    """Path of the shipped baseline checkpoint (see ``docs/results/baseline.md`` for how it was made)."""
    if not BASELINE_FILE.is_file():
        from agrl.rl.checkpoint import CheckpointError

        raise CheckpointError(
            f"{BASELINE_FILE}: the shipped baseline is missing; train one with `python -m agrl.train` "
            "and pass its checkpoint path instead of 'baseline'"
        )
    return BASELINE_FILE
