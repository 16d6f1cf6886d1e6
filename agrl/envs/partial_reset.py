"""New episodes written into some rows of a batch, as a collector's partial reset needs
(:meth:`agrl.envs.GuidanceEnv.maybe_reset`): the fields that start at zero, and the rows' out-of-place writes."""

from __future__ import annotations

import torch
from tensordict import TensorDict, TensorDictBase

from agrl.core.reward import REWARD_PART_KEYS

#: The fields a new episode starts at zero, with their dtype and any shape after the rows: those other than the initial
#: conditions, held targets and observation (:meth:`GuidanceEnv.start_fields`). The partial reset zeroes them in the
#: rows it restarts (:meth:`GuidanceEnv.maybe_reset`), as TorchRL pads a field the new rows lack.
ZERO_AT_START: dict[str, tuple] = {
    "last_action": (torch.int64,),
    "action_before_last": (torch.int64,),
    "step_count": (torch.int64,),
    "episode_return": (torch.float32,),
    "instruction_count": (torch.int64,),
    "outcome": (torch.int64,),  # Outcome.RUNNING, which is 0
    "done": (torch.bool, 1),
    "terminated": (torch.bool, 1),
    **{key: (torch.float32,) for key in REWARD_PART_KEYS},
}


def put_rows(state: TensorDictBase, new: TensorDictBase | None, rows: torch.Tensor) -> None:
    """Every field of ``state`` with its ``rows`` (indices) replaced by ``new``'s fields, each a new tensor (the
    old ones may be a step's stored ``next`` entries): a field ``new`` (or ``new is None``) lacks is zeroed in
    those rows, a field only ``new`` has is added, zero in the other rows (TorchRL's padding in a partial reset)."""
    index = (rows,)
    for key, value in list(state.items()):
        other = None if new is None else new._get_str(key, None)
        if isinstance(value, TensorDictBase):
            put_rows(value, other, rows)
            continue
        if other is None:
            other = torch.zeros((), dtype=value.dtype, device=value.device)
        state._set_str(key, value.index_put(index, other), inplace=False, validated=True, non_blocking=False)
    for key in () if new is None else new.keys():
        if key in state.keys():
            continue
        value = new._get_str(key, None)
        if isinstance(value, TensorDictBase):
            nested = TensorDict({}, batch_size=state.batch_size, device=state.device)
            put_rows(nested, value, rows)
            state.set(key, nested)
            continue
        state.set(key, value.new_zeros((*state.batch_size, *value.shape[1:])).index_put(index, value))
