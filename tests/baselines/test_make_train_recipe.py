"""``make train`` trains the shipped baseline, and ``make train-two-stage`` Tables 4-5's B: their
commands compose exactly the configs the shipped files were trained with (docs/results/baseline.md). A change to
the defaults, to ``conf/experiment/switch_schedule.yaml`` or ``switch_finetune.yaml``, or to the Makefile's targets
fails here until a retrained agent is shipped with it (or the recipe is restored): otherwise ``make train`` would
quietly stop reproducing the file."""

from __future__ import annotations

import dataclasses
import re
import shlex
import subprocess
from pathlib import Path

import pytest
import torch

from agrl.baselines import BASELINE_FILE, SHIPPED_AGENTS
from agrl.config import upgraded_config
from agrl.core.parameters import ACTION_FIELDS
from agrl.rl.metrics import flatten_config

ROOT = Path(__file__).resolve().parents[2]
#: make train-two-stage's stage 1 as shipped (checkpoint=baseline-stage1), trained on the same defaults.
STAGE_ONE_FILE = SHIPPED_AGENTS["baseline-stage1"].file
#: make train-two-stage's stage 2 (checkpoint=baseline-two-stage).
TWO_STAGE_FILE = SHIPPED_AGENTS["baseline-two-stage"].file
#: Set per invocation, not by the recipe: where the run starts from, whether a progress bar is drawn, and what the
#: run returns to a sweeper (the search section changes nothing in training).
NOT_THE_RECIPE = {"progress", "method.baseline", "search.success", "search.max_instructions", "search.penalty_seconds",
                  "search.seeds"}
#: Options added after the shipped files were trained, at the value that trains exactly as before: a file without
#: the key was trained with that value. Any other value of such an option is still a difference.
#: ``eval.confirm_episodes``: stage 1's confirmation holds where its periodic evaluation stopped it (``make train``
#: gave the shipped files bit for bit with it), and stage 2 never stops on a target.
#: ``actions``: the paper's maneuvers, the only actions there were (its target-holding fields unset).
#: ``finetune``: none (0 iterations: the run stops at its target; the other two keys are then unread).
ADDED_SINCE = {"ppo.target_kl": 0.0, "eval.confirm_episodes": 1000, "actions.name": "maneuvers",
               **{f"actions.{name}": "None" for name in ACTION_FIELDS["targets"]},
               "finetune.iterations": 0, "finetune.switch_cost": 0.3, "finetune.learning_rate": "None"}


def _recipe(config: dict) -> dict:
    """``a.b.c`` keys (as the TensorBoard hparams are written) without the per-invocation ones."""
    return {key: value for key, value in flatten_config(config).items() if key not in NOT_THE_RECIPE}


def _saved(path: Path) -> dict:
    """The file's saved config, with today's keys (the shipped files predate the keys' renaming)."""
    return _recipe(upgraded_config(torch.load(path, weights_only=True)["config"]))


def _differences(composed: dict, saved: dict) -> dict:
    """{key: (what the command composes, what the file was trained with)} for every key that differs."""
    saved = {**{key: value for key, value in ADDED_SINCE.items() if key not in saved}, **saved}
    # The files were trained when every method shared one schema: a method's section holds None for the knobs of
    # the others, which its own schema no longer has.
    saved = {key: value for key, value in saved.items()
             if not (key.startswith("method.") and value in (None, "None") and key not in composed)}
    return {key: (composed.get(key), saved.get(key)) for key in composed.keys() | saved.keys()
            if composed.get(key) != saved.get(key)}


def _makefile_finetune_args() -> list[str]:
    match = re.search(r"^FINETUNE_ARGS \?= (.*)$", (ROOT / "Makefile").read_text(), flags=re.MULTILINE)
    assert match, "the Makefile no longer sets FINETUNE_ARGS"
    return shlex.split(match.group(1))


def test_make_train_is_one_run_of_the_shipped_recipe(compose_train):
    (command,) = _dry_run_train_commands("train", "TRAIN_DIR=/tmp/agrl-train")
    assert command == ["+experiment=switch_schedule", "hydra.run.dir=/tmp/agrl-train"]
    config = compose_train("+experiment=switch_schedule")
    assert _differences(_recipe(dataclasses.asdict(config)), _saved(BASELINE_FILE)) == {}


