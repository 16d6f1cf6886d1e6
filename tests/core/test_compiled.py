"""The eager fallback of compiled functions (agrl.core.compiled); the simulator's and the loss's use of it are
tested in tests/core/test_simulation.py and tests/rl/test_ppo.py."""

from __future__ import annotations

import pytest

from agrl.core.compiled import EagerFallback


def test_an_error_of_the_eager_function_itself_is_raised():
    def eager(value):
        raise ValueError(f"bad value {value}")

    function = EagerFallback(eager, eager, "nothing compiled")
    assert not function.compiled
    with pytest.raises(ValueError, match="bad value 3"):
        function(3)


def test_a_failing_compiled_function_warns_once_then_runs_the_eager_one():
    calls = []

    def compiled(value):
        calls.append("compiled")
        raise RuntimeError("no C++ compiler")

    def eager(value):
        calls.append("eager")
        return 2 * value

    function = EagerFallback(compiled, eager, "the doubling")
    with pytest.warns(RuntimeWarning, match="torch.compile of the doubling failed.*no C\\+\\+ compiler"):
        assert function(3) == 6
    assert not function.compiled
    assert function(4) == 8  # no second warning, no second try
    assert calls == ["compiled", "eager", "eager"]
