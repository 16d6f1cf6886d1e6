"""Compiled functions: a fallback to the eager original if compilation fails, and a compilation kept on disk
so that later processes load it instead of compiling again."""

from __future__ import annotations

import copy
import hashlib
import json
import os
import platform
import re
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch
from torch.utils import _pytree as pytree

#: Environment variable naming the folder of kept compilations; ``off`` keeps none (each process compiles).
CACHE_VARIABLE = "AGRL_COMPILE_CACHE"


class EagerFallback:
    """Calls ``compiled``; if that raises (no C++ compiler, an unsupported platform), warns once, naming
    ``what``, and calls ``eager`` from then on. An error of the eager function itself is raised as it is."""

    def __init__(self, compiled: Callable, eager: Callable, what: str):
        self.eager = eager
        self.what = what
        self._call = compiled

    @property
    def compiled(self) -> bool:
        """False once compilation has failed (and always if ``compiled`` is ``eager``)."""
        return self._call is not self.eager

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        try:
            return self._call(*args, **kwargs)
        except Exception as error:  # noqa: BLE001 - any compiler failure falls back to eager
            self._fall_back(error)
            return self.eager(*args, **kwargs)

    def repeat(self, times: int, *args: Any) -> Any:
        """The function applied ``times`` times, each call's results (a tuple) replacing its leading arguments
        (:func:`repeat`); through ``compiled``'s own ``repeat`` where it has one (:meth:`CachedRowwiseCompile.repeat`).
        The function must not change its arguments: after a compiler failure the eager repeat starts again from
        ``args``."""
        if self._call is not self.eager and hasattr(self._call, "repeat"):
            try:
                return self._call.repeat(times, *args)
            except Exception as error:  # noqa: BLE001 - any compiler failure falls back to eager
                self._fall_back(error)
        return repeat(self, times, *args)

    def _fall_back(self, error: Exception) -> None:
        if self._call is self.eager:
            raise error
        warnings.warn(f"torch.compile of {self.what} failed ({type(error).__name__}: {error}); running eagerly",
                      RuntimeWarning, stacklevel=4)
        self._call = self.eager


def repeat(function: Callable, times: int, *args: Any) -> Any:
    """``function`` applied ``times`` (>= 1) times, each call's results (a tuple) replacing its leading arguments:
    ``args = (*results, *args[len(results):])``; the last call's results."""
    _check_times(times)
    for _ in range(times):
        results = function(*args)
        args = (*results, *args[len(results):])
    return results


def _check_times(times: int) -> None:
    if times < 1:
        raise ValueError(f"times={times} is not allowed: an integer >= 1")


def compile_cache_dir() -> Path | None:
    """The folder of kept compilations: ``$AGRL_COMPILE_CACHE`` (``off``: none), else ``$XDG_CACHE_HOME/agrl/
    compiled``, else ``~/.cache/agrl/compiled``. A user folder rather than ``/tmp``, so it outlives a reboot."""
    chosen = os.environ.get(CACHE_VARIABLE)
    if chosen is not None:
        return None if chosen.strip().lower() in ("off", "0", "none", "") else Path(chosen).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "agrl" / "compiled"


#: torch's variable naming the folder of its own compilations (TorchInductor's generated code and built kernels).
INDUCTOR_CACHE_VARIABLE = "TORCHINDUCTOR_CACHE_DIR"


def keep_kernels_per_instruction_set() -> Path:
    """Point torch's own compile cache (``$TORCHINDUCTOR_CACHE_DIR``) at ``agrl-<the instruction set torch's CPU
    kernels use>`` in torch's default folder (``/tmp/torchinductor_$USER/agrl-avx2``), unless the user chose another
    folder (torch's import sets the variable to its default, which counts as unchosen); return the folder in use.

    torch's cache of compiled graphs does not tell apart the vector instructions it generated their C++ for (torch
    2.13): a graph generated on the AVX-512 path and found again by a process on the AVX2 path
    (``ATEN_CPU_CAPABILITY=avx2``, which ``make train`` sets), or the other way round, is built with the other
    path's compiler flags and computes wrong numbers, silently (a PPO loss's gradients turned NaN; a sum came out a
    third short). One folder per instruction set keeps them apart. It stays on this machine, in torch's temporary
    folder, rather than in a home folder other machines may share: torch builds the kernels for this very processor
    (``-march=native``). Called before agrl compiles anything."""
    from torch._inductor.runtime.cache_dir_utils import default_cache_dir

    chosen = os.environ.get(INDUCTOR_CACHE_VARIABLE)
    if chosen and os.path.abspath(chosen) != os.path.abspath(default_cache_dir()):
        return Path(chosen)
    folder = Path(default_cache_dir()) / f"agrl-{torch.backends.cpu.get_cpu_capability().lower()}"
    os.environ[INDUCTOR_CACHE_VARIABLE] = str(folder)
    reuse_vector_probe(folder)
    return folder


