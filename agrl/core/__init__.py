"""Pure, batched torch functions: dynamics, destinations, termination, reward, observation.

Nothing here imports TorchRL or Hydra; every function takes and returns tensors
of any batch shape, so it can be tested and reused on its own.
"""
