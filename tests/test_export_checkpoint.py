"""``python -m agrl.export SOURCE DESTINATION --evaluation eval.json`` (the checkpoint format, the default): the
slim copy a run is shared as and the shipped baseline was made with. The other formats: tests/test_export.py."""

from __future__ import annotations

import json

import pytest
import torch
from torch.serialization import get_unsafe_globals_in_checkpoint

from agrl.rl.checkpoint import load_checkpoint, save_checkpoint
from agrl.rl.trainer import Trainer

pytestmark = pytest.mark.usefixtures("torch_one_thread")

def assert_same_tensors(a: dict, b: dict, where: str) -> None:
    assert a.keys() == b.keys(), where
    for key in a:
        assert torch.equal(a[key], b[key]), f"{where}[{key}]"


SLIM_KEYS = {"format_version", "versions", "actor", "critic", "config", "config_yaml", "counters", "exported_from",
             "evaluation"}


@pytest.fixture(scope="module")
def exported(tiny_run, run_cli, tmp_path_factory):
    """The export of the shared tiny run, in process (``main`` is all ``python -m agrl.export`` runs:
    ``sys.exit(main())``), and a missing source, as a real process: exit code and stderr line of the command."""
    import contextlib
    import io
    import subprocess

    from agrl.export import main

    directory = tmp_path_factory.mktemp("export")
    arguments = [str(tiny_run.run_dir), str(directory / "slim.pt"), "--evaluation",
                 str(tiny_run.run_dir / "eval" / "eval.json")]
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = main(arguments)
    run_dir = subprocess.CompletedProcess(["main", *arguments], code, stdout.getvalue(), stderr.getvalue())
    missing = run_cli.batch({"missing": ("export", str(directory / "missing.pt"), str(directory / "never.pt"))})
    return {"directory": directory, "run-dir": run_dir, **missing}


def test_export_keeps_the_networks_config_and_evaluation_only(exported, tiny_run):
    result = exported["run-dir"]
    assert result.returncode == 0, result.stderr[-3000:]
    slim_path = exported["directory"] / "slim.pt"
    assert result.stdout.strip().splitlines()[-1] == str(slim_path)
    assert get_unsafe_globals_in_checkpoint(slim_path) == []
    slim = load_checkpoint(slim_path)
    source = tiny_run.run_dir / "checkpoints" / "latest.pt"  # a run directory stands for its latest.pt
    full = load_checkpoint(source)
    assert set(slim) == SLIM_KEYS  # no optimiser, RNG, collector rows or reuse state
    for key in ("actor", "critic"):
        assert_same_tensors(slim[key], full[key], key)
    for key in ("config", "config_yaml", "counters"):
        assert slim[key] == full[key], key
    assert slim["exported_from"] == str(source)
    assert slim["evaluation"] == json.loads((tiny_run.run_dir / "eval" / "eval.json").read_text())


def test_an_exported_agent_is_a_baseline_for_pretrained_runs(exported, compose_train, tiny_args, tmp_path):
    slim_path = exported["directory"] / "slim.pt"
    assert exported["run-dir"].returncode == 0, exported["run-dir"].stderr[-3000:]
    trainer = Trainer(compose_train(*tiny_args(), "method=pretrained", f"method.baseline={slim_path}"), tmp_path)
    slim = load_checkpoint(slim_path)
    assert_same_tensors(trainer.actor.state_dict(), slim["actor"], "actor")
    assert_same_tensors(trainer.critic.state_dict(), slim["critic"], "critic")
    trainer.collector.shutdown()


def test_a_missing_source_is_one_line(exported):
    result = exported["missing"]
    assert result.returncode == 2, result.stderr[-3000:]
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert lines == [f"agrl.export: error: {exported['directory'] / 'missing.pt'}: no such checkpoint file or run "
                     "directory; allowed: a checkpoint file, a run directory, or a shipped agent (baseline, "
                     "baseline-first-search, baseline-two-stage, baseline-stage1, baseline-both-terms, "
                     "baseline-targets, baseline-absolute)"]
    assert not (exported["directory"] / "never.pt").exists()


