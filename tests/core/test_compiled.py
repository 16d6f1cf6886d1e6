"""Compiled functions (agrl.core.compiled): the eager fallback and the compilation kept on disk. The simulator's
and the loss's use of them are tested in tests/core/test_simulation.py and tests/rl/test_ppo.py."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import torch

from agrl.core.compiled import (
    CACHE_VARIABLE,
    INDUCTOR_CACHE_VARIABLE,
    KEPT_COMPILATIONS,
    VECTOR_PROBE_RECORD,
    WHOLE_VECTOR_ROWS,
    CachedRowwiseCompile,
    EagerFallback,
    compile_cache_dir,
    keep_kernels_per_instruction_set,
    padded_rows,
    repeat,
)


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


# ---------------------------------------------------------------- a compilation kept on disk
def _rowwise(position, speed, step):
    """A small row-wise function of the simulator's kind (tensors with rows first, a Python constant)."""
    moved = position + speed * step
    return moved, torch.sin(moved) * speed


def _rows(count: int, seed: int = 0):
    generator = torch.Generator().manual_seed(seed)
    return torch.randn(count, generator=generator), torch.rand(count, generator=generator)


def _assert_matches_eager(function, count):
    position, speed = _rows(count, seed=count)
    for result, expected in zip(function(position, speed, 0.5), _rowwise(position, speed, 0.5), strict=True):
        assert result.shape == (count,)
        torch.testing.assert_close(result, expected)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_VARIABLE, str(tmp_path / "compiled"))
    return tmp_path / "compiled"


def test_a_compilation_is_kept_on_disk_and_loaded_by_the_next_one(cache):
    first = CachedRowwiseCompile(_rowwise, "the test function", key="step 0.5")
    for count in (64, 37, 1, 0):  # one compilation for every size; one row padded, none run eagerly
        _assert_matches_eager(first, count)
    assert first.loaded_from is None
    (kept,) = cache.glob("*.bin")
    assert oct(cache.stat().st_mode & 0o777) == oct(0o700)  # the files hold code: private to the user

    again = CachedRowwiseCompile(_rowwise, "the test function", key="step 0.5")
    _assert_matches_eager(again, 5)
    assert again.loaded_from == kept
    other = CachedRowwiseCompile(_rowwise, "the test function", key="step 0.25")  # other constants: another file
    _assert_matches_eager(other, 5)
    assert other.loaded_from is None and len(list(cache.glob("*.bin"))) == 2


def test_a_damaged_compilation_is_compiled_again_with_one_line(cache):
    CachedRowwiseCompile(_rowwise, "the test function", key="damaged")(*_rows(8), 0.5)
    (kept,) = cache.glob("*.bin")
    kept.write_bytes(kept.read_bytes()[:1000])  # truncated, as by a full disk or a killed writer
    damaged = CachedRowwiseCompile(_rowwise, "the test function", key="damaged")
    with pytest.warns(RuntimeWarning, match=f"the compiled the test function in {kept} could not be used") as caught:
        _assert_matches_eager(damaged, 8)
    assert len(caught) == 1 and "\n" not in str(caught[0].message)
    assert damaged.loaded_from is None
    repaired = CachedRowwiseCompile(_rowwise, "the test function", key="damaged")
    _assert_matches_eager(repaired, 8)
    assert repaired.loaded_from == kept


def test_a_cache_that_cannot_be_written_compiles_in_memory(tmp_path, monkeypatch):
    blocked = tmp_path / "a file"
    blocked.write_text("not a folder")
    monkeypatch.setenv(CACHE_VARIABLE, str(blocked / "compiled"))
    with pytest.warns(RuntimeWarning, match="cannot keep the compiled the test function in .*a file"):
        _assert_matches_eager(CachedRowwiseCompile(_rowwise, "the test function", key="blocked"), 8)


def test_off_keeps_nothing(monkeypatch, tmp_path):
    monkeypatch.setenv(CACHE_VARIABLE, "off")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))  # where the default folder would be
    assert compile_cache_dir() is None
    function = CachedRowwiseCompile(_rowwise, "the test function", key="off")
    _assert_matches_eager(function, 8)
    assert function.loaded_from is None and not any(tmp_path.iterdir())


