"""``agrl.cli``: the entry points' command line, checked before Hydra runs (the subprocess side, exit codes and
messages, is in tests/test_train_cli.py and tests/test_evaluate_cli.py)."""

from __future__ import annotations

import pytest

from agrl.cli import check_overrides, resume_in_place
from agrl.config import ConfigError


def test_valid_overrides_pass():
    check_overrides(["task=curved", "radius=500", "method=reuse", "ppo.num_envs=64", "+experiment=fast"], "config")
    check_overrides(["checkpoint=baseline", "task=uniform", "speed=20", "threads=1"], "evaluate")


def test_hydras_own_overrides_are_checked_and_its_flags_left_to_it():
    check_overrides(["hydra/launcher=joblib", "hydra.launcher.n_jobs=2", "hydra.run.dir=/nowhere", "seed=1"], "config")
    with pytest.raises(ConfigError, match=r"^hydra\.launcher\.n_jobs=2 is not allowed"):  # the basic launcher has none
        check_overrides(["hydra.launcher.n_jobs=2", "seed=1"], "config")
    for flag in ("--help", "--cfg=job", "--info"):
        check_overrides([flag, "sed=1"], "config")  # Hydra prints help or the config; nothing runs


def test_every_value_of_every_sweep_is_checked():
    check_overrides(["-m", "task=uniform", "speed=10,20,50,100", "method=scratch,pretrained,reuse", "seed=0,1,2"],
                    "config")
    with pytest.raises(ConfigError, match=r"^method=foo is not allowed: one of pretrained, reuse, scratch$"):
        check_overrides(["--multirun", "task=uniform", "speed=10,20", "method=scratch,foo"], "config")
    with pytest.raises(ConfigError, match=r"^speed=-20\.0 is not allowed"):
        check_overrides(["-m", "seed=0,1", "task=uniform", "speed=10,-20"], "config")
    with pytest.raises(ConfigError, match=r"^task=foo is not allowed"):
        check_overrides(["-m", "task=choice(fixed,foo)", "seed=range(0,3)"], "config")
    check_overrides(["-m", "task=glob(f*)", "seed=range(0,3)"], "config")  # whatever it expands to, no crash


def test_the_culprit_is_named_among_valid_overrides():
    with pytest.raises(ConfigError, match=r"^ppo\.epoch=3 is not allowed: ppo has no key 'epoch'; its keys: .*epochs"):
        check_overrides(["task=uniform", "speed=20", "ppo.epoch=3", "seed=2"], "config")


def test_a_resumed_run_takes_only_resumable_overrides(tiny_run):
    # Its values come from the checkpoint: composition, the overrides it may take and the file's existence are checked.
    check_overrides([f"resume={tiny_run.run_dir}", "ppo.total_frames=1000", "eval.interval=3"], "config")
    with pytest.raises(ConfigError, match=r"^ppo\.total_frame=1000 is not allowed"):
        check_overrides([f"resume={tiny_run.run_dir}", "ppo.total_frame=1000"], "config")
    with pytest.raises(ConfigError, match=r"^ppo\.num_envs=64 is not allowed with resume: .*only ppo\.total_frames"):
        check_overrides([f"resume={tiny_run.run_dir}", "ppo.num_envs=64"], "config")
    with pytest.raises(ConfigError, match=r"^resume: no/such/run: no such checkpoint file or run directory"):
        check_overrides(["resume=no/such/run", "ppo.total_frames=1000"], "config")


def test_a_named_checkpoint_must_exist(tmp_path):
    check_overrides(["method=pretrained", "method.baseline=baseline"], "config")  # the shipped one
    with pytest.raises(ConfigError, match=rf"^method\.baseline: {tmp_path}: run directory has no checkpoints/latest"):
        check_overrides(["method=reuse", f"method.baseline={tmp_path}"], "config")
    check_overrides(["method=scratch", f"method.baseline={tmp_path}"], "config")  # scratch reads no baseline
    with pytest.raises(ConfigError, match=r"^checkpoint: no/such\.pt: no such checkpoint file"):
        check_overrides(["checkpoint=no/such.pt"], "evaluate")


def test_a_resume_goes_on_in_its_run_directory(tiny_run):
    arguments = [f"resume={tiny_run.run_dir / 'checkpoints' / 'best.pt'}", "ppo.total_frames=1000"]
    assert resume_in_place(arguments, check_overrides(arguments, "config")) == [
        f"hydra.run.dir='{tiny_run.run_dir}'", "hydra.output_subdir=null"]
    chosen = [*arguments, "hydra.run.dir=elsewhere"]  # the user's choice stands
    assert resume_in_place(chosen, check_overrides(chosen, "config")) == []
    assert resume_in_place(["seed=1"], check_overrides(["seed=1"], "config")) == []


def test_adding_a_key_no_schema_reads_is_refused():
    # Hydra's hint for a mistyped key is "+key=value", which would add a key nothing reads.
    with pytest.raises(ConfigError, match=r"^\+ppo\.learning_rat=0\.001 is not allowed: ppo has no key 'learning_rat'"):
        check_overrides(["+ppo.learning_rat=0.001"], "config")
    check_overrides(["+experiment=fast", "seed=1"], "config")  # appending a config group stays allowed


def _cyclic_garbage_with_a_flag() -> list:
    """A reference cycle, already unreachable, and the list its finaliser appends to when it is collected."""
    import weakref

    collected: list = []

    class Node:
        pass

    node = Node()
    node.self = node
    weakref.finalize(node, collected.append, True)
    return collected


@pytest.mark.parametrize("outcome", ["returns", "raises"])
def test_a_command_ends_with_its_garbage_collected_and_the_rest_frozen(outcome):
    """run_command exits with main's code (or lets main's error through), having collected what was garbage, so
    that nothing frozen was waiting to be finalised, and frozen the rest for a short interpreter teardown."""
    import gc

    from agrl.cli import run_command

    def main() -> int:
        if outcome == "raises":
            raise RuntimeError("main failed")
        return 3

    gc.unfreeze()  # nothing frozen before: the freeze counted below is run_command's
    gc.disable()  # the cycle must wait for run_command's collection, not for an automatic one
    try:
        assert gc.get_freeze_count() == 0
        collected = _cyclic_garbage_with_a_flag()
        expected = (SystemExit, "3") if outcome == "returns" else (RuntimeError, "main failed")
        with pytest.raises(expected[0]) as ended:
            run_command(main)
        assert str(ended.value) == expected[1]
        assert collected == [True]
        assert gc.get_freeze_count() > 0
    finally:
        gc.unfreeze()
        gc.enable()