def test_the_previous_baselines_command_composes_its_recipe(compose_train):
    """``baseline-first-search`` was make train's agent before the recipe changed; its listed command, the
    recipe of today with the values of then on the command line, composes the config it was trained with."""
    agent = SHIPPED_AGENTS["baseline-first-search"]
    command = shlex.split(agent.made_by[0])
    assert command[:3] == ["python", "-m", "agrl.train"]
    config = compose_train(*command[3:])
    assert _differences(_recipe(dataclasses.asdict(config)), _saved(agent.file)) == {}


def _composed(compose_train, command: list[str]) -> dict:
    """The recipe a ``python -m agrl.train`` command composes (its run folder aside)."""
    return _recipe(dataclasses.asdict(compose_train(*[item for item in command if not item.startswith("hydra.")])))


def test_two_stage_stage_one_is_the_defaults_with_the_eager_loss(compose_train):
    stage1, _ = _dry_run_train_commands("train-two-stage", "TWO_STAGE_DIR=/tmp/agrl-two")
    assert stage1 == ["ppo.compile_loss=false", "hydra.run.dir=/tmp/agrl-two/stage1"]
    assert _differences(_composed(compose_train, stage1), _saved(STAGE_ONE_FILE)) == {}


def test_two_stage_stage_two_is_the_finetune_experiment_with_the_makefiles_arguments(compose_train):
    _, stage2 = _dry_run_train_commands("train-two-stage", "TWO_STAGE_DIR=/tmp/agrl-two")
    assert stage2[:4] == ["+experiment=switch_finetune", "ppo.compile_loss=false",
                          "method.baseline=/tmp/agrl-two/stage1", "hydra.run.dir=/tmp/agrl-two/stage2"]
    assert stage2[4:] == _makefile_finetune_args()
    assert _differences(_composed(compose_train, stage2), _saved(TWO_STAGE_FILE)) == {}


def test_make_train_targets_composes_the_shipped_target_agents_recipe(compose_train):
    stage1, stage2 = _dry_run_train_commands("train-targets", "TARGETS_TRAIN_DIR=/tmp/agrl-targets")
    assert "actions=targets" in stage1 and "+experiment=switch_finetune" not in stage1
    assert "ppo.compile_loss=false" in stage1  # as stage 2, whose saved config is compared below
    assert "method.baseline=/tmp/agrl-targets/stage1" in stage2
    assert _differences(_composed(compose_train, stage2), _saved(SHIPPED_AGENTS["baseline-targets"].file)) == {}


def test_the_two_stage_file_was_fine_tuned_from_a_stage_one_run():
    saved = torch.load(TWO_STAGE_FILE, weights_only=True)["config"]
    assert saved["method"]["name"] == "pretrained"
    assert saved["method"]["baseline"].endswith("stage1")


def test_the_shipped_file_was_trained_from_scratch_with_a_fine_tune_phase():
    saved = torch.load(BASELINE_FILE, weights_only=True)["config"]
    assert saved["method"]["name"] == "scratch"
    assert saved["finetune"]["iterations"] > 0 and saved["finetune"]["switch_cost"] > saved["reward"]["switch_cost"]


