"""The agents shipped with agrl, by name (``checkpoint=baseline``, ``method.baseline=baseline-stage1``, ...).

:data:`SHIPPED_AGENTS` is the one list of them: each name's file (a slim checkpoint in this folder), what the agent
is, the commands that made it, and its evaluation record (``<file>.evaluations.json`` beside it: the summary of each
evaluation on episodes no training used). :func:`agrl.rl.checkpoint.resolve_checkpoint_path` turns a name into its
file, so every command and function that takes a checkpoint takes these names. ``python -m agrl.baselines`` prints
the list. How each was trained and how it flies the moving destinations: docs/results/baseline.md.

No torch here: the command-line checks read this list before anything heavy is imported.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

FOLDER = Path(__file__).parent


@dataclass(frozen=True)
class ShippedAgent:
    """One shipped agent: its name on the command line, its file in this folder, what it is and how it was made."""

    name: str
    filename: str
    description: str
    #: The commands that made it, in order. Agents other than ``baseline`` were trained by the code of their day,
    #: so these give an agent of the same recipe, not the same bytes (tests/baselines/test_make_train_recipe.py
    #: checks that ``make train`` and ``make train-two-stage`` still compose the recipes of ``baseline``,
    #: ``baseline-two-stage`` and ``baseline-stage1`` exactly).
    made_by: tuple[str, ...]

    @property
    def file(self) -> Path:
        return FOLDER / self.filename

    @property
    def evaluations_file(self) -> Path:
        return self.file.with_suffix(".evaluations.json")

    def evaluations(self) -> list[dict]:
        """Its evaluation record: one summary per evaluation (task, episodes, seed, success, instructions, ...)."""
        return json.loads(self.evaluations_file.read_text())["evaluations"]


SHIPPED_AGENTS: dict[str, ShippedAgent] = {agent.name: agent for agent in (
    ShippedAgent(
        "baseline", "fixed_baseline.pt",
        "the shipped fixed-destination agent (Guide, evaluate and plan by default): make train, one run of 2 x 64 "
        "networks with a switch-cost schedule (0.104 per instruction until 99.8 % success, then 60 iterations at "
        "0.449), the three-seed recipe search's best (docs/results/baseline.md)",
        ("make train",
         "python -m agrl.export <run>/checkpoints/latest.pt fixed_baseline.pt --evaluation <run>/eval/eval.json"),
    ),
    ShippedAgent(
        "baseline-first-search", "fixed_baseline_first_search.pt",
        "the shipped baseline of 2026-12-06 before this one: make train's recipe then, the best trial of a "
        "one-seed recipe search (0.175 per instruction until 99.5 % success, then 60 iterations at 0.38); as "
        "method=reuse's B at 20 m/s it needs method.selection_decay=1e-4 (docs/results/baseline.md)",
        ("python -m agrl.train +experiment=switch_schedule ppo.learning_rate=1.83e-3 reward.switch_cost=0.175 "
         "target_success=0.995 finetune.switch_cost=0.38 finetune.learning_rate=1.4e-3",
         "python -m agrl.export <run>/checkpoints/latest.pt fixed_baseline_first_search.pt "
         "--evaluation <run>/eval/eval.json"),
    ),
    ShippedAgent(
        "baseline-two-stage", "fixed_baseline_two_stage.pt",
        "the baseline B that method=pretrained and method=reuse start from by default, Tables 4-5's, and the shipped "
        "baseline until 2026-12-06: make train-two-stage (the position shaping term and a switch cost of 0.1, then "
        "a fine-tune at 0.3; 2 x 128 networks)",
        ("make train-two-stage",
         "python -m agrl.export <run>/stage2/checkpoints/latest.pt fixed_baseline_two_stage.pt "
         "--evaluation <run>/stage2/eval/eval.json"),
    ),
    ShippedAgent(
        "baseline-stage1", "fixed_baseline_stage1.pt",
        "make train-two-stage's stage 1 alone (python -m agrl.train's defaults with the eager loss, seed 0): about 10 "
        "instructions per episode; Table 3's fine-tuned row (make experiments-table3) starts from it",
        ("python -m agrl.train seed=0 ppo.compile_loss=false",
         "python -m agrl.export <run>/checkpoints/latest.pt fixed_baseline_stage1.pt "
         "--evaluation <run>/eval/eval.json"),
    ),
    ShippedAgent(
        "baseline-both-terms", "fixed_baseline_both_terms.pt",
        "one stage with both of the paper's shaping terms (position and continuous action) and a switch cost of "
        "0.1, the shipped baseline before make train had two stages; baseline-absolute is distilled from it",
        ("python -m agrl.train reward.use_continuous_action=true ppo.total_frames=4000000 ppo.max_minutes=0 seed=0 "
         "ppo.compile_loss=false",
         "python -m agrl.export <run>/checkpoints/latest.pt fixed_baseline_both_terms.pt "
         "--evaluation <run>/eval/eval.json"),
    ),
    ShippedAgent(
        "baseline-targets", "fixed_baseline_targets.pt",
        "the fixed-destination baseline with target-holding actions (actions=targets: heading, altitude and speed "
        "clearances an autopilot flies): make train-targets' two stages, seed 0; method=pretrained starts from it "
        "for actions=targets",
        ("make train-targets",
         "python -m agrl.export <run>/stage2/checkpoints/latest.pt fixed_baseline_targets.pt "
         "--evaluation <run>/stage2/eval/eval.json"),
    ),
    ShippedAgent(
        "baseline-absolute", "fixed_baseline_absolute.pt",
        "baseline-both-terms distilled onto the paper's absolute observation (equation 4), for runs with "
        "agent.observation=absolute (PPO from scratch learns the fixed destination far more slowly on it)",
        ("python -m agrl.distill baseline-both-terms fixed_baseline_absolute.pt --observation absolute",),
    ),
)}

#: The file of ``checkpoint=baseline``.
BASELINE_FILE = SHIPPED_AGENTS["baseline"].file


def shipped_agent_names() -> str:
    """The names, comma-separated, for the one-line errors that list what is allowed."""
    return ", ".join(SHIPPED_AGENTS)