#: The file, in agrl's folder of torch's compile cache, recording what torch's vector instruction probe found here.
VECTOR_PROBE_RECORD = "vector-probe.json"


def reuse_vector_probe(folder: Path) -> bool:
    """Spare this process most of torch's probe of the vector instruction sets where an earlier one on this machine
    found every set the processor lists usable; whether it was spared.

    Before the first kernel a process compiles or loads, torch (2.13) builds a test library for each vector
    instruction set the processor has and loads each in a child Python
    (``torch._inductor.cpu_vec_isa.valid_vec_isa_list``); with its further checks of some sets' extensions that is
    about 2.5 s of such a process's start on the 2-core VM, of which torch's ``cpp.vec_isa_ok`` setting skips about
    1 s (the extensions are still checked). The sets it finds usable are recorded in ``folder``
    (:func:`keep_kernels_per_instruction_set` passes agrl's own, machine-local one) with torch's version and the
    Python. A later process with the same, where the probe had found every set the processor lists usable, sets
    ``vec_isa_ok``: torch then lists the same sets and builds with the same flags without building and loading the
    test libraries again. Anything else (no or another record, a set the probe
    turned down, a user's own ``TORCHINDUCTOR_VEC_ISA_OK``, not Linux on x86-64) leaves torch to probe, and the
    record is written anew."""
    from torch._inductor import config as inductor_config
    from torch._inductor import cpu_vec_isa

    if inductor_config.cpp.vec_isa_ok is not None or sys.platform != "linux" or platform.machine() != "x86_64":
        return False
    try:  # the sets torch would probe: those the processor has, in torch's order of preference
        has = cpu_vec_isa.x86_isa_checker()
        listed = [str(isa) for isa in cpu_vec_isa.supported_vec_isa_list
                  if all(flag in has for flag in str(isa).split())]
    except AttributeError:  # another torch: leave it to probe
        return False
    setting = {"torch": str(torch.__version__), "python": sys.executable}
    path = folder / VECTOR_PROBE_RECORD
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        record = None
    if isinstance(record, dict) and record.get("setting") == setting and record.get("usable") == listed:
        inductor_config.cpp.vec_isa_ok = True  # every listed set passed this machine's probe
        return True
    try:
        usable = [str(isa) for isa in cpu_vec_isa.valid_vec_isa_list()]  # torch's probe, as its first kernel would
    except Exception:  # noqa: BLE001 - torch's own compile meets it again, where agrl falls back to eager
        return False
    try:
        folder.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(f"{path.name}.{os.getpid()}.partial")
        partial.write_text(json.dumps({"setting": setting, "usable": usable}))
        os.replace(partial, path)
    except OSError:
        pass  # not kept: the next process probes again
    return False


#: Rows a batch is padded to a multiple of wherever a row's bits must not depend on the batch it is computed in:
#: the compiled kernel computes the rows after its last full vector (8 floats with AVX2, 16 with AVX-512) in a second
#: copy of its loop, and ATen's eager loops run the rows after their last pair of vectors through a scalar loop; both
#: round sines, arctangents and tanh differently in places. 64 is a multiple of twice the widest vector.
WHOLE_VECTOR_ROWS = 64


def padded_rows(index: torch.Tensor) -> torch.Tensor:
    """``index`` (rows of a batch, 1-D) followed by copies of its first row up to a multiple of
    :data:`WHOLE_VECTOR_ROWS`: compute on ``batch[padded_rows(index)]`` and keep the first ``index.numel()`` rows,
    and each row comes out as in any batch of whole vectors."""
    return torch.cat((index, index[:1].expand(-index.numel() % WHOLE_VECTOR_ROWS)))


