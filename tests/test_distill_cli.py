"""``python -m agrl.distill``: errors (the distillation itself: tests/rl/test_distill.py)."""

from __future__ import annotations

import pytest
import torch

from agrl.distill import main


def test_a_missing_teacher_is_one_line(tmp_path, capsys):
    assert main([str(tmp_path / "nothing.pt"), str(tmp_path / "out.pt")]) == 2
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and error.startswith("agrl.distill: error:") and "nothing.pt" in error
    assert not (tmp_path / "out.pt").exists()


def test_an_ensemble_with_a_missing_teacher_is_one_line_naming_it(tmp_path, capsys):
    assert main(["baseline", str(tmp_path / "missing.pt"), str(tmp_path / "out.pt"), "--observation", "relative"]) == 2
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and error.startswith("agrl.distill: error:") and "missing.pt" in error
    assert not (tmp_path / "out.pt").exists()


def test_threads_sets_torchs_intra_op_threads_before_the_work(tmp_path, capsys):
    threads = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        assert main([str(tmp_path / "nothing.pt"), str(tmp_path / "out.pt"), "--threads", "1"]) == 2
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(threads)


@pytest.mark.parametrize("option", ["--rounds", "--envs", "--epochs", "--threads"])
def test_counts_below_one_are_refused_naming_the_value(tmp_path, capsys, option):
    with pytest.raises(SystemExit) as exited:
        main(["baseline", str(tmp_path / "out.pt"), option, "0"])
    assert exited.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        f"python -m agrl.distill: error: argument {option}: 0 is not allowed: a positive integer")


def test_an_unwritable_destination_is_refused_before_the_rounds(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    assert main(["baseline", str(blocker / "student.pt")]) == 2
    assert capsys.readouterr().err.strip() == (
        f"agrl.distill: error: {blocker / 'student.pt'}: cannot be written: {blocker} is a file, not a folder")
