"""The machine a run was made on, as its results record it: a run repeats bit for bit only on the same processor
path and thread count (torch's CPU kernels, and the code torch.compile generates, choose their instructions by
processor), so an agent's record names them."""

from __future__ import annotations

import os
import platform

import torch


def cpu_model(cpuinfo: dict[str, str] | None = None) -> str:
    """The processor's model name (``/proc/cpuinfo``, or its fields already read), else what :mod:`platform`
    knows."""
    cpuinfo = _cpuinfo() if cpuinfo is None else cpuinfo
    return cpuinfo.get("model name") or platform.processor() or platform.machine()


def processor_record() -> dict[str, str | int]:
    """What decides a CPU run's rounding: the processor (model name; family and model number on x86, which tell
    apart processors sold under one name), the instruction set torch's kernels use here, the one MKL's are limited
    to (``MKL_ENABLE_INSTRUCTIONS``; empty: MKL's own choice), torch and its threads."""
    info = _cpuinfo()
    return {
        "cpu": cpu_model(info),
        "cpu_family_model": f"{info['cpu family']}/{info['model']}" if "cpu family" in info else "",
        "cpu_capability": torch.backends.cpu.get_cpu_capability(),
        "mkl_instructions": os.environ.get("MKL_ENABLE_INSTRUCTIONS", ""),
        "torch": str(torch.__version__),  # a plain string: checkpoints keep the record (weights_only)
        "threads": torch.get_num_threads(),
    }


#: What makes a run round differently on one processor or another: the instruction sets torch's and MKL's kernels use.
PATH_FIELDS = ("cpu_capability", "mkl_instructions")


def other_path(saved: dict | None, here: dict | None = None) -> str | None:
    """How the processor path of ``saved`` (a :func:`processor_record`, e.g. a checkpoint's ``machine``) differs
    from ``here`` (default: this process's), in words, or ``None`` if it does not (or ``saved`` is ``None``: a
    checkpoint written before they recorded it). A resume is exact only on its checkpoint's path."""
    if not saved:
        return None
    here = processor_record() if here is None else here
    differing = [f"{field} {saved.get(field, '')!r} there, {here[field]!r} here" for field in PATH_FIELDS
                 if saved.get(field, "") != here[field]]
    return "; ".join(differing) or None


def _cpuinfo() -> dict[str, str]:
    """The first processor's fields in ``/proc/cpuinfo`` (empty where there is none)."""
    fields: dict[str, str] = {}
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            for line in cpuinfo:
                if not line.strip():
                    break
                key, _, value = line.partition(":")
                fields.setdefault(key.strip().lower(), value.strip())
    except OSError:
        pass
    return fields