class CachedRowwiseCompile:
    """``fn`` compiled with ``torch.compile`` once for any number of rows, kept on disk for later processes.

    ``fn`` must be row-wise: each tensor argument and result has the rows as its first dimension, and row i of the
    results depends on row i of the arguments only (so one or no row can be padded or run eagerly). The compiled
    kernel keeps that to float rounding only: the rows after its last full vector (8 floats with AVX2, 16 with
    AVX-512) run in a second copy of its loop that rounds differently in places, so a caller that needs a row's bits
    independent of the batch pads it to whole vectors (:func:`padded_rows`), as the evaluation does. Its arguments
    keep their dtype, device and strides from call to call (a call that breaks the compilation's guards raises,
    and :class:`EagerFallback` then runs ``fn`` eagerly), and its first argument (or its first element) is a
    tensor. It is compiled ahead of its first call (``torch.compile(...).aot_compile``) with the rows as a dynamic
    dimension, once per dtype, device, torch thread count and grad mode (a call in inference mode uses the
    no-grad one), and saved in :func:`compile_cache_dir`
    under a name that hashes these, ``key`` (the constants the caller passes in, e.g. its parameters), the source
    of ``fn``'s package, the torch and Python versions and the processor. A later process with the same name loads
    it (under a second, instead of tens of seconds of tracing and compiling); torch's own cache
    (``TORCHINDUCTOR_CACHE_DIR``) keeps the built kernels it needs, and without them loading rebuilds them (a few
    seconds). A file that cannot be loaded or no longer fits is compiled again and replaced, with one warning line;
    a folder that cannot be written is used in memory only.

    The files hold code, like torch's own compile cache: they are written by this class for this user and are
    never meant to be shared (the folder is created private).
    """

    def __init__(self, fn: Callable, what: str, key: str, options: dict[str, Any] | None = None):
        self.fn = fn
        self.what = what
        self.key = key
        self.options = dict(options or {})
        self._compiled: dict[tuple, Callable] = {}
        self._unguarded: dict[tuple, Callable] = {}  # per signature, once a repeat has met the guards throughout
        self.loaded_from: Path | None = None  # the file of the last compilation loaded from disk, if any

    @staticmethod
    def _signature(first: torch.Tensor) -> tuple:
        # torch's thread count (its kernels are built for it) and grad mode are part of what a compilation guards.
        return first.dtype, first.device, torch.get_num_threads(), torch.is_grad_enabled()

    def __call__(self, *args: Any) -> Any:
        first = _first_tensor(args)
        if torch.is_inference_mode_enabled() or first.is_inference():
            return self._outside_inference_mode(args)
        signature = self._signature(first)
        compiled = self._compiled.get(signature)
        rows = first.shape[0]
        if compiled is not None and rows > 1:
            return compiled(*args)  # the common case, kept short: it runs many times a decision
        if rows == 0:
            return self.fn(*args)  # nothing to compute
        if rows == 1:  # the compilation's rows start at two (torch specialises 0 and 1): pad with a copy
            padded = pytree.tree_map_only(torch.Tensor, lambda tensor: torch.cat((tensor, tensor)), args)
            return pytree.tree_map_only(torch.Tensor, lambda tensor: tensor[:1], self(*padded))
        compiled, result = self._load_or_compile(signature, args)
        self._compiled[signature] = compiled
        return result

    def repeat(self, times: int, *args: Any) -> Any:
        """:func:`repeat`: ``fn`` applied ``times`` times, each call's results replacing its leading arguments, with
        torch's guard check on the first call only, once such a repeat has met the guards on every call.

        The results of a compiled call are new tensors with the rows, dtypes, device and (contiguous) strides its
        compilation makes; where they are those of the arguments they replace, the next call meets the guards the
        first one met, since nothing else changes between the calls. The first repeat of each compilation checks
        every call (a result that breaks the guards raises, as any call that breaks them), then trusts the rest."""
        _check_times(times)
        first = _first_tensor(args)
        fast = first.shape[0] > 1 and not (torch.is_inference_mode_enabled() or first.is_inference())
        signature = self._signature(first) if fast else None
        unguarded = self._unguarded.get(signature)
        if unguarded is None:  # every call checked (and compiled, or loaded, on the first if need be)
            results = repeat(self, times, *args)
            checked = self._compiled.get(signature) if times > 1 else None  # results fed back met the guards
            if hasattr(checked, "disable_guard_check"):  # torch's AOT-compiled function: trust the next repeats
                unguarded = copy.copy(checked)
                unguarded.disable_guard_check()
                self._unguarded[signature] = unguarded
            return results
        results = self._compiled[signature](*args)  # the first call, checked
        if times > 1:
            results = repeat(unguarded, times - 1, *results, *args[len(results):])
        return results

    def _outside_inference_mode(self, args: tuple) -> Any:
        """A call under ``torch.inference_mode`` (a user's evaluation), or on tensors made there: the compilation's
        guards check each argument's dispatch keys, which an inference tensor lacks, so such a call would fail
        them and fall back to eager, or in a later process replace the kept file. It runs outside inference mode
        and without gradients instead, its inference tensors copied: the no-grad compilation, the same results."""
        with torch.inference_mode(False), torch.no_grad():
            ordinary = pytree.tree_map_only(
                torch.Tensor, lambda tensor: tensor.clone() if tensor.is_inference() else tensor, args)
            return self(*ordinary)

    # ------------------------------------------------------------------ the disk cache
    def cache_file(self, signature: tuple) -> Path | None:
        folder = compile_cache_dir()
        if folder is None:
            return None
        digest = hashlib.sha256()
        for part in (self.key, repr(signature), repr(sorted(self.options.items())), torch.__version__,
                     sys.version, platform.machine(), _device_description(signature)):
            digest.update(part.encode() + b"\0")
        for source in sorted(Path(sys.modules[self.fn.__module__].__file__).parent.glob("*.py")):
            digest.update(source.read_bytes())
        return folder / f"{self.fn.__name__.strip('_')}-{digest.hexdigest()[:20]}.bin"

    def _load_or_compile(self, signature: tuple, args: tuple) -> tuple[Callable, Any]:
        keep_kernels_per_instruction_set()
        path = self.cache_file(signature)
        if path is None:
            compiled = self._compile(args)
            return compiled, compiled(*args)
        try:
            path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
            from filelock import FileLock

            lock = FileLock(f"{path}.lock")
            lock.acquire()  # another process compiling the same function: wait, then load its file
        except OSError as error:
            warnings.warn(f"cannot keep the compiled {self.what} in {path.parent} ({error}); compiling it in "
                          "memory", RuntimeWarning, stacklevel=4)
            compiled = self._compile(args)
            return compiled, compiled(*args)
        try:
            if path.is_file():
                try:
                    with open(path, "rb") as file:
                        compiled = torch.compiler.load_compiled_function(file, f_globals=self.fn.__globals__)
                    result = compiled(*args)
                    self.loaded_from = path
                    os.utime(path)  # recently used: kept by _prune
                    return compiled, result
                except Exception as error:  # noqa: BLE001 - a damaged or stale file is compiled again
                    reason = _one_line(error)
                    warnings.warn(f"the compiled {self.what} in {path} could not be used ({type(error).__name__}: "
                                  f"{reason}); compiling it again", RuntimeWarning, stacklevel=4)
            compiled = self._compile(args)
            result = compiled(*args)  # a compilation that cannot run is not kept
            self._save(compiled, path)
            return compiled, result
        finally:
            lock.release()

    def _compile(self, args: tuple) -> Callable:
        import torch._dynamo

        example = pytree.tree_map_only(torch.Tensor, torch.clone, args)  # marking dynamic leaves the caller's alone
        for tensor in pytree.tree_leaves(example):
            if isinstance(tensor, torch.Tensor):
                torch._dynamo.mark_dynamic(tensor, 0)
        function = torch.compile(self.fn, fullgraph=True, options=self.options)
        return function.aot_compile((example, {}))

    def _save(self, compiled: Callable, path: Path) -> None:
        partial = path.with_name(f"{path.name}.{os.getpid()}.partial")
        try:
            compiled.save_compiled_function(str(partial))
            os.replace(partial, path)  # readers see the old file or the whole new one
            _prune(path.parent)
        except Exception as error:  # noqa: BLE001 - a full disk or a compilation torch cannot save: still usable here
            partial.unlink(missing_ok=True)
            warnings.warn(f"cannot keep the compiled {self.what} in {path} ({error}); it is compiled again in the "
                          "next process", RuntimeWarning, stacklevel=5)


