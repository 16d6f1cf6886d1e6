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

TorchRL writes its log lines to stdout (an INFO line when a trainer's replay buffer is allocated) unless
``TORCHRL_CONSOLE_STREAM`` names another stream when it is first imported; this package sets it to stderr (a value
the user set is kept) before any benchmark imports TorchRL, so that stdout holds the JSON lines alone and
``make bench > bench.jsonl`` is a file of records.
"""

import os

os.environ.setdefault("TORCHRL_CONSOLE_STREAM", "stderr")

