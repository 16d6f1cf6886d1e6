"""The fixed-destination baseline agent shipped with agrl (``checkpoint=baseline``).

Only the file's location lives here; :func:`agrl.rl.checkpoint.resolve_checkpoint_path`
turns ``baseline`` into this path and says what to do if the file is missing.
"""

from __future__ import annotations

from pathlib import Path

#: See ``docs/results/baseline.md`` for how it was made and how well it flies.
BASELINE_FILE = Path(__file__).with_name("fixed_baseline.pt")