def _make_train_args(args: str) -> subprocess.CompletedProcess:
    """``make train-two-stage``'s first step alone: the check of ARGS, which runs before anything is installed or
    trained."""
    return subprocess.run(["make", "--no-print-directory", "train-args", f"ARGS={args}"], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize("args", ["task=uniform speed=50", "seed=2 method=reuse", "+experiment=fast",
                                  "agent.actor_hidden=[64,64]"])
def test_make_train_two_stage_refuses_arguments_stage_two_cannot_fine_tune(args):
    result = _make_train_args(args)
    assert result.returncode != 0
    assert f"ARGS='{args}'" in result.stderr and "python -m agrl.train" in result.stderr


@pytest.mark.parametrize("args", ["", "seed=3", "seed=3 ppo.learning_rate=1e-3 reward.switch_cost=0.2"])
def test_make_train_two_stage_accepts_other_stage_one_overrides(args):
    assert _make_train_args(args).returncode == 0


def _dry_run(target: str, *variables: str) -> str:
    """What ``make -n <target>`` prints: the commands it would run, none of them run."""
    return subprocess.run(["make", "--no-print-directory", "-n", target, *variables], cwd=ROOT,
                          capture_output=True, text=True, timeout=60, check=True).stdout


def _dry_run_train_commands(target: str, *variables: str) -> list[list[str]]:
    """The overrides of each ``python -m agrl.train`` command ``make -n <target>`` would run, in order."""
    commands = _dry_run(target, *variables).replace("\\\n", " ").splitlines()
    return [shlex.split(line.split(" -m agrl.train ", 1)[1]) for line in commands
            if re.match(r"(?:\w+=\S* )*\S*python\S* -m agrl\.train ", line)]


def test_make_train_fast_fine_tunes_its_own_stage_one(compose_train):
    stage_one, stage_two = _dry_run_train_commands("train-fast", "FAST_TRAIN_DIR=/tmp/agrl-fast", "ARGS=seed=2")
    assert "hydra.run.dir=/tmp/agrl-fast/stage1" in stage_one and "hydra.run.dir=/tmp/agrl-fast/stage2" in stage_two
    first, second = (compose_train(*[item for item in overrides if not item.startswith("hydra.")])
                     for overrides in (stage_one, stage_two))
    assert second.method.name == "pretrained" and second.method.baseline == "/tmp/agrl-fast/stage1"
    # Stage 2 loads stage 1's actor and critic: the networks must be the same.
    assert second.agent == first.agent and first.agent.actor_hidden == [64, 64]
    assert first.seed == second.seed == 2
    # make train's reward (the position term and a switch cost), then the fine-tune's larger cost, both compiled.
    assert first.reward.name == second.reward.name == "switch" and not first.reward.use_continuous_action
    assert second.reward.switch_cost > first.reward.switch_cost
    assert first.ppo.compile_loss and second.ppo.compile_loss


def test_make_train_passes_its_arguments_to_its_one_run():
    (command,) = _dry_run_train_commands("train", "TRAIN_DIR=/tmp/agrl-train", "ARGS=seed=2")
    assert command == ["+experiment=switch_schedule", "hydra.run.dir=/tmp/agrl-train", "seed=2"]


def _has_avx2() -> bool:
    cpuinfo = Path("/proc/cpuinfo")
    return cpuinfo.is_file() and "avx2" in cpuinfo.read_text().split()


def _make_train_environment(*variables: str) -> list[str]:
    """The variables ``make train`` sets on its ``python -m agrl.train`` command."""
    (line,) = [line for line in _dry_run("train", "TRAIN_DIR=/tmp/agrl-train", *variables).splitlines()
               if " -m agrl.train " in line]
    return re.match(r"((?:\w+=\S* )*)", line).group(1).split()


def test_make_train_runs_on_the_processor_path_the_shipped_agent_was_trained_on():
    """On AVX-512 processors too, so that it trains the shipped file bit for bit there (docs/results/baseline.md)."""
    recorded = torch.load(BASELINE_FILE, weights_only=True)["evaluation"]["machine"]["cpu_capability"]
    expected = [f"ATEN_CPU_CAPABILITY={recorded.lower()}", f"MKL_ENABLE_INSTRUCTIONS={recorded.upper()}"]
    assert _make_train_environment() == (expected if _has_avx2() else [])
    assert _make_train_environment("CPU_PATH=") == []  # left to torch


def test_tables_4_and_5_are_reproduced_with_the_b_they_were_measured_with():
    """docs/results/moving.md was measured with baseline-two-stage, the shipped baseline of the day, and the eager
    loss, the default of the day (its runs have wall-time budgets: a faster update would give them more iterations)."""
    commands = _dry_run_train_commands("experiments-moving")
    assert len(commands) == 5
    assert all("method.baseline=baseline-two-stage" in command for command in commands)
    assert all("ppo.compile_loss=false" in command for command in commands)


def test_table_3_is_reproduced_with_the_loss_it_was_measured_with():
    """docs/results/table3.md's runs (wall-time budgets, then 80-iteration fine-tunes) ran the eager loss."""
    commands = _dry_run_train_commands("experiments-table3")
    assert len(commands) == 4
    assert all("ppo.compile_loss=false" in command for command in commands)


@pytest.mark.parametrize("method", ["pretrained", "reuse"])
def test_the_methods_start_from_tables_4_and_5s_b_by_default(compose_train, method):
    """Not make train's agent: it starts weaker on fast destinations (docs/results/baseline.md)."""
    assert compose_train(f"method={method}").method.baseline == "baseline-two-stage"


def test_make_train_fast_checks_its_arguments_first():
    dry_run = _dry_run("train-fast", "ARGS=task=uniform")
    assert "changes the task, method, experiment or networks" in dry_run
    assert dry_run.index("changes the task") < dry_run.index("-m agrl.train")
