"""``agrl.machine``: the processor record a run's evaluation carries."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from agrl.machine import processor_record


def test_the_record_names_the_kernels_path_torch_and_threads(monkeypatch):
    monkeypatch.setenv("MKL_ENABLE_INSTRUCTIONS", "AVX2")  # what make train sets
    record = processor_record()
    assert record["cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    assert record["mkl_instructions"] == "AVX2"
    monkeypatch.delenv("MKL_ENABLE_INSTRUCTIONS")
    assert processor_record()["mkl_instructions"] == ""  # MKL's own choice
    assert (record["torch"], record["threads"]) == (torch.__version__, torch.get_num_threads())
    assert record["cpu"]


@pytest.mark.skipif(not Path("/proc/cpuinfo").is_file(), reason="no /proc/cpuinfo")
def test_the_record_reads_the_first_processor_of_proc_cpuinfo():
    first = Path("/proc/cpuinfo").read_text().split("\n\n")[0]
    fields = {key.strip(): value.strip() for key, _, value in (line.partition(":") for line in first.splitlines())}
    record = processor_record()
    if "model name" in fields:  # x86 and most others; some ARM kernels name none
        assert record["cpu"] == fields["model name"]
    if "cpu family" in fields:
        assert record["cpu_family_model"] == f"{fields['cpu family']}/{fields['model']}"
