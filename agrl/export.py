"""``python -m agrl.export SOURCE [SOURCE ...] DESTINATION [--format checkpoint|onnx|torch_export]``: ship a
trained agent.

The format follows DESTINATION's suffix (``.onnx``, ``.pt2``, else ``checkpoint``) unless ``--format`` is given;
an existing DESTINATION is replaced only with ``--force``.

- ``checkpoint``: a slim checkpoint (actor, critic, resolved config and counters; no
  optimiser, RNG or collector state), e.g. to ship a baseline usable as ``method.baseline=<file>``;
  ``--evaluation eval.json`` embeds an evaluation summary. Several sources: one agent whose weights are
  their average (:func:`agrl.rl.checkpoint.average_agents`, for the seeds of one fine-tune);
- ``onnx``: the deterministic policy from the raw state (:class:`agrl.guide.GuidePolicy`: the observation
  function, the actor's network and the argmax) as an ONNX graph, for onnxruntime or any ONNX runtime;
- ``torch_export``: the same graph as a ``torch.export`` archive (``.pt2``).

Both graphs take ``aircraft_state`` ``(N, 7)`` float32, ``destination_state`` ``(N, 4)`` float32 and
``last_action`` ``(N,)`` int64 (any N) and return ``maneuver`` ``(N,)`` int64; an agent holding targets
(``actions=targets``) takes ``held_targets`` ``(N, 3)`` float32 instead of ``last_action`` and returns ``action``
``(N,)`` int64. The airspace, limits and action set they were trained with are stored beside them as JSON
metadata. ``agrl.guide.Guide.load``
reads all three formats.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import torch

from agrl.cli import run_command
from agrl.rl.checkpoint import CheckpointError, average_agents, export_agent

FORMATS = ("checkpoint", "onnx", "torch_export")
SUFFIXES = {"onnx": ".onnx", "torch_export": ".pt2"}


def _dynamic_batch():
    batch = torch.export.Dim("batch", min=1)
    return ({0: batch}, {0: batch}, {0: batch})


def export_torch(source: str | Path, destination: str | Path) -> Path:
    """Write ``source``'s policy (a shipped agent's name, a checkpoint or a run directory) as a ``torch.export``
    ``.pt2``."""
    from agrl.guide import example_inputs, export_metadata, load_policy

    policy, _, checkpoint = load_policy(source)
    program = torch.export.export(policy, example_inputs(holds_targets=policy.actions.holds_targets),
                                  dynamic_shapes=_dynamic_batch())
    destination = Path(destination)
    destination.parent.mkdir(parents=True, exist_ok=True)
    torch.export.save(program, str(destination), extra_files=export_metadata(policy, checkpoint))
    return destination


def export_onnx(source: str | Path, destination: str | Path) -> Path:
    """Write ``source``'s policy as an ONNX model (needs onnx and onnxscript: ``pip install 'agrl[export]'``)."""
    import logging
    import warnings

    try:
        import onnx
    except ImportError:
        raise CheckpointError("format=onnx needs the onnx package (pip install 'agrl[export]')") from None
    from agrl.guide import example_inputs, export_metadata, io_names, load_policy

    policy, _, checkpoint = load_policy(source)
    input_names, output_name = io_names(policy)
    destination = Path(destination)
    destination.parent.mkdir(parents=True, exist_ok=True)
    logging.getLogger("torch.onnx").setLevel(logging.ERROR)  # "torchvision is not installed" notes
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the exporter's own deprecation notes about its internals
        program = torch.onnx.export(policy, example_inputs(holds_targets=policy.actions.holds_targets), dynamo=True,
                                    dynamic_shapes=_dynamic_batch(), input_names=list(input_names),
                                    output_names=[output_name], verbose=False)
    model = program.model_proto
    for key, value in export_metadata(policy, checkpoint).items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.save(model, str(destination))
    return destination


def _format_of(destination: str) -> str:
    """The format a destination's suffix names (``.onnx``, ``.pt2``), else ``checkpoint``."""
    suffix = Path(destination).suffix
    return next((name for name, known in SUFFIXES.items() if known == suffix), "checkpoint")


def _read_evaluation(path: str) -> dict:
    try:
        with open(path) as file:
            evaluation = json.load(file)
    except (OSError, json.JSONDecodeError) as error:
        raise CheckpointError(f"--evaluation={path}: not a readable eval.json ({error})") from None
    if not isinstance(evaluation, dict):
        raise CheckpointError(f"--evaluation={path}: not an evaluation summary (a JSON object, as eval.json)")
    return evaluation


def main(argv: list[str] | None = None) -> int:
    summary = " ".join(__doc__.split("\n\n")[0].split())  # the docstring's first paragraph
    parser = argparse.ArgumentParser(prog="python -m agrl.export", description=summary)
    parser.add_argument("sources", nargs="+", metavar="source",
                        help="a checkpoint file, a run directory or a shipped agent (python -m agrl.baselines); "
                             "several (format checkpoint): one agent with their averaged weights")
    parser.add_argument("destination", help="where to write the export (.onnx for onnx, .pt2 for torch_export)")
    parser.add_argument("--format", choices=FORMATS, default=None,
                        help="checkpoint (a slim checkpoint), onnx or torch_export; default: onnx for a .onnx "
                             "destination, torch_export for .pt2, else checkpoint")
    parser.add_argument("--evaluation", help="an eval.json to embed (format=checkpoint: its summary travels with "
                                             "the agent)")
    parser.add_argument("--force", action="store_true", help="replace the destination if it exists")
    args = parser.parse_args(argv)
    inferred = _format_of(args.destination)
    args.format = args.format or inferred
    if args.format != inferred:
        expected = SUFFIXES.get(args.format)
        writes = f"a {expected} file" if expected else f"a checkpoint, not a {Path(args.destination).suffix} file"
        parser.error(f"destination={args.destination!r} is not allowed: format={args.format} writes {writes}")
    if Path(args.destination).exists() and not args.force:
        parser.error(f"destination={args.destination!r} is not allowed: it exists (a run's checkpoint, say); give "
                     "--force to replace it, or another path")
    if args.evaluation and args.format != "checkpoint":
        parser.error(f"--evaluation={args.evaluation!r} is not allowed: only with --format checkpoint")
    if len(args.sources) > 1 and args.format != "checkpoint":
        parser.error(f"{len(args.sources)} sources are not allowed with --format {args.format}: average them into a "
                     "checkpoint first (--format checkpoint), then export that")
    source = args.sources[0]
    try:
        if args.format == "onnx":
            path = export_onnx(source, args.destination)
        elif args.format == "torch_export":
            path = export_torch(source, args.destination)
        else:
            extra = {"evaluation": _read_evaluation(args.evaluation)} if args.evaluation else {}
            if len(args.sources) > 1:
                path = average_agents(args.sources, args.destination, **extra)
            else:
                path = export_agent(source, args.destination, **extra)
    except (CheckpointError, OSError) as error:
        print(f"agrl.export: error: {error}", file=sys.stderr)
        return 2
    print(path)
    return 0


if __name__ == "__main__":
    run_command(main)
