"""TorchRL pieces: actor-critic models, checkpoints, evaluation, the policy-reuse transform, the trainer."""
