"""``python -m agrl.baselines``: the shipped agents, one row each: name, file, evaluations, what it is."""

from __future__ import annotations

from agrl.baselines import SHIPPED_AGENTS


def evaluation_summary(evaluation: dict) -> str:
    """``"99.83 % at 6.86 instructions (fixed, 10000 episodes, seed 777)"``."""
    task = evaluation["task"] + "".join(f" {key}={evaluation[key]:g}" for key in ("speed", "radius")
                                        if evaluation.get(key) is not None)
    return (f"{100 * evaluation['success_rate']:.2f} % at {evaluation['instructions_per_episode']:.2f} instructions "
            f"({task}, {evaluation['episodes']} episodes, seed {evaluation['seed']})")


def main() -> None:
    for agent in SHIPPED_AGENTS.values():
        print(f"{agent.name}: agrl/baselines/{agent.filename}")
        print(f"  {agent.description}")
        for evaluation in agent.evaluations():
            print(f"  evaluated: {evaluation_summary(evaluation)}")
        for command in agent.made_by:
            print(f"  made by: {command}")


if __name__ == "__main__":
    main()
