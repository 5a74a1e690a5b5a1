"""The PyTorch ports of posts 000 and 001 for S seeds at once (``--seed-batch``).

Each network is the solo module run under ``torch.func.vmap`` with ``functional_call``
over its seeds' stacked weights (``torch.func.stack_module_state``): seed k's slice is
seed k's solo module, parameter for parameter, so nothing of the networks is written a
second time. The update is ``TorchDDPGLearner.update`` itself, through its hooks: each
seed's loss its own mean, the gradient taken of their sum (so each slice gets its solo
gradient), Keras' Adam per seed with its own step count and a mask (``SeedKerasAdam``:
post 001's seeds train different numbers of batches on one env step), and masked soft
updates. Each slice starts from the weights its solo run draws (``torch.manual_seed``,
then the solo builder). The tests: ``tests/test_torch_stacked.py``.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from keras_rl.buffers import Layout
from keras_rl.config import check_same_but_seed
from keras_rl.envs import EnvSpec
from keras_rl.errors import ConfigError, argument
from keras_rl.torch import require_torch, save_state
from keras_rl.torch.ddpg import TorchDDPGLearner, post000_learner, post001_learner
from keras_rl.torch.optimizers import SeedKerasAdam, keep_where, not_portable

require_torch()  # a clear error, naming the extra, when torch is missing
import torch  # noqa: E402
from torch import nn  # noqa: E402

NETWORKS = ("actor", "critic", "target_actor", "target_critic")


class Vmapped(nn.Module):
    """S copies of one solo module, weights stacked on a leading seed axis: ``[S, B, ...]``
    in, ``[S, B, ...]`` out. ``parameters()`` then ``buffers()`` pair up one to one with a
    solo module's (``_variables``' order)."""

    def __init__(self, solos: Sequence[nn.Module]):
        super().__init__()
        params, buffers = torch.func.stack_module_state(list(solos))
        self.template = [copy.deepcopy(solos[0]).to("meta")]  # a list: not a submodule, its weights unused
        self.param_names, self.buffer_names = list(params), list(buffers)
        self.stacked = nn.ParameterList(nn.Parameter(p.detach().clone()) for p in params.values())
        for i, b in enumerate(buffers.values()):
            self.register_buffer(f"b{i}", b.detach().clone())

    def forward(self, *inputs):
        params = dict(zip(self.param_names, self.stacked))
        buffers = dict(zip(self.buffer_names, self.buffers()))
        template = self.template[0]

        def one(p, b, *xs):
            return torch.func.functional_call(template, (p, b), xs)

        return torch.func.vmap(one)(params, buffers, *inputs)


class StackedTorchDDPGLearner(TorchDDPGLearner):
    """``TorchDDPGLearner``'s update for S seeds in one call (see the module docstring)."""

    takes_masks = True
    """``train(rows, mask)``: the loop may train some seeds and not others on one call."""

    def __init__(self, solos: Sequence[tuple], *, actor_lr: float, critic_lr: float, **kwargs):
        not_portable("seed-batched PyTorch DDPG")
        self.seeds = len(solos)
        nets = [Vmapped([s[i] for s in solos]) for i in range(4)]
        super().__init__(*nets, actor_lr=actor_lr, critic_lr=critic_lr, **kwargs)
        self.seed_adams = (
            SeedKerasAdam(nets[0].parameters(), self.seeds, actor_lr),
            SeedKerasAdam(nets[1].parameters(), self.seeds, critic_lr),
        )
        self.actor_optimizer, self.critic_optimizer = self.seed_adams
        self.solo_policies = [(s[0], s[1]) for s in solos]  # seed k's modules, for saving its slice

    # -- TorchDDPGLearner's hooks --------------------------------------------------------------
    def seed_mean(self, x):
        return x.mean(dim=tuple(range(1, x.dim())))  # [S]: each seed's own loss

    def total(self, loss):
        return loss.sum()  # each slice gets its solo gradient

    def soft_update_targets(self) -> None:
        mask = self.seed_adams[0].mask
        for target, source in self._soft_pairs:
            for t, s in zip(target, source, strict=True):
                t.copy_(torch.where(keep_where(mask, t), self.tau * s + (1.0 - self.tau) * t, t))

    # -- the stacked interface -------------------------------------------------------------------
    def train(self, rows: np.ndarray, mask: np.ndarray | None = None) -> dict:
        """One update of the seeds where ``mask`` is True (all by default) on their own rows
        ``[S, B, width]``; losses ``[S]``."""
        which = torch.ones(self.seeds, dtype=torch.bool) if mask is None else torch.as_tensor(np.asarray(mask, bool))
        self.seed_adams[0].mask = self.seed_adams[1].mask = which
        return super().train(rows)

    @torch.no_grad()
    def act(self, states: np.ndarray) -> np.ndarray:
        """Each seed's action for its state: ``[S, obs] -> [S, act]``."""
        return self.actor(torch.as_tensor(np.asarray(states, np.float32))[:, None, :])[:, 0].numpy()

    def train_and_act(self, rows: np.ndarray, states: np.ndarray, separate: bool = False):
        return self.train(rows), self.act(states)

    def step_without_batch(self, states: np.ndarray, episode_ended: bool = False) -> np.ndarray:
        return self.act(states)

    def slice_weights(self, k: int) -> dict[str, list[np.ndarray]]:
        """Seed k's weights as its solo module holds them (parameters, then buffers)."""
        return {
            name: [
                t[k].detach().numpy().copy()
                for t in (*getattr(self, name).parameters(), *getattr(self, name).buffers())
            ]
            for name in NETWORKS
        }

    def save_slice(self, k: int, run_dir) -> None:
        """Seed k's ``actor.pt`` and ``critic.pt``, as a solo run saves them."""
        weights = self.slice_weights(k)
        actor, critic = self.solo_policies[k]
        with torch.no_grad():
            for module, values in ((actor, weights["actor"]), (critic, weights["critic"])):
                for tensor, value in zip((*module.parameters(), *module.buffers()), values, strict=True):
                    tensor.copy_(torch.from_numpy(value))
        save_state(actor, Path(run_dir) / "actor.pt")
        save_state(critic, Path(run_dir) / "critic.pt")

    def _stateful(self) -> list:
        return [
            *(t for name in NETWORKS for t in (*getattr(self, name).parameters(), *getattr(self, name).buffers())),
            *self.seed_adams[0].tensors(),
            *self.seed_adams[1].tensors(),
        ]

    def slice_state(self, k: int) -> dict:
        return {"tensors": [t[k].detach().clone() for t in self._stateful()]}

    @torch.no_grad()
    def load_slice_state(self, k: int, state: dict) -> None:
        tensors = self._stateful()
        if len(tensors) != len(state["tensors"]):
            raise ValueError(f"checkpoint holds {len(state['tensors'])} values for {len(tensors)} tensors")
        for tensor, value in zip(tensors, state["tensors"]):
            tensor[k] = value


