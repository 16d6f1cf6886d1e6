"""Fixtures of the policy-reuse tests: collector batches of the hand-built scenarios (``reuse_scenarios``)."""

from __future__ import annotations

import functools

import pytest
from reuse_scenarios import Collected, Relabelled, Spanning, guidance_task

from agrl.envs import MotionKind


@pytest.fixture(scope="module")
def task_params(compose_parameters):
    """``task_params(kind, start, destination_start)``: :func:`reuse_scenarios.guidance_task` on conf's tasks."""
    return functools.partial(guidance_task, compose_parameters)


@pytest.fixture(scope="module")
def uniform(torch_one_thread, task_params) -> Collected:
    return Collected(task_params(MotionKind.UNIFORM))


@pytest.fixture(scope="module")
def relabelled(uniform) -> Relabelled:
    return Relabelled(uniform)


@pytest.fixture(scope="module")
def fixed(torch_one_thread, task_params) -> Collected:
    # 3 km from a fixed destination: flying straight, the baseline arrives at the fourth decision.
    return Collected(task_params(MotionKind.FIXED, start=((-3_000.0, -3_000.0), 0.0, 100.0)))


@pytest.fixture(scope="module")
def spanning(torch_one_thread, task_params) -> Spanning:
    return Spanning(task_params(MotionKind.UNIFORM))
