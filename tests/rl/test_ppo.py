"""PPO pieces: the learning-rate schedule, the compiled loss, the update's minibatches and its caps (agrl.rl.ppo)."""

from __future__ import annotations

import itertools

import pytest
import torch

from agrl.rl.ppo import LOGGED_LOSS_TERMS, CompiledLoss, annealed_learning_rate, logged_terms, total_loss
from agrl.rl.trainer import Trainer

pytestmark = pytest.mark.usefixtures("torch_one_thread")


def test_annealed_learning_rate_is_linear_to_zero():
    assert annealed_learning_rate(5e-4, 0, 1_000) == 5e-4
    assert annealed_learning_rate(5e-4, 250, 1_000) == pytest.approx(3.75e-4)
    assert annealed_learning_rate(5e-4, 1_000, 1_000) == 0.0
    assert annealed_learning_rate(5e-4, 1_500, 1_000) == 0.0  # a resumed run past its budget


@pytest.mark.parametrize("anneal", [True, False])
def test_trainer_applies_the_schedule_each_iteration(tmp_path, compose_train, tiny_args, anneal):
    # Two iterations of 512 decisions with a 1024-decision budget: the second one runs at half the rate.
    config = compose_train(*tiny_args({"ppo.total_frames": 1024, "ppo.anneal_lr": str(anneal).lower(),
                                       "ppo.learning_rate": 3e-4, "eval.episodes": 4}))
    trainer = Trainer(config, tmp_path / "run")
    trainer.train()
    assert trainer.counters.iteration == 2
    assert trainer.optimizer.param_groups[0]["lr"] == pytest.approx(1.5e-4 if anneal else 3e-4)


def _loss_and_batch(rows: int = 512, compiled_entropy_draw: bool = False):
    """A fresh loss over 2 x 128 networks and one minibatch with the fields the update reads."""
    from tensordict import TensorDict

    from agrl.core.observation import observation_size
    from agrl.rl.models import make_actor, make_critic
    from agrl.rl.ppo import make_loss

    torch.manual_seed(0)
    actor, critic = make_actor([128, 128], "tanh"), make_critic([128, 128], "tanh")
    batch = TensorDict({"observation": torch.randn(rows, observation_size("relative"))}, [rows])
    with torch.no_grad():
        actor(batch)
        critic(batch)
    batch["advantage"] = torch.randn(rows, 1)
    batch["value_target"] = batch["state_value"] + torch.randn(rows, 1)
    # Move the networks off the behaviour policy, so that the ratio and the clipping are exercised.
    with torch.no_grad():
        for parameter in actor.parameters():
            parameter.add_(0.05 * torch.randn_like(parameter))
    return make_loss(actor, critic, clip_epsilon=0.2, entropy_coeff=0.01, critic_coeff=0.5,
                     compiled_entropy_draw=compiled_entropy_draw), batch


def _terms_and_gradients(loss_module, loss_parameters, batch):
    losses = loss_module(batch)
    gradients = torch.autograd.grad(total_loss(losses), loss_parameters)
    return {key: losses[key].detach() for key in LOGGED_LOSS_TERMS if key in losses.keys()}, gradients


def test_compiled_loss_computes_the_eager_loss_and_gradients():
    loss, batch = _loss_and_batch()
    parameters = list(loss.parameters())
    eager_terms, eager_gradients = _terms_and_gradients(loss, parameters, batch)
    compiled = CompiledLoss(loss)
    compiled_terms, compiled_gradients = _terms_and_gradients(compiled, parameters, batch)
    assert compiled.compiled  # no fallback: the comparison is between the two paths
    assert eager_terms["clip_fraction"] > 0
    assert eager_terms.keys() == compiled_terms.keys()
    for key, value in eager_terms.items():
        torch.testing.assert_close(compiled_terms[key], value, rtol=1e-4, atol=1e-6, msg=key)
    for eager, fused in zip(eager_gradients, compiled_gradients, strict=True):
        torch.testing.assert_close(fused, eager, rtol=1e-4, atol=1e-6)