def _solo_networks(build, configs: Sequence, spec: EnvSpec) -> list[tuple]:
    """Each seed's four solo modules, drawn as its solo run draws them (its solo learner's)."""
    check_same_but_seed(configs)
    return [
        (lambda solo: (solo.actor, solo.critic, solo.target_actor, solo.target_critic))(build(c, spec)) for c in configs
    ]


def stack_post000(configs: Sequence, spec: EnvSpec):
    """Post 000's PyTorch learner for the seeds of ``configs``."""
    c = configs[0]
    if len(configs) == 1:
        from keras_rl.learners.stacked import SoloAsStack

        return SoloAsStack(post000_learner(c, spec))
    return StackedTorchDDPGLearner(
        _solo_networks(post000_learner, configs, spec),
        actor_lr=c.actor_lr,
        critic_lr=c.critic_lr,
        gamma=c.gamma,
        tau=c.tau,
        broadcast_target=c.broadcast_target,
        layout=Layout(spec.obs_dim, spec.action_dim),
    )


def stack_post001(configs: Sequence, spec: EnvSpec):
    """Post 001's PyTorch learner for the seeds of ``configs``, at learning phase 0."""
    c = configs[0]
    if len(configs) == 1:
        from keras_rl.learners.stacked import SoloAsStack

        return SoloAsStack(post001_learner(c, spec))
    if c.learning_phase_training:
        raise ConfigError(
            f"{argument('seed_batch')} does not cover learning_phase_training=true (its BatchNormalization updates "
            "its statistics in place and its noise draws from one generator); run it without"
        )
    return StackedTorchDDPGLearner(
        _solo_networks(post001_learner, configs, spec),
        actor_lr=c.actor_lr,
        critic_lr=c.critic_lr,
        gamma=c.gamma,
        tau=c.tau,
        broadcast_target=False,
        layout=Layout(spec.obs_dim, spec.action_dim),
        actor_gradient=c.actor_gradient,
        dqda_at_buffer_actions=c.dqda_at_buffer_actions,
    )