#: Compilations kept in the cache folder (about 1 MB each); the least recently used beyond this are removed, so that
#: editing agrl.core (a new name for each version) does not fill the disk.
KEPT_COMPILATIONS = 32


def _prune(folder: Path) -> None:
    files = sorted(folder.glob("*.bin"), key=lambda file: file.stat().st_mtime, reverse=True)
    for file in files[KEPT_COMPILATIONS:]:
        file.unlink(missing_ok=True)
        Path(f"{file}.lock").unlink(missing_ok=True)


def _one_line(error: Exception) -> str:
    """A failed guard's reason (torch's message spans lines), or the error's first line."""
    text = str(error).strip()
    guard = re.search(r"verbose_code_parts=\[(.*?)\]", text, re.DOTALL)
    return " ".join((guard.group(1) if guard else (text.splitlines() or [""])[0]).split())


def _first_tensor(value: Any) -> torch.Tensor:
    while not isinstance(value, torch.Tensor):
        value = value[0]
    return value


def _device_description(signature: tuple) -> str:
    """The processor the kernels are built for: the CPU's vector instructions, and the GPU's model if any."""
    device = signature[1]
    described = torch.backends.cpu.get_cpu_capability()
    if device.type == "cuda":
        described += f" {torch.cuda.get_device_name(device)} {torch.cuda.get_device_capability(device)}"
    return described