def test_the_compiled_total_and_logged_terms_are_those_taken_after_the_loss_compiled_alone():
    """:class:`CompiledLoss` fuses the total and the logged terms' stack into the loss's graph: the same terms, total,
    logged values and gradients, bit for bit, as the sum and stack taken after the loss compiled alone, so fusing them
    changes no number of a run."""
    loss, batch = _loss_and_batch()
    parameters = list(loss.parameters())
    alone = torch.compile(loss)(batch)
    after_total = total_loss(alone)
    after_terms = torch.stack([alone[key].detach().float().mean() for key in logged_terms(alone)]).double()
    after_gradients = torch.autograd.grad(after_total, parameters)
    compiled = CompiledLoss(loss)
    losses, total, terms = compiled.scored(batch)
    assert compiled.compiled
    assert logged_terms(losses) == logged_terms(alone) and "explained_variance" in logged_terms(losses)
    for key in logged_terms(losses):
        assert torch.equal(losses[key], alone[key]), key
    assert torch.equal(total, after_total) and torch.equal(terms, after_terms)
    for fused, after in zip(torch.autograd.grad(total, parameters), after_gradients, strict=True):
        assert torch.equal(fused, after)


def test_the_analytic_entropy_loss_is_torchrls_loss_when_eager():
    """``ppo.compiled_entropy_draw=false`` changes nothing in an eager update: the same terms and gradients, bit for
    bit, as TorchRL's ``ClipPPOLoss``, whose eager entropy is the analytic one too."""
    analytic, batch = _loss_and_batch()
    torchrls, _ = _loss_and_batch(compiled_entropy_draw=True)
    assert type(analytic) is not type(torchrls)
    analytic_terms, analytic_gradients = _terms_and_gradients(analytic, list(analytic.parameters()), batch)
    torchrl_terms, torchrl_gradients = _terms_and_gradients(torchrls, list(torchrls.parameters()), batch)
    assert analytic_terms.keys() == torchrl_terms.keys() and "entropy" in analytic_terms
    for key, value in analytic_terms.items():
        assert torch.equal(value, torchrl_terms[key]), key
    for analytic_gradient, torchrl_gradient in zip(analytic_gradients, torchrl_gradients, strict=True):
        assert torch.equal(analytic_gradient, torchrl_gradient)


@pytest.mark.parametrize("compiled_entropy_draw", [False, True])
def test_the_compiled_loss_draws_from_torchs_generator_only_with_the_entropy_draw(compiled_entropy_draw):
    """TorchRL's compiled loss samples a Monte-Carlo entropy estimate every call, moving the default generator (so
    the update's minibatch orders); without the draw a compiled call leaves the generator where it was."""
    loss, batch = _loss_and_batch(compiled_entropy_draw=compiled_entropy_draw)
    compiled = CompiledLoss(loss)
    compiled(batch)  # compiles
    assert compiled.compiled
    before = torch.get_rng_state()
    compiled(batch)
    assert torch.equal(torch.get_rng_state(), before) is not compiled_entropy_draw


@pytest.mark.parametrize("draw", [False, True])
def test_the_trainer_builds_the_loss_its_config_names(tmp_path, compose_train, tiny_args, draw):
    """``ppo.compiled_entropy_draw`` reaches the trainer's loss: TorchRL's own with the draw (``make train``'s recipe,
    which its shipped agent needs), agrl's analytic-entropy loss without (the default)."""
    from torchrl.objectives import ClipPPOLoss

    from agrl.rl.ppo import AnalyticEntropyPPOLoss

    config = compose_train(*tiny_args({"ppo.compiled_entropy_draw": str(draw).lower()}))
    trainer = Trainer(config, tmp_path / "run")
    assert type(trainer.loss) is (ClipPPOLoss if draw else AnalyticEntropyPPOLoss)
    trainer.collector.shutdown()


