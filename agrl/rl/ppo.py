"""The PPO pieces: TorchRL's ``ClipPPOLoss`` and ``GAE``, and the epochs-over-minibatches update."""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Iterator

import torch
from tensordict import TensorDictBase
from torchrl.objectives import ClipPPOLoss
from torchrl.objectives.value import GAE

from agrl.core.compiled import EagerFallback, keep_kernels_per_instruction_set

#: Loss outputs averaged over an iteration's updates and logged as ``loss/<name>``.
LOGGED_LOSS_TERMS = ("loss_objective", "loss_critic", "loss_entropy", "entropy", "kl_approx", "clip_fraction",
                     "explained_variance")


class TrainingDiverged(RuntimeError):
    """A loss or gradient became NaN or infinite; the last good checkpoint is kept."""


def make_advantage(gamma: float, gae_lambda: float, critic, device: torch.device) -> GAE:
    """GAE with the critic as value network (``critic=None``: values are supplied with the data).

    The critic runs once over a batch's observations and the one after its last (TorchRL's ``shifted=True``),
    instead of over every observation and again over every successor: the same advantages and value targets (to
    float rounding: the matrix products have other shapes) in about 0.4 x the time at the defaults' 512 x 64
    (``benchmarks.profile_iteration``; ``tests/rl/test_ppo.py`` checks them against the two passes). The value after
    an episode's end is not the critic's then, but GAE does not read it: every end of agrl's env terminates. The
    batch's last dimension must be its time.
    """
    return GAE(gamma=gamma, lmbda=gae_lambda, value_network=critic, average_gae=False, device=device, shifted=True)


class AnalyticEntropyPPOLoss(ClipPPOLoss):
    """TorchRL's ``ClipPPOLoss`` whose entropy bonus is the categorical's analytic entropy, compiled or not.

    Under ``torch.compile`` TorchRL cannot test the analytic entropy for finiteness without a graph break, so it also
    draws a Monte-Carlo estimate every minibatch (one sampled action per row) and keeps it where the analytic one is
    not finite. A categorical's entropy is finite wherever its logits are (torch clamps them), so the draw only costs
    time and moves torch's generator: about 5 % of a compiled iteration at the defaults' 512 x 64 (0.90 against
    0.85 x the plain-PyTorch floor's speed in ``benchmarks.bench_peer``: docs/benchmarks.md, "What each design
    choice buys"). Eagerly both compute the same entropy. A duplicate of TorchRL's ``_get_entropy`` for
    ``torch.distributions.Categorical``; other distributions go to TorchRL's.
    """

    def _get_entropy(self, dist, adv_shape):
        if type(dist) is torch.distributions.Categorical:
            return dist.entropy().unsqueeze(-1)
        return super()._get_entropy(dist, adv_shape)


def make_loss(actor, critic, clip_epsilon: float, entropy_coeff: float, critic_coeff: float,
              compiled_entropy_draw: bool = False) -> ClipPPOLoss:
    """The PPO loss; ``compiled_entropy_draw``: TorchRL's own, whose compiled form draws a Monte-Carlo entropy
    estimate it does not use (``ppo.compiled_entropy_draw``: runs compiled before the draw was dropped repeat with
    it), else :class:`AnalyticEntropyPPOLoss`."""
    # functional=False: the loss calls the actor and critic as they are. Functionalised parameters (the default)
    # are for meta-RL and cost a parameter swap on every minibatch, a noticeable share of an update here.
    loss_class = ClipPPOLoss if compiled_entropy_draw else AnalyticEntropyPPOLoss
    return loss_class(actor, critic, clip_epsilon=clip_epsilon, entropy_coeff=entropy_coeff,
                      critic_coeff=critic_coeff, normalize_advantage=True, loss_critic_type="smooth_l1",
                      functional=False)


