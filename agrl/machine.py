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
        "torch": torch.__version__,
        "threads": torch.get_num_threads(),
    }


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
