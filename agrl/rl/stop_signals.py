"""Pre-emption: a scheduler's stop signal ends training at the next safe point, with a checkpoint.

Slurm sends SIGTERM before it pre-empts or times out a job (``--signal`` can ask for SIGUSR1 earlier); submitit
sends its jobs SIGUSR2 (or ``$SUBMITIT_PREEMPT_SIGNAL``) and requeues them from its handler. Python's default for
each is to die at once, and submitit's handler requeues at once, losing every iteration since the last periodic
checkpoint. :class:`StopSignals` turns them into a flag that the training loop reads after each completed iteration
(its safe point: the state is whole there), where the trainer saves ``latest``, marks the run as pre-empted
(:data:`PREEMPTED_MARKER`, so that the same command, run again, resumes it), hands the signal on to the handler it
replaced (submitit's: the requeue) and raises :class:`Preempted`.
"""

from __future__ import annotations

import os
import signal
import threading
from types import FrameType

#: The signals that mean "stop soon, save first": Slurm's and submitit's.
STOP_SIGNALS = tuple(dict.fromkeys((
    signal.SIGTERM, signal.SIGUSR1, signal.SIGUSR2,
    getattr(signal, f"SIG{os.environ.get('SUBMITIT_PREEMPT_SIGNAL', 'USR2')}", signal.SIGUSR2),
)))

#: In a run's ``checkpoints/``: the run stopped on a stop signal after saving ``latest.pt``; the same command run
#: again in the same run directory (a requeued job) resumes it.
PREEMPTED_MARKER = "preempted.json"

#: ``python -m agrl.train``'s exit code after a pre-emption: EX_TEMPFAIL, "try again later" (sysexits.h).
PREEMPTED_EXIT_CODE = 75


class Preempted(Exception):
    """Training stopped on a stop signal after saving its last completed iteration."""

    def __init__(self, signal_name: str, checkpoint: str, run_dir: str):
        self.signal_name, self.checkpoint, self.run_dir = signal_name, checkpoint, run_dir
        super().__init__(f"stopped by {signal_name}: saved the last completed iteration to {checkpoint}; "
                         f"resume with: python -m agrl.train resume={run_dir}")


class StopSignals:
    """While active (``with StopSignals() as stop:``), SIGTERM and SIGUSR1 set ``stop.received`` (the signal's
    name) instead of killing the process; the previous handlers are restored on exit.

    Signal handlers can only be installed from the main thread: elsewhere (a training started from a worker
    thread) this does nothing and the signals keep their previous meaning.
    """

    def __init__(self, signals: tuple[signal.Signals, ...] = STOP_SIGNALS):
        self.signals = signals
        self.received: str | None = None
        self._previous: dict[signal.Signals, object] = {}

    def _handle(self, number: int, frame: FrameType | None) -> None:
        self.received = self.received or signal.Signals(number).name

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is threading.main_thread():
            for number in self.signals:
                self._previous[number] = signal.signal(number, self._handle)
        return self

    def forward(self) -> None:
        """Hand the received signal on to the handler it replaced, if that was a Python function (submitit's,
        which requeues the job and exits; a default or ignored signal is left as handled here)."""
        if self.received is None:
            return
        number = signal.Signals[self.received]
        previous = self._previous.get(number)
        if callable(previous):
            previous(number, None)

    def __exit__(self, *exc_info) -> None:
        for number, handler in self._previous.items():
            signal.signal(number, handler)
        self._previous.clear()
