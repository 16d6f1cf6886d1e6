"""``agrl.machine``: the processor record a run's evaluation carries."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from agrl.machine import other_path, processor_record


def test_the_record_names_the_kernels_path_torch_and_threads(monkeypatch):
    monkeypatch.setenv("MKL_ENABLE_INSTRUCTIONS", "AVX2")  # what make train sets
    record = processor_record()
    assert record["cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    assert record["mkl_instructions"] == "AVX2"
    monkeypatch.delenv("MKL_ENABLE_INSTRUCTIONS")
    assert processor_record()["mkl_instructions"] == ""  # MKL's own choice
    assert (record["torch"], record["threads"]) == (torch.__version__, torch.get_num_threads())
    assert type(record["torch"]) is str  # not torch's TorchVersion, which a weights_only load of a checkpoint refuses
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


def test_another_processor_path_is_named_field_by_field():
    here = {**processor_record(), "cpu_capability": "AVX512", "mkl_instructions": ""}
    assert other_path({**here, "cpu": "another model", "threads": 64}, here) is None  # the same path
    assert other_path(None, here) is None  # a checkpoint from before they recorded it
    assert other_path({"cpu_capability": "AVX2", "mkl_instructions": "AVX2"}, here) == (
        "cpu_capability 'AVX2' there, 'AVX512' here; mkl_instructions 'AVX2' there, '' here")
    assert other_path({"cpu_capability": "AVX512"}, here) is None  # MKL's own choice, unrecorded: the same