def test_compiled_loss_falls_back_to_the_eager_loss_when_compilation_fails(monkeypatch):
    def failing_compile(module, *args, **kwargs):
        def compiled(*call_args, **call_kwargs):
            raise RuntimeError("no C++ compiler")
        return compiled

    loss, batch = _loss_and_batch(64)
    monkeypatch.setattr(torch, "compile", failing_compile)
    compiled = CompiledLoss(loss)
    with pytest.warns(RuntimeWarning, match="torch.compile of the PPO loss failed.*no C\\+\\+ compiler"):
        losses = compiled(batch)
    assert not compiled.compiled
    torch.testing.assert_close(losses["loss_objective"], loss(batch)["loss_objective"])


def test_trainer_updates_through_the_compiled_loss(tmp_path, compose_train, tiny_args, monkeypatch):
    """``ppo.compile_loss=true`` routes every update through :class:`CompiledLoss` around the trainer's own loss.
    torch.compile is replaced by a recorder whose "compiled" function calls the module and counts the calls: that
    the compiled loss computes the eager one is the test above; here only the wiring is, without a second
    compilation of seconds."""
    compiled_modules, calls = [], []

    def recording_compile(module, *args, **kwargs):
        compiled_modules.append(module)

        def compiled(*call_args, **call_kwargs):
            calls.append(1)
            return module(*call_args, **call_kwargs)
        return compiled

    monkeypatch.setattr(torch, "compile", recording_compile)
    config = compose_train(*tiny_args({"ppo.total_frames": 512, "ppo.compile_loss": "true", "eval.episodes": 4}))
    trainer = Trainer(config, tmp_path / "run")
    before = [parameter.detach().clone() for parameter in trainer.actor.parameters()]
    trainer.train()
    assert isinstance(trainer.update_loss, CompiledLoss) and trainer.update_loss.compiled
    (compiled_module,) = compiled_modules  # the loss with its total and logged terms (ScoredLoss)
    assert compiled_module.loss is trainer.update_loss.loss
    assert len(calls) == 4  # one iteration of 512 rows: 4 minibatches of 128, one epoch
    assert any(not torch.equal(old, new) for old, new in zip(before, trainer.actor.parameters(), strict=True))


def _adam_steps(optimizer) -> int:
    return int(next(iter(optimizer.state.values()))["step"])


def _replay_buffer_update(loss, optimizer, rows, minibatch_size: int, epochs: int, max_grad_norm: float) -> None:
    """The update as it was before :func:`agrl.rl.ppo.minibatches`: epochs of minibatches sampled from a
    TorchRL replay buffer without replacement, each one loss, backward, clip and Adam step."""
    from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
    from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement

    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(len(rows)), sampler=SamplerWithoutReplacement(),
                                    batch_size=minibatch_size)
    buffer.extend(rows)
    parameters = list(loss.parameters())
    for _ in range(epochs):
        for batch in buffer:
            optimizer.zero_grad(set_to_none=True)
            total_loss(loss(batch)).backward()
            torch.nn.utils.clip_grad_norm_(parameters, max_grad_norm)
            optimizer.step()


