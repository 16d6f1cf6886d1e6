"""Fixtures of the policy-reuse tests: collector batches of the hand-built scenarios (``reuse_scenarios``).

The scenarios are built once per test process (session scope) and shared by the test files of this folder, as they
were by the tests of the one file these came from; each is built on one torch thread, as the tests run.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
import torch
from reuse_scenarios import Collected, Relabelled, Spanning, guidance_task

from agrl.envs import MotionKind


@contextmanager
def one_thread() -> Iterator[None]:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


@pytest.fixture(scope="module", autouse=True)
def reuse_tests_on_one_thread(torch_one_thread):
    """Every test here runs on one torch thread (the suite runs one worker per core)."""


@pytest.fixture(scope="session")
def task_params(compose_parameters):
    """``task_params(kind, start, destination_start)``: :func:`reuse_scenarios.guidance_task` on conf's tasks."""
    return functools.partial(guidance_task, compose_parameters)


@pytest.fixture(scope="session")
def uniform(task_params) -> Collected:
    with one_thread():
        return Collected(task_params(MotionKind.UNIFORM))


@pytest.fixture(scope="session")
def relabelled(uniform) -> Relabelled:
    with one_thread():
        return Relabelled(uniform)


@pytest.fixture(scope="session")
def fixed(task_params) -> Collected:
    # 3 km from a fixed destination: flying straight, the baseline arrives at the fourth decision.
    with one_thread():
        return Collected(task_params(MotionKind.FIXED, start=((-3_000.0, -3_000.0), 0.0, 100.0)))


@pytest.fixture(scope="session")
def spanning(task_params) -> Spanning:
    with one_thread():
        return Spanning(task_params(MotionKind.UNIFORM))