def _shifted_copy(source, destination, shift: float, **changes):
    """``source``'s checkpoint with every actor and critic weight moved by ``shift`` (a second agent to average)."""
    payload = load_checkpoint(source)
    for part in ("actor", "critic"):
        payload[part] = {name: tensor + shift for name, tensor in payload[part].items()}
    payload.update(changes)
    return save_checkpoint(payload, destination)


def test_several_sources_give_one_agent_with_their_mean_weights(tiny_run, tmp_path, capsys):
    from agrl.export import main
    from agrl.guide import Guide

    source = tiny_run.run_dir / "checkpoints" / "latest.pt"
    other = _shifted_copy(source, tmp_path / "other.pt", 1.0)
    third = _shifted_copy(source, tmp_path / "third.pt", -0.25)
    assert main([str(tiny_run.run_dir), str(other), str(third), str(tmp_path / "soup.pt")]) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "soup.pt")
    soup = load_checkpoint(tmp_path / "soup.pt")
    full = load_checkpoint(source)
    assert get_unsafe_globals_in_checkpoint(tmp_path / "soup.pt") == []
    assert set(soup) == (SLIM_KEYS - {"evaluation"}) | {"averaged_from"}
    for part in ("actor", "critic"):
        for name, tensor in full[part].items():  # the mean of w, w + 1 and w - 0.25
            torch.testing.assert_close(soup[part][name], tensor + 0.25, msg=f"{part}[{name}]")
            assert soup[part][name].dtype == tensor.dtype
    assert soup["config"] == full["config"] and soup["exported_from"] == str(source)
    assert soup["averaged_from"] == [str(source), str(other), str(third)]
    Guide.load(tmp_path / "soup.pt")  # an agent like any other


def test_averaging_agents_of_different_networks_is_one_line(tiny_run, tmp_path, capsys):
    from agrl.export import main

    source = tiny_run.run_dir / "checkpoints" / "latest.pt"
    payload = load_checkpoint(source)
    payload["critic"] = {**payload["critic"], "0.weight": torch.zeros(64, 23)}
    save_checkpoint(payload, tmp_path / "narrow.pt")
    assert main([str(source), str(tmp_path / "narrow.pt"), str(tmp_path / "soup.pt")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and f"{tmp_path / 'narrow.pt'}: its critic network differs from" in lines[0]
    assert "0.weight absent in the first, (64, 23) in this one" in lines[0] and not (tmp_path / "soup.pt").exists()
    with pytest.raises(SystemExit):
        main([str(source), str(source), str(tmp_path / "soup.onnx"), "--format", "onnx"])
    assert "2 sources are not allowed with --format onnx" in capsys.readouterr().err


def test_an_existing_destination_is_kept_unless_forced(tmp_path, capsys):
    from agrl.export import main

    destination = tmp_path / "latest.pt"
    destination.write_bytes(b"a run's checkpoint")
    with pytest.raises(SystemExit) as exited:
        main(["baseline", str(destination)])
    assert exited.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        f"python -m agrl.export: error: destination={str(destination)!r} is not allowed: it exists (a run's "
        "checkpoint, say); give --force to replace it, or another path")
    assert destination.read_bytes() == b"a run's checkpoint"
    assert main(["baseline", str(destination), "--force"]) == 0
    assert set(load_checkpoint(destination)) >= {"actor", "critic", "config"}


@pytest.mark.parametrize("content", [None, "not json", "[1, 2]"])
def test_a_bad_evaluation_file_is_one_line_naming_the_option(tmp_path, capsys, content):
    from agrl.export import main

    evaluation = tmp_path / "eval.json"
    if content is not None:
        evaluation.write_text(content)
    assert main(["baseline", str(tmp_path / "slim.pt"), "--evaluation", str(evaluation)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"agrl.export: error: --evaluation={evaluation}: not ")
    assert not (tmp_path / "slim.pt").exists()
