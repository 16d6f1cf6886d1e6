"""agrl.rl.stop_signals: a stop signal becomes a flag while active, and the previous handlers come back."""

from __future__ import annotations

import os
import signal
import threading

import pytest

from agrl.rl.stop_signals import STOP_SIGNALS, Preempted, StopSignals


@pytest.mark.parametrize("stop_signal", STOP_SIGNALS, ids=lambda number: signal.Signals(number).name)
def test_a_stop_signal_is_recorded_not_fatal(stop_signal):
    with StopSignals() as stop:
        assert stop.received is None
        os.kill(os.getpid(), stop_signal)  # delivered before os.kill returns to Python code
        assert stop.received == signal.Signals(stop_signal).name


def test_the_first_signal_is_the_one_named():
    with StopSignals() as stop:
        os.kill(os.getpid(), signal.SIGUSR1)
        os.kill(os.getpid(), signal.SIGTERM)
    assert stop.received == "SIGUSR1"


def test_previous_handlers_are_restored():
    seen = []
    previous = signal.signal(signal.SIGUSR1, lambda number, frame: seen.append(number))
    try:
        with StopSignals():
            assert signal.getsignal(signal.SIGUSR1) is not previous
        os.kill(os.getpid(), signal.SIGUSR1)
        assert seen == [signal.SIGUSR1]
    finally:
        signal.signal(signal.SIGUSR1, previous)


def test_outside_the_main_thread_nothing_is_installed():
    before = {number: signal.getsignal(number) for number in STOP_SIGNALS}
    during = {}

    def enter():
        with StopSignals():
            during.update({number: signal.getsignal(number) for number in STOP_SIGNALS})

    thread = threading.Thread(target=enter)
    thread.start()
    thread.join()
    assert during == before


def test_preempted_names_the_signal_the_checkpoint_and_the_resume_command():
    message = str(Preempted("SIGTERM", "run/checkpoints/latest.pt", "run"))
    assert message == ("stopped by SIGTERM: saved the last completed iteration to run/checkpoints/latest.pt; "
                       "resume with: python -m agrl.train resume=run")


def test_forward_hands_the_signal_to_the_handler_it_replaced():
    seen = []
    previous = signal.signal(signal.SIGUSR2, lambda number, frame: seen.append(number))
    try:
        with StopSignals() as stop:
            os.kill(os.getpid(), signal.SIGUSR2)
            assert seen == []  # held while training goes on to its safe point
            stop.forward()
        assert seen == [signal.SIGUSR2]
    finally:
        signal.signal(signal.SIGUSR2, previous)


def test_forward_leaves_a_default_handler_alone():
    with StopSignals() as stop:
        os.kill(os.getpid(), signal.SIGTERM)
        stop.forward()  # SIG_DFL before: forwarding would kill the process
    assert stop.received == "SIGTERM"
