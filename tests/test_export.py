"""``python -m agrl.export``: checkpoint, ONNX and torch.export formats, each answering what the TorchRL actor does."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import torch
from test_guide import actor_maneuvers, random_raw_states

from agrl.export import main
from agrl.guide import Guide, GuideError

STATES = 10_000
SINGLE_QUERIES = 500


@pytest.fixture(scope="module")
def exports(tmp_path_factory):
    folder = tmp_path_factory.mktemp("exports")
    paths = {"checkpoint": folder / "slim.pt", "onnx": folder / "guide.onnx", "torch_export": folder / "guide.pt2"}
    # The format follows the destination's suffix unless given (torch_export is given here, the others inferred).
    assert main(["baseline", str(paths["checkpoint"])]) == 0
    assert main(["baseline", str(paths["onnx"])]) == 0
    assert main(["baseline", str(paths["torch_export"]), "--format", "torch_export"]) == 0
    assert all(path.is_file() for path in paths.values())
    return paths


@pytest.fixture(scope="module")
def states():
    aircraft, destination, last_action = random_raw_states(STATES, seed=5)
    return aircraft, destination, last_action, actor_maneuvers("baseline", aircraft, destination, last_action)


@pytest.mark.parametrize("format_name", ["checkpoint", "onnx", "torch_export"])
def test_every_format_answers_what_the_torchrl_actor_answers(exports, states, format_name):
    aircraft, destination, last_action, expected = states
    guide = Guide.load(exports[format_name])
    assert guide.kind == format_name
    assert guide.source.endswith(".pt")  # the checkpoint it came from
    np.testing.assert_array_equal(guide.instruct_batch(aircraft, destination, last_action), expected)
    single = [guide.instruct(aircraft[i], destination[i], int(last_action[i])) for i in range(SINGLE_QUERIES)]
    np.testing.assert_array_equal(np.array(single), expected[:SINGLE_QUERIES])


def test_onnx_file_runs_without_agrl(exports, states):
    """What a deployment without agrl does: onnxruntime alone, raw-state inputs, the maneuver out."""
    import onnxruntime

    aircraft, destination, last_action, expected = states
    session = onnxruntime.InferenceSession(str(exports["onnx"]), providers=["CPUExecutionProvider"])
    assert [value.name for value in session.get_inputs()] == ["aircraft_state", "destination_state", "last_action"]
    (maneuver,) = session.run(["maneuver"], {"aircraft_state": aircraft[:500], "destination_state": destination[:500],
                                             "last_action": last_action[:500].astype(np.int64)})
    np.testing.assert_array_equal(maneuver, expected[:500])


def test_torch_export_file_runs_as_a_plain_module(exports, states):
    aircraft, destination, last_action, expected = states
    module = torch.export.load(str(exports["torch_export"])).module()
    answer = module(torch.from_numpy(aircraft[:500]), torch.from_numpy(destination[:500]),
                    torch.from_numpy(last_action[:500]))
    np.testing.assert_array_equal(answer.numpy(), expected[:500])


def test_foreign_and_corrupt_files_are_refused(tmp_path):
    corrupt = tmp_path / "broken.onnx"
    corrupt.write_bytes(b"not a model")
    with pytest.raises(GuideError, match="broken.onnx: not a readable ONNX model"):
        Guide.load(corrupt)
    foreign = tmp_path / "foreign.onnx"
    import onnx
    from onnx import TensorProto, helper

    graph = helper.make_graph([helper.make_node("Identity", ["x"], ["y"])], "identity",
                              [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1])],
                              [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1])])
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)]), str(foreign))
    with pytest.raises(GuideError, match="foreign.onnx: not an agrl guide export"):
        Guide.load(foreign)
    with pytest.raises(GuideError, match="missing.pt2: no such torch.export file"):
        Guide.load(tmp_path / "missing.pt2")
    broken = tmp_path / "broken.pt2"
    broken.write_bytes(b"not an archive")
    with pytest.raises(GuideError, match="broken.pt2: not a readable torch.export archive"):
        Guide.load(broken)


def test_cli_arguments_are_checked(tmp_path):
    destination = str(tmp_path / "guide.onnx")
    command = [sys.executable, "-m", "agrl.export", "baseline", destination, "--format", "torch_export"]
    completed = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert completed.returncode == 2
    assert "destination=" in completed.stderr and "format=torch_export writes a .pt2 file" in completed.stderr
    with pytest.raises(SystemExit):
        main(["baseline", str(tmp_path / "g.onnx"), "--format", "onnx", "--evaluation", "eval.json"])
    with pytest.raises(SystemExit):
        main(["baseline", str(tmp_path / "g.onnx"), "--format", "tflite"])


def test_a_suffix_of_another_format_is_refused(tmp_path, capsys):
    with pytest.raises(SystemExit) as exited:
        main(["baseline", str(tmp_path / "g.onnx"), "--format", "checkpoint"])
    assert exited.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1].endswith(
        "is not allowed: format=checkpoint writes a checkpoint, not a .onnx file")
    assert not (tmp_path / "g.onnx").exists()


def test_an_agent_holding_targets_exports_with_its_held_targets_input(tiny_targets_run, tmp_path):
    """Both graphs of an agent holding targets read ``held_targets`` and answer what its TorchRL actor answers;
    the action set travels in the metadata."""
    import onnxruntime
    from test_guide import actor_target_actions, random_held_targets

    aircraft, destination, _ = random_raw_states(1_000, seed=11)
    held = random_held_targets(aircraft, seed=11)
    expected = actor_target_actions(tiny_targets_run.run_dir, aircraft, destination, held)
    for name in ("guide.onnx", "guide.pt2"):
        assert main([str(tiny_targets_run.run_dir), str(tmp_path / name)]) == 0
        guide = Guide.load(tmp_path / name)
        assert guide.holds_targets and guide.num_actions == 26
        np.testing.assert_array_equal(guide.instruct_batch(aircraft, destination, held), expected)
        assert guide.instruct(aircraft[0], destination[0], held[0].tolist()) == expected[0]
    session = onnxruntime.InferenceSession(str(tmp_path / "guide.onnx"), providers=["CPUExecutionProvider"])
    assert [value.name for value in session.get_inputs()] == ["aircraft_state", "destination_state", "held_targets"]
    (action,) = session.run(["action"], {"aircraft_state": aircraft, "destination_state": destination,
                                         "held_targets": held})
    np.testing.assert_array_equal(action, expected)