def test_minibatches_are_those_a_replay_buffer_samples_from_the_same_draws():
    """Same rows, same order, same sizes (a smaller last one) as TorchRL's sampler without replacement, and the
    default generator left in the same state (the sampler draws a pass's successor as it hands out its last
    minibatch), so the rest of a run draws the same numbers."""
    from tensordict import TensorDict
    from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
    from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement

    from agrl.rl.ppo import minibatches

    rows = TensorDict({"x": torch.arange(3000.0), "y": torch.randn(3000, 3)}, [3000])
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(4096), sampler=SamplerWithoutReplacement(),
                                    batch_size=512)
    buffer.extend(rows)
    torch.manual_seed(5)
    sampled = [batch.exclude("index") for _ in range(2) for batch in buffer]
    after_buffer = torch.get_rng_state()
    torch.manual_seed(5)
    sliced = list(itertools.islice(minibatches(rows, 512), 12))
    assert torch.equal(torch.get_rng_state(), after_buffer)
    assert [len(batch) for batch in sliced] == [512] * 5 + [440] + [512] * 5 + [440]
    assert len(sampled) == len(sliced)
    for old, new in zip(sampled, sliced, strict=True):
        assert (old == new).all()
    assert not torch.equal(sliced[0]["x"], sliced[6]["x"])  # each pass draws its own order


def test_ppo_update_learns_what_the_replay_buffer_update_learned():
    """The same parameters, bit for bit, after 4 epochs over fixed rows as the buffer-sampled update, and the
    same state of the default generator after it."""
    from agrl.rl.ppo import make_optimizer, ppo_update

    results, generator_states = [], []
    for update in ("buffer", "slices"):
        loss, batch = _loss_and_batch(3000)
        optimizer = make_optimizer(loss, 1e-3)
        torch.manual_seed(11)
        if update == "buffer":
            _replay_buffer_update(loss, optimizer, batch, 512, epochs=4, max_grad_norm=0.5)
        else:
            ppo_update(loss, optimizer, batch, 512, epochs=4, max_grad_norm=0.5, where="here")
        results.append([parameter.detach().clone() for parameter in loss.parameters()])
        generator_states.append(torch.get_rng_state())
    before = _loss_and_batch(3000)[0]
    assert any(not torch.equal(old, new) for old, new in zip(before.parameters(), results[0], strict=True))
    for old, new in zip(*results, strict=True):
        assert torch.equal(old, new)
    assert torch.equal(*generator_states)


@pytest.mark.parametrize(("max_updates", "expected"), [(None, 4 * 6), (10, 10), (100, 4 * 6)])
def test_ppo_update_stops_after_max_updates_minibatches(max_updates, expected):
    """6 minibatches per pass over 3 072 rows, 4 passes: ``max_updates`` cuts them short (never lengthens them)."""
    from agrl.rl.ppo import make_optimizer, ppo_update

    loss, batch = _loss_and_batch(3072)
    optimizer = make_optimizer(loss, 1e-4)
    losses = ppo_update(loss, optimizer, batch, 512, epochs=4, max_grad_norm=0.5, where="here",
                        max_updates=max_updates)
    assert _adam_steps(optimizer) == expected
    assert losses["minibatches"] == expected


@pytest.mark.parametrize(("target_kl", "expected"), [(0.0, 4 * 6), (1e-12, 1), (1e3, 4 * 6)])
def test_ppo_update_stops_before_the_first_minibatch_past_the_kl_limit(target_kl, expected):
    """The first minibatch's KL is 0 (the policy has not moved yet), so it always steps; with a tiny limit the
    second one, which sees the policy after a step, stops the whole update; a huge limit never does."""
    from agrl.rl.ppo import make_optimizer, ppo_update

    loss, batch = _loss_and_batch(3072)
    optimizer = make_optimizer(loss, 1e-3)
    losses = ppo_update(loss, optimizer, batch, 512, epochs=4, max_grad_norm=0.5, where="here", target_kl=target_kl)
    assert _adam_steps(optimizer) == expected
    assert losses["minibatches"] == expected


