"""Pre-emption: a scheduler's stop signal ends training at the next safe point, with a checkpoint.

Slurm sends SIGTERM before it pre-empts or times out a job (``--signal`` can ask for SIGUSR1 earlier), and
submitit relays it. Python's default for either is to die at once, losing every iteration since the last periodic
checkpoint. :class:`StopSignals` turns them into a flag that the training loop reads after each completed iteration
(its safe point: the state is whole there), where the trainer saves ``latest`` and raises :class:`Preempted`.
"""

from __future__ import annotations

import signal
import threading
from types import FrameType

#: The signals that mean "stop soon, save first".
STOP_SIGNALS = (signal.SIGTERM, signal.SIGUSR1)

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

    def __exit__(self, *exc_info) -> None:
        for number, handler in self._previous.items():
            signal.signal(number, handler)
        self._previous.clear()
