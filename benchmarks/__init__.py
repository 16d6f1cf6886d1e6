"""agrl's benchmarks: scripts beside the package, not part of it (the wheel ships ``agrl`` only).

Run each one from the repository root as a module, with agrl installed (``make bench`` runs the first three)::

    python -m benchmarks.bench          # simulator, envs and guide throughput
    python -m benchmarks.bench_reuse    # one policy-reuse relabelling
    python -m benchmarks.bench_peer     # one PPO iteration beside stable-baselines3 (the ``bench`` extra)
    python -m benchmarks.bench_race     # both trainers on the same task in the same wall time (the ``bench`` extra)
    python -m benchmarks.soak           # a long training run watched from outside

Each prints one JSON object per line (docs/benchmarks.md). This file makes ``benchmarks`` a regular package: torchrl
installs a namespace package of the same name into site-packages, and a regular package on ``sys.path`` (the
repository root, which ``python -m`` puts first) takes precedence over it.
"""

from __future__ import annotations


def torchrl_logs_to_stderr() -> None:
    """Send TorchRL's console log lines (an INFO line when a trainer's replay buffer is allocated) to stderr in this
    process: TorchRL writes them to stdout, where a benchmark writes its JSON lines, so that ``make bench >
    bench.jsonl`` is a file of records. Not through ``TORCHRL_CONSOLE_STREAM``, which would reach every process
    this one starts too."""
    import logging
    import sys

    import torchrl  # noqa: F401 - sets up its console handler

    for handler in logging.getLogger("torchrl").handlers:
        if isinstance(handler, logging.StreamHandler) and handler.stream is sys.stdout:
            handler.setStream(sys.stderr)