def test_the_default_folder_is_the_users_cache(monkeypatch, tmp_path):
    monkeypatch.delenv(CACHE_VARIABLE, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert compile_cache_dir() == tmp_path / "agrl" / "compiled"


def test_the_least_recently_used_compilations_beyond_the_limit_are_removed(cache):
    cache.mkdir(mode=0o700)
    old = [cache / f"old-{index:02d}.bin" for index in range(KEPT_COMPILATIONS)]
    for age, file in enumerate(old):
        file.write_bytes(b"")
        os.utime(file, (1_000_000 + age, 1_000_000 + age))  # old[0] is the least recently used
    CachedRowwiseCompile(_rowwise, "the test function", key="new")(*_rows(8), 0.5)
    kept = set(cache.glob("*.bin"))
    assert len(kept) == KEPT_COMPILATIONS and old[0] not in kept and old[1] in kept


def test_each_thread_count_has_its_own_compilation(cache):
    """torch's compilation guards the thread count its kernels were built for: make train-two-stage's stages run on two
    and one threads, and neither may replace the other's file."""
    threads = torch.get_num_threads()
    try:
        for count in (1, 2, 1):
            torch.set_num_threads(count)
            function = CachedRowwiseCompile(_rowwise, "the test function", key="threads")
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # no "could not be used"
                _assert_matches_eager(function, 8)
        assert function.loaded_from is not None  # the third: the first's file, loaded
        assert len(list(cache.glob("*.bin"))) == 2
    finally:
        torch.set_num_threads(threads)


def test_each_grad_mode_has_its_own_compilation(cache):
    """torch's compilation guards the grad mode it was made in: training or an evaluation (no grad) and an env
    stepped in a user's own code (grad on), in one process or one after the other, must neither fall back to eager
    nor replace each other's file."""
    function = CachedRowwiseCompile(_rowwise, "the test function", key="grad")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "could not be used", no "failed ... running eagerly"
        for grad in (False, True, False):
            with torch.set_grad_enabled(grad):
                _assert_matches_eager(function, 8)
        again = CachedRowwiseCompile(_rowwise, "the test function", key="grad")
        with torch.no_grad():
            _assert_matches_eager(again, 8)
    assert again.loaded_from is not None
    assert len(list(cache.glob("*.bin"))) == 2


def test_a_compilation_that_cannot_be_saved_is_still_used(cache, monkeypatch):
    """A full disk (or anything else that stops the file) costs the next process a compilation, not this one."""
    def no_space(self, *args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", lambda *args: no_space(None))
    function = CachedRowwiseCompile(_rowwise, "the test function", key="full disk")
    with pytest.warns(RuntimeWarning, match="cannot keep the compiled the test function in .*No space left"):
        _assert_matches_eager(function, 8)
    assert not list(cache.glob("*.bin")) and not list(cache.glob("*.partial"))  # no half-written file left
    _assert_matches_eager(function, 16)  # compiled, in memory


def test_inference_mode_uses_the_no_grad_compilation(cache):
    """A user's evaluation under torch.inference_mode makes inference tensors, whose dispatch keys a compilation's
    guards check: calls in that mode, or on its tensors afterwards, must neither fall back to eager nor compile
    again, and give the no-grad compilation's results."""
    function = CachedRowwiseCompile(_rowwise, "the test function", key="inference")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "could not be used", no "failed ... running eagerly"
        with torch.inference_mode():
            _assert_matches_eager(function, 8)  # its arguments are made in inference mode
            made_there = _rows(8, seed=3)
        with torch.no_grad():
            _assert_matches_eager(function, 8)
            results = function(*made_there, 0.5)
        assert not any(result.is_inference() for result in results)
        for result, expected in zip(results, _rowwise(*made_there, 0.5), strict=True):
            torch.testing.assert_close(result, expected)
        again = CachedRowwiseCompile(_rowwise, "the test function", key="inference")
        with torch.inference_mode():
            _assert_matches_eager(again, 8)
    assert again.loaded_from is not None
    assert len(list(cache.glob("*.bin"))) == 1


# ---------------------------------------------------------------- a call repeated on its own results
def _moved(position, speed, step):
    """A row-wise step whose results replace its leading argument (the simulator's kind)."""
    return (position + torch.sin(position) * speed * step,)


def _widened(position, speed, step):
    """A row-wise step whose second result is not of the dtype of the argument it replaces: it breaks the guards."""
    return position + speed * step, speed.double()


def test_repeat_feeds_each_calls_results_back_as_its_leading_arguments():
    (position,) = repeat(lambda position, step: (position + step,), 3, torch.zeros(2), 0.5)
    assert position.tolist() == [1.5, 1.5]
    with pytest.raises(ValueError, match="^times=0 is not allowed: an integer >= 1$"):
        repeat(_moved, 0, *_rows(4), 0.5)


def test_a_compiled_repeat_checks_the_guards_on_its_first_call_once_its_results_met_them(cache, monkeypatch):
    """The first repeat of a compilation checks every call; later ones the first call only, with the same results
    as calls checked one by one."""
    from torch._dynamo.aot_compile import AOTCompiledFunction

    checks = []
    check = AOTCompiledFunction.guard_check

    def counted(self, *args, **kwargs):
        checks.append(1)
        return check(self, *args, **kwargs)

    monkeypatch.setattr(AOTCompiledFunction, "guard_check", counted)  # torch's check, counted
    function = CachedRowwiseCompile(_moved, "the test function", key="repeat")
    position, speed = _rows(64)
    (first,) = function.repeat(5, position, speed, 0.5)
    assert len(checks) == 5
    (again,) = function.repeat(5, position, speed, 0.5)
    assert len(checks) == 6
    (one_by_one,) = repeat(function, 5, position, speed, 0.5)
    assert torch.equal(first, one_by_one) and torch.equal(again, one_by_one)
    torch.testing.assert_close(first, repeat(_moved, 5, position, speed, 0.5)[0])


def test_a_repeat_whose_results_break_the_guards_falls_back_to_eager(cache):
    function = EagerFallback(CachedRowwiseCompile(_widened, "the widening", key="widened"), _widened, "the widening")
    position, speed = _rows(64)
    with pytest.warns(RuntimeWarning, match="torch.compile of the widening failed.*GuardManager check failed"):
        result = function.repeat(3, position, speed, 0.5)
    assert not function.compiled
    for tensor, expected in zip(result, repeat(_widened, 3, position, speed, 0.5), strict=True):
        assert torch.equal(tensor, expected)


def test_a_repeat_whose_compiler_fails_warns_once_and_repeats_eagerly():
    def compiled(*args):
        raise RuntimeError("no C++ compiler")

    function = EagerFallback(compiled, _moved, "the step")
    position, speed = _rows(8)
    with pytest.warns(RuntimeWarning, match="torch.compile of the step failed.*no C\\+\\+ compiler") as caught:
        (result,) = function.repeat(3, position, speed, 0.5)
    assert len(caught) == 1 and not function.compiled
    assert torch.equal(result, repeat(_moved, 3, position, speed, 0.5)[0])


# ---------------------------------------------------------------- torch's own cache, one folder per instruction set
def _capability() -> str:
    return torch.backends.cpu.get_cpu_capability().lower()


@pytest.fixture
def torch_default(monkeypatch, tmp_path):
    """torch's default folder (under ``$TMPDIR``) in a temporary folder, ``$TORCHINDUCTOR_CACHE_DIR`` unset (an empty
    value counts as unset); both restored after the test."""
    import tempfile

    from torch._inductor import config as inductor_config
    from torch._inductor.runtime.cache_dir_utils import default_cache_dir

    monkeypatch.setenv(INDUCTOR_CACHE_VARIABLE, "")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    # A second call may find the first one's vector probe record and tell torch so: restored after the test too
    # (by assignment: torch's config module has no attribute for monkeypatch to delete and set back).
    saved = inductor_config.cpp.vec_isa_ok
    yield Path(default_cache_dir())
    inductor_config.cpp.vec_isa_ok = saved


def test_torchs_cache_goes_to_a_folder_of_this_instruction_set(torch_default, tmp_path):
    folder = keep_kernels_per_instruction_set()
    assert folder == torch_default / f"agrl-{_capability()}" and folder.is_relative_to(tmp_path)
    assert os.environ[INDUCTOR_CACHE_VARIABLE] == str(folder)
    assert keep_kernels_per_instruction_set() == folder  # chosen once: a second call keeps it


def test_torchs_default_folder_counts_as_unchosen(torch_default, monkeypatch):
    """Importing torch._dynamo (tensordict does) sets the variable to torch's default before agrl compiles."""
    monkeypatch.setenv(INDUCTOR_CACHE_VARIABLE, str(torch_default))
    assert keep_kernels_per_instruction_set() == torch_default / f"agrl-{_capability()}"


def test_a_folder_the_user_chose_for_torchs_cache_is_kept(torch_default, monkeypatch, tmp_path):
    monkeypatch.setenv(INDUCTOR_CACHE_VARIABLE, str(tmp_path / "mine"))
    assert keep_kernels_per_instruction_set() == tmp_path / "mine"
    assert os.environ[INDUCTOR_CACHE_VARIABLE] == str(tmp_path / "mine")


def _run_python(code: str, **environment: str) -> str:
    """``code`` in a new interpreter as a user's run starts one (torch's cache variable and path unset, so its kernels
    are the user's), with ``environment`` added; its stdout."""
    env = {key: value for key, value in os.environ.items()
           if key not in (INDUCTOR_CACHE_VARIABLE, "ATEN_CPU_CAPABILITY")}
    env.update(environment)
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.strip()


def test_each_instruction_set_torch_runs_on_has_its_own_folder():
    if _capability() == "default":
        pytest.skip("torch's kernels use no vector instructions here: no second path to choose")
    code = "from agrl.core.compiled import keep_kernels_per_instruction_set as keep; print(keep().name)"
    assert _run_python(code) == f"agrl-{_capability()}"
    assert _run_python(code, ATEN_CPU_CAPABILITY="default") == "agrl-default"


#: A compiled function whose C++ torch vectorises: it prints its largest difference from the eager result. Importing
#: torch._dynamo first sets torch's cache variable, as in a run (tensordict imports it).
_VECTORISED = """
import torch, torch._dynamo
from agrl.core.compiled import keep_kernels_per_instruction_set
keep_kernels_per_instruction_set()
rows = torch.randn(1000, 37, generator=torch.Generator().manual_seed(0))
function = lambda rows: torch.log_softmax(2 * rows, -1).sum(-1)
print(float((torch.compile(function)(rows) - function(rows)).abs().max()))
"""


@pytest.mark.skipif(torch.backends.cpu.get_cpu_capability() != "AVX512",
                    reason="needs a processor with AVX-512, whose AVX2 path torch's cache would confuse with it")
def test_a_compilation_on_the_avx2_path_is_not_mixed_up_with_one_on_avx512():
    """torch 2.13's cache found a graph generated for AVX-512 again on the AVX2 path (make train's), built it with
    AVX2's flags, and this function came out a third short; so did a PPO loss's gradients, as NaN. The first
    process leaves the AVX-512 graph in the user's cache (compiled, or found there), which the second would find."""
    assert float(_run_python(_VECTORISED)) < 1e-3
    assert float(_run_python(_VECTORISED, ATEN_CPU_CAPABILITY="avx2")) < 1e-3


# ---------------------------------------------------------------- torch's probe of the vector instruction sets
#: In a new process: agrl's reuse of the probe for the folder in argv[1]; with argv[2] == "unprobed", torch's probe
#: of a whole set (its test library, not the further checks of some sets' extensions) fails the test if it runs.
#: Prints whether the probe was spared, the sets torch lists and its setting.
_PROBE = """
import json, sys
from pathlib import Path
from torch._inductor import config, cpu_vec_isa
from agrl.core.compiled import reuse_vector_probe

check_build = cpu_vec_isa.VecISA.check_build

def probed(self, code):
    if code == cpu_vec_isa.VecISA._avx_code:
        raise AssertionError(f"torch probed {self}")
    return check_build(self, code)

if sys.argv[2] == "unprobed":
    cpu_vec_isa.VecISA.check_build = probed
spared = reuse_vector_probe(Path(sys.argv[1]))
listed = [str(isa) for isa in cpu_vec_isa.valid_vec_isa_list()]
print(json.dumps({"spared": spared, "usable": listed, "setting": config.cpp.vec_isa_ok}))
"""

linux_x86 = pytest.mark.skipif(
    not (sys.platform == "linux" and os.uname().machine == "x86_64"),
    reason="torch probes the vector instruction sets this way on Linux on x86-64 only")


def _probe(folder: Path, mode: str = "probed", **environment: str) -> dict:
    import json

    env = {key: value for key, value in os.environ.items() if key != "TORCHINDUCTOR_VEC_ISA_OK"}
    env.update(environment)
    done = subprocess.run([sys.executable, "-c", _PROBE, str(folder), mode], env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@linux_x86
def test_a_later_process_is_spared_torchs_probe_and_lists_the_same_sets(tmp_path):
    """torch builds and loads a test library per vector instruction set in every process that compiles or loads a
    kernel (about a second); a process after the first finds the first one's record and skips that."""
    first = _probe(tmp_path)
    assert not first["spared"] and first["setting"] is None
    assert (tmp_path / VECTOR_PROBE_RECORD).is_file()
    later = _probe(tmp_path, "unprobed")
    assert later == {"spared": True, "usable": first["usable"], "setting": True}


@linux_x86
def test_a_record_of_other_sets_or_another_setting_is_probed_again(tmp_path):
    import json

    first = _probe(tmp_path)
    record_file = tmp_path / VECTOR_PROBE_RECORD
    record = json.loads(record_file.read_text())
    # A set the processor lists that the probe turned down: probe again, as torch would.
    record_file.write_text(json.dumps({**record, "usable": record["usable"][1:]}))
    again = _probe(tmp_path)
    assert again == {"spared": False, "usable": first["usable"], "setting": None}
    assert json.loads(record_file.read_text()) == record  # the probe's own result, recorded anew
    record_file.write_text(json.dumps({**record, "setting": {**record["setting"], "torch": "another version"}}))
    assert _probe(tmp_path) == again
    assert json.loads(record_file.read_text()) == record


@linux_x86
def test_a_users_own_vector_setting_is_left_alone(tmp_path):
    assert _probe(tmp_path, TORCHINDUCTOR_VEC_ISA_OK="0") == {"spared": False, "usable": [], "setting": False}
    assert not (tmp_path / VECTOR_PROBE_RECORD).exists()


def test_a_probe_that_fails_is_left_to_torch(tmp_path, monkeypatch):
    """Whatever torch's probe raises reaches its own compilation, where the simulator falls back to eager; agrl's
    reuse of it, called before, records nothing and raises nothing."""
    from torch._inductor import config as inductor_config
    from torch._inductor import cpu_vec_isa

    from agrl.core.compiled import reuse_vector_probe

    def broken():
        raise RuntimeError("no compiler")

    saved, inductor_config.cpp.vec_isa_ok = inductor_config.cpp.vec_isa_ok, None
    monkeypatch.setattr(cpu_vec_isa, "valid_vec_isa_list", broken)
    try:
        assert reuse_vector_probe(tmp_path) is False
        assert inductor_config.cpp.vec_isa_ok is None and not (tmp_path / VECTOR_PROBE_RECORD).exists()
    finally:
        inductor_config.cpp.vec_isa_ok = saved


@pytest.mark.parametrize("count", [0, 1, 5, 63, 64, 65, 1000])
def test_padded_rows_fills_whole_vectors_with_the_first_row(count):
    index = torch.arange(count) * 3 + 2  # any rows of a batch, not starting at 0
    padded = padded_rows(index)
    assert padded.numel() % WHOLE_VECTOR_ROWS == 0 and padded.numel() - count < WHOLE_VECTOR_ROWS
    assert torch.equal(padded[:count], index)
    assert bool((padded[count:] == 2).all())  # copies of the first row