class CompiledLoss(torch.nn.Module):
    """``loss`` with its forward and backward fused by ``torch.compile`` (``ppo.compile_loss``), together with what the
    update reads of it (:func:`scored`: the total it minimises and the logged terms).

    The same function as ``loss`` (to float rounding; ``tests/rl/test_ppo.py``). A minibatch of 512 rows is a
    few dozen small kernels and TensorDict bookkeeping in eager mode; compiled, the update is shorter in
    ``python -m benchmarks.bench_peer``, for a compilation on the first minibatch (kept between runs by torch's
    compile cache, one folder per instruction set: :func:`agrl.core.compiled.keep_kernels_per_instruction_set`).
    The default (``ppo.compile_loss=true``); the results pages' older runs used ``loss`` itself.
    If compilation fails (no C++ compiler, an unsupported platform) it warns once and stays eager.
    """

    def __init__(self, loss: ClipPPOLoss):
        super().__init__()
        self.loss = loss
        keep_kernels_per_instruction_set()  # torch's cache would mix kernels of two instruction sets
        scored_loss = ScoredLoss(loss)
        self._scored = EagerFallback(torch.compile(scored_loss), scored_loss, "the PPO loss")

    def forward(self, batch: TensorDictBase) -> TensorDictBase:
        return self.scored(batch)[0]

    def scored(self, batch: TensorDictBase) -> tuple[TensorDictBase, torch.Tensor, torch.Tensor]:
        """:func:`scored` of the loss, compiled."""
        return self._scored(batch)

    @property
    def compiled(self) -> bool:
        return self._scored.compiled


class ScoredLoss(torch.nn.Module):
    """:func:`scored` of ``loss`` as a module: what :class:`CompiledLoss` compiles."""

    def __init__(self, loss: torch.nn.Module):
        super().__init__()
        self.loss = loss

    def forward(self, batch: TensorDictBase) -> tuple[TensorDictBase, torch.Tensor, torch.Tensor]:
        return scored(self.loss, batch)


def total_loss(losses: TensorDictBase) -> torch.Tensor:
    """What the update minimises: the clipped objective plus the critic's and the entropy's terms."""
    return losses["loss_objective"] + losses["loss_critic"] + losses["loss_entropy"]


def logged_terms(losses: TensorDictBase) -> list[str]:
    """The :data:`LOGGED_LOSS_TERMS` among ``losses``, in that order."""
    return [key for key in LOGGED_LOSS_TERMS if key in losses.keys()]


def scored(loss: torch.nn.Module, batch: TensorDictBase) -> tuple[TensorDictBase, torch.Tensor, torch.Tensor]:
    """``loss``'s terms on ``batch``, their :func:`total_loss`, and its :func:`logged_terms` detached and stacked as
    float64 (TorchRL's terms are float32 scalars, taken as they are; another shape is averaged first).

    One function, so that :class:`CompiledLoss` fuses the sum and the stack into the loss's graph instead of running
    them as a dozen small eager operations after it, every minibatch (docs/benchmarks.md, "What each design choice
    buys"). The same numbers either way: a sum and a stack round alike in both (``tests/rl/test_ppo.py``)."""
    losses = loss(batch)
    terms = [losses[key].detach() for key in logged_terms(losses)]
    terms = torch.stack([term if term.dim() == 0 and term.dtype == torch.float32 else term.float().mean()
                         for term in terms]).double()
    return losses, total_loss(losses), terms


def make_optimizer(loss: ClipPPOLoss, learning_rate: float) -> torch.optim.Adam:
    """Adam over the actor's and critic's parameters; the fused kernel (CPU and CUDA) does one pass per step."""
    return torch.optim.Adam(loss.parameters(), lr=learning_rate, eps=1e-5, fused=True)


def update_fields(loss: ClipPPOLoss) -> list:
    """The fields of a collected row that the PPO update reads (the rest stays out of the replay buffer:
    each pass over the rows gathers every stored field, so fewer fields make it cheaper)."""
    keys = loss.tensor_keys
    fields = [*loss.actor_network.in_keys, *loss.critic_network.in_keys, keys.action, keys.sample_log_prob,
              keys.advantage, keys.value_target, keys.value]
    return list(dict.fromkeys(fields))


