"""``python -m agrl.distill``: errors (the distillation itself: tests/rl/test_distill.py)."""

from __future__ import annotations

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
