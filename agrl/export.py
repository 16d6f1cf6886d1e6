"""``python -m agrl.export SOURCE [SOURCE ...] DESTINATION [--format checkpoint|onnx|torch_export]``: ship a
trained agent.

- ``checkpoint`` (default): a slim checkpoint (actor, critic, resolved config and counters; no
  optimiser, RNG or collector state), e.g. to ship a baseline usable as ``method.baseline=<file>``;
  ``--evaluation eval.json`` embeds an evaluation summary. Several sources: one agent whose weights are
  their average (:func:`agrl.rl.checkpoint.average_agents`, for the seeds of one fine-tune);
- ``onnx``: the deterministic policy from the raw state (:class:`agrl.guide.GuidePolicy`: the observation
  function, the actor's network and the argmax) as an ONNX graph, for onnxruntime or any ONNX runtime;
- ``torch_export``: the same graph as a ``torch.export`` archive (``.pt2``).

Both graphs take ``aircraft_state`` ``(N, 7)`` float32, ``destination_state`` ``(N, 4)`` float32 and
``last_action`` ``(N,)`` int64 (any N) and return ``maneuver`` ``(N,)`` int64; the airspace and
limits they were trained with are stored beside them as JSON metadata. ``agrl.guide.Guide.load``
reads all three formats.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import torch

from agrl.rl.checkpoint import CheckpointError, average_agents, export_agent

FORMATS = ("checkpoint", "onnx", "torch_export")
SUFFIXES = {"onnx": ".onnx", "torch_export": ".pt2"}


def _dynamic_batch():
    batch = torch.export.Dim("batch", min=1)
    return ({0: batch}, {0: batch}, {0: batch})


def export_torch(source: str | Path, destination: str | Path) -> Path:
    """Write ``source``'s policy (``baseline``, a checkpoint or a run directory) as a ``torch.export`` ``.pt2``."""
    from agrl.guide import example_inputs, export_metadata, load_policy

    policy, _, checkpoint = load_policy(source)
    program = torch.export.export(policy, example_inputs(), dynamic_shapes=_dynamic_batch())
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
    from agrl.guide import INPUT_NAMES, OUTPUT_NAME, example_inputs, export_metadata, load_policy

    policy, _, checkpoint = load_policy(source)
    destination = Path(destination)
    destination.parent.mkdir(parents=True, exist_ok=True)
    logging.getLogger("torch.onnx").setLevel(logging.ERROR)  # "torchvision is not installed" notes
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the exporter's own deprecation notes about its internals
        program = torch.onnx.export(policy, example_inputs(), dynamo=True, dynamic_shapes=_dynamic_batch(),
                                    input_names=list(INPUT_NAMES), output_names=[OUTPUT_NAME], verbose=False)
    model = program.model_proto
    for key, value in export_metadata(policy, checkpoint).items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.save(model, str(destination))
    return destination


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m agrl.export", description=__doc__.splitlines()[0])
    parser.add_argument("sources", nargs="+", metavar="source",
                        help="a checkpoint file, a run directory or 'baseline'; several (format checkpoint): one agent "
                             "with their averaged weights")
    parser.add_argument("destination", help="where to write the export (.onnx for onnx, .pt2 for torch_export)")
    parser.add_argument("--format", choices=FORMATS, default="checkpoint",
                        help="checkpoint (slim checkpoint, default), onnx or torch_export")
    parser.add_argument("--evaluation", help="an eval.json to embed (format=checkpoint: its summary travels with "
                                             "the agent)")
    args = parser.parse_args(argv)
    suffix = SUFFIXES.get(args.format)
    if suffix and Path(args.destination).suffix != suffix:
        parser.error(f"destination={args.destination!r} is not allowed: format={args.format} writes a {suffix} file")
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
            extra = {}
            if args.evaluation:
                with open(args.evaluation) as file:
                    extra["evaluation"] = json.load(file)
            if len(args.sources) > 1:
                path = average_agents(args.sources, args.destination, **extra)
            else:
                path = export_agent(source, args.destination, **extra)
    except (CheckpointError, OSError, json.JSONDecodeError) as error:
        print(f"agrl.export: error: {error}", file=sys.stderr)
        return 2
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