def minibatches(rows: TensorDictBase, size: int) -> Iterator[TensorDictBase]:
    """Pass after pass over ``rows``, each in a new random order, as contiguous slices of one permuted copy.

    The minibatches TorchRL's ``SamplerWithoutReplacement`` draws from a replay buffer holding ``rows``, in the same
    order and drawn from the default generator at the same moments (a pass's order when the update starts, the next
    one's as the last minibatch of a pass is handed out; the last minibatch of a pass is smaller), so a run's numbers
    are those of the buffer-sampled update; but each field is gathered once per pass instead of once per minibatch.
    """
    count = rows.shape[0]
    order = torch.randperm(count, device=rows.device)
    while True:
        shuffled = rows[order]
        for start in range(0, count, size):
            if start + size >= count:
                order = torch.randperm(count, device=rows.device)
            yield shuffled[start:start + size]


def ppo_update(
    loss: ClipPPOLoss,
    optimizer: torch.optim.Optimizer,
    rows: TensorDictBase,
    minibatch_size: int,
    epochs: int,
    max_grad_norm: float,
    where: str,
    max_updates: int | None = None,
    target_kl: float = 0.0,
) -> dict[str, float]:
    """``epochs`` passes over the flat ``rows`` in minibatches (:func:`minibatches`), stopping after
    ``max_updates`` minibatches if given, or before the first minibatch whose approximate KL from the collecting
    policy exceeds ``1.5 * target_kl`` if ``target_kl`` > 0 (stable-baselines3's rule, on the loss's own
    ``kl_approx``: the mean of the stored minus the current log-probability of the minibatch's actions); the mean of
    each logged loss term, and ``minibatches``: the optimiser steps taken.

    Raises :class:`TrainingDiverged` (naming ``where`` and the update) on a non-finite loss or gradient,
    before the optimiser step, so the parameters stay finite.
    """
    logged: list[str] = []
    sums: torch.Tensor | None = None  # float64 sums of the logged terms, in ``logged``'s order
    updates = 0
    parameters = list(loss.parameters())  # once: loss.parameters() walks every submodule of actor and critic
    kl_limit = 1.5 * target_kl if target_kl > 0 else None
    planned = epochs * math.ceil(rows.shape[0] / minibatch_size)
    if max_updates is not None:
        planned = min(planned, max_updates)
    score = loss.scored if isinstance(loss, CompiledLoss) else functools.partial(scored, loss)
    for batch in itertools.islice(minibatches(rows, minibatch_size), planned):
        losses, total, terms = score(batch)
        if kl_limit is not None and float(losses["kl_approx"]) > kl_limit:
            break  # the policy has moved far enough from the one that collected (or relabelled) the rows
        if not torch.isfinite(total):
            raise TrainingDiverged(f"non-finite loss ({total.item()}) {where}, update {updates + 1}")
        optimizer.zero_grad(set_to_none=True)
        total.backward()
        gradient_norm = torch.nn.utils.clip_grad_norm_(parameters, max_grad_norm)
        if not torch.isfinite(gradient_norm):
            raise TrainingDiverged(f"non-finite gradient {where}, update {updates + 1}")
        optimizer.step()
        updates += 1
        if sums is None:
            logged = logged_terms(losses)
        sums = terms if sums is None else sums + terms  # one tensor, read once per update
    means = {} if sums is None else dict(zip(logged, (sums / updates).tolist(), strict=True))
    return {**means, "minibatches": float(updates)}


def annealed_learning_rate(initial: float, frames: int, total_frames: int) -> float:
    """Linear decay from ``initial`` to 0 over the frame budget (``ppo.anneal_lr``)."""
    return initial * max(0.0, 1.0 - frames / total_frames)


@torch.no_grad()
def clip_fraction_by_source(actor, data: TensorDictBase, clip_epsilon: float) -> dict[str, float]:
    """Fraction of rows whose probability ratio is outside the clip range, for own and relabelled rows."""
    if "relabelled" not in data.keys():
        return {}
    ratio = (actor.get_dist(data).log_prob(data["action"]) - data["action_log_prob"]).exp()
    clipped = (ratio - 1).abs() > clip_epsilon
    relabelled = data["relabelled"]
    return {
        f"loss/clip_fraction_{name}": float(clipped[mask].float().mean())
        for name, mask in (("own", ~relabelled), ("relabelled", relabelled))
        if bool(mask.any())
    }