def test_equal_update_cost_gives_a_reuse_update_the_minibatches_of_a_plain_iteration(compose_train, tmp_path):
    """One reuse iteration of 16 x 8 decisions whose buffer holds more rows than it collected (relabelled
    episodes are longer): 3 passes over all rows by default, 3 passes' worth of one batch (3 x ceil(128 / 48))
    with the switch."""
    import math

    # A 0.3 s integration step: the relabelling's re-plays cost a fifteenth of the default 0.02 s one.
    overrides = ["method=reuse", "ppo.num_envs=16", "ppo.steps_per_env=8", "ppo.minibatch_size=48", "ppo.epochs=3",
                 "ppo.total_frames=128", "simulation.compile=false", "simulation.integration_step=0.3",
                 "eval.interval=0", "eval.episodes=4", "progress=false", "seed=3"]
    steps, rows = {}, {}
    for equal in (False, True):
        trainer = Trainer(compose_train(*overrides, f"method.equal_update_cost={str(equal).lower()}"),
                          tmp_path / str(equal))
        trainer.train()
        steps[equal], rows[equal] = _adam_steps(trainer.optimizer), len(trainer.buffer)
    assert rows[False] == rows[True] > 128  # the same relabelling: only the update differs
    assert steps[False] == 3 * math.ceil(rows[False] / 48)
    assert steps[True] == 3 * math.ceil(128 / 48)


class _RecordingLoss(torch.nn.Module):
    """The loss as it is, keeping each minibatch's logged terms as it computed them."""

    def __init__(self, loss):
        super().__init__()
        self.loss = loss
        self.terms: list[dict[str, float]] = []

    def forward(self, batch):
        losses = self.loss(batch)
        self.terms.append({key: float(losses[key].detach().float().mean())
                           for key in LOGGED_LOSS_TERMS if key in losses.keys()})
        return losses


def test_ppo_update_returns_each_logged_term_averaged_over_its_minibatches():
    from agrl.rl.ppo import make_optimizer, ppo_update

    loss, batch = _loss_and_batch(3072)
    recording = _RecordingLoss(loss)
    losses = ppo_update(recording, make_optimizer(loss, 1e-3), batch, 512, epochs=2, max_grad_norm=0.5, where="here")
    assert len(recording.terms) == losses["minibatches"] == 12
    assert set(losses) == {*recording.terms[0], "minibatches"} and "explained_variance" in losses
    for key in recording.terms[0]:
        values = [terms[key] for terms in recording.terms]
        assert losses[key] == sum(values) / len(values), key
    assert len({terms["loss_objective"] for terms in recording.terms}) > 1  # a mean of different minibatches


def test_advantage_runs_the_critic_once_to_the_values_of_two_passes():
    """make_advantage's single critic pass (TorchRL's ``shifted=True``) gives the advantages and value targets of
    TorchRL's default two passes, on a batch whose episodes end inside it (at the decision budget or before)."""
    from torchrl.objectives.value import GAE

    from agrl.config import guidance_parameters
    from agrl.envs import GuidanceEnv
    from agrl.rl.models import make_critic
    from agrl.rl.ppo import make_advantage

    torch.manual_seed(0)
    params = guidance_parameters("simulation.max_decisions=5")
    env = GuidanceEnv(params, num_envs=16, seed=0)
    batch = env.rollout(12, break_when_any_done=False)  # random maneuvers: episodes end at 5 decisions or before
    assert batch.names[-1] == "time" and batch["next", "done"].sum() >= 16
    critic = make_critic([32, 32], "tanh")
    with torch.no_grad():
        one_pass = make_advantage(0.99, 0.95, critic, torch.device("cpu"))(batch.clone())
        two_passes = GAE(gamma=0.99, lmbda=0.95, value_network=critic, average_gae=False)(batch.clone())
    for key in ("advantage", "value_target", "state_value"):
        torch.testing.assert_close(one_pass[key], two_passes[key], rtol=0, atol=1e-6)
    # The value after an episode's end is not computed once (every end terminates: GAE does not bootstrap it).
    assert bool(batch["next", "terminated"].eq(batch["next", "done"]).all())
    going_on = ~batch["next", "done"]
    torch.testing.assert_close(one_pass["next", "state_value"][going_on], two_passes["next", "state_value"][going_on],
                               rtol=0, atol=1e-6)
