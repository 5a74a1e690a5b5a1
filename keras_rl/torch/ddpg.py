"""PyTorch ports of posts 000 and 001: the same DDPG update as ``keras_rl.learners.ddpg.DDPGLearner``.

Only the learner is ported. The agent skeleton and its parts (``keras_rl/agents/``,
``keras_rl/posts/``), buffers, configs, quirk switches and result files are shared, so a
difference in outcome between ``--framework keras`` and ``--framework torch`` comes from
the framework: its kernels, its float summation order, and (unless ``matched_init``)
its default initialisation.

What a PyTorch user porting these posts would write, with two decisions made so that
both frameworks run the same algorithm:

- **Optimiser.** Both posts use Keras' ``Adam`` (``epsilon=1e-7`` added to ``sqrt(v)``
  *before* the bias correction). ``torch.optim.Adam`` adds its ``eps`` after it, which
  for gradients below ~3e-4 changes the first steps by more than 1e-5. ``KerasAdam`` is
  ``torch.optim.Adam`` with ``eps`` rescaled every step so the arithmetic is Keras'.
- **Initialisation.** By default each network gets PyTorch's own ``nn.Linear`` init,
  as a PyTorch user would get; Keras' is Glorot-uniform kernels and zero biases.
  ``matched_init=True`` (``--matched-init``) builds the Keras networks with the same seed
  and copies their initial weights in (``copy_from_keras``), which isolates the framework.

Post 001's settlements carry over as Keras decided them (FIDELITY P001-PHASE,
P001-ACTORGRAD): learning phase 0 (noise layer off, BatchNormalization on its never-updated
moving statistics with Keras' epsilon 1e-3) and the literal second-order actor step.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from keras_rl.buffers import Batch, Layout
from keras_rl.envs import EnvSpec
from keras_rl.learners.protocol import ActorGradient, check_actor_gradient, four_networks
from keras_rl.torch import load_state, require_torch, save_state, single_threaded
from keras_rl.torch.networks import Actor, Critic, MountainCarActor, MountainCarCritic
from keras_rl.torch.optimizers import KerasAdam, SeedKerasAdam, check_same_arithmetic
from keras_rl.torch.weights import hard_copy, match_keras, soft_update, variables

require_torch()  # a clear error, naming the extra, when torch is missing
import torch  # noqa: E402


class TorchDDPGLearner:
    """``keras_rl.learners.ddpg.DDPGLearner`` in PyTorch: the same ``Learner`` protocol, the
    same update order (critic, actor, soft updates) and the same ``actor_gradient`` modes
    (``mean_q``, ``dpg_intended``, ``dpg_literal``)."""

    loss_names = ("critic_loss", "actor_loss")

    def __init__(
        self,
        actor,
        critic,
        target_actor,
        target_critic,
        *,
        actor_lr: float,
        critic_lr: float,
        gamma: float,
        tau: float,
        broadcast_target: bool,
        layout: Layout,
        actor_gradient: ActorGradient = "mean_q",
        dqda_at_buffer_actions: bool = False,
    ):
        check_actor_gradient(actor_gradient)
        self.actor, self.critic, self.target_actor, self.target_critic = actor, critic, target_actor, target_critic
        # KerasAdam here; a seed-batched subclass puts a SeedKerasAdam in their place
        self.actor_optimizer: KerasAdam | SeedKerasAdam = KerasAdam(actor.parameters(), lr=actor_lr)
        self.critic_optimizer: KerasAdam | SeedKerasAdam = KerasAdam(critic.parameters(), lr=critic_lr)
        self.gamma, self.tau = float(gamma), float(tau)
        self.broadcast_target = bool(broadcast_target)
        self.layout = layout
        self.actor_gradient, self.dqda_at_buffer_actions = actor_gradient, bool(dqda_at_buffer_actions)
        self._actor_params = list(actor.parameters())
        # (target, source) lists for the soft updates, built once, not per update
        self._soft_pairs = [(variables(target_actor), variables(actor)), (variables(target_critic), variables(critic))]

    def compile(self) -> None:
        """Nothing to trace: PyTorch runs eagerly."""

    def train(self, rows: np.ndarray) -> dict:
        return self.update(self.layout.split(torch.from_numpy(np.ascontiguousarray(rows, np.float32))))

    @torch.no_grad()
    def act(self, state: np.ndarray) -> np.ndarray:
        """The actor's action for one state [obs] -> [act], as numpy."""
        return self.actor(torch.as_tensor(np.asarray(state, np.float32))[None, :])[0].numpy()

    def train_and_act(self, rows: np.ndarray, state: np.ndarray):
        return self.train(rows), self.act(state)

    def step_without_batch(self, state: np.ndarray, want_action: bool):
        return self.act(state) if want_action else None

    def weights(self) -> dict[str, list[np.ndarray]]:
        return {
            name: [t.detach().numpy().copy() for t in variables(getattr(self, name))]
            for name in ("actor", "critic", "target_actor", "target_critic")
        }

    def state_dict(self) -> dict:
        nets = ("actor", "critic", "target_actor", "target_critic")
        return {
            "nets": {n: {k: v.clone() for k, v in getattr(self, n).state_dict().items()} for n in nets},
            "optimizers": {
                n: copy.deepcopy(getattr(self, n).state_dict()) for n in ("actor_optimizer", "critic_optimizer")
            },
            "iterations": {n: getattr(self, n).iterations for n in ("actor_optimizer", "critic_optimizer")},
            "torch_rng": torch.get_rng_state(),
        }

    def load_state_dict(self, state: dict) -> None:
        check_same_arithmetic(*state["optimizers"].values())
        for name, values in state["nets"].items():
            getattr(self, name).load_state_dict(values)
        for name, values in state["optimizers"].items():
            getattr(self, name).load_state_dict(values)
            getattr(self, name).iterations = int(state["iterations"][name])
        torch.set_rng_state(state["torch_rng"])

    @torch.no_grad()
    def td_targets(self, rewards, next_states, dones):
        """The critic's regression targets, [B,B] under P000-BROADCAST, else [B,1]."""
        next_q = self.target_critic(next_states, self.target_actor(next_states))  # [B, 1]
        rewards = rewards[..., None]
        if self.broadcast_target:
            return rewards + self.gamma * next_q * (1.0 - dones[..., None, :])  # [B, B], as in the Keras learner
        return rewards + self.gamma * next_q * (1.0 - dones[..., :, None])

    def update(self, batch: Batch) -> dict:
        states, actions, rewards, next_states, dones = batch
        targets = self.td_targets(rewards, next_states, dones)

        q_values = self.critic(states, actions)
        critic_loss = self.seed_mean(torch.square(q_values - targets))
        self.critic_optimizer.zero_grad(set_to_none=False)
        self.total(critic_loss).backward()
        self.critic_optimizer.step()

        grads, actor_loss = self.actor_gradients(states, actions)
        for p, g in zip(self._actor_params, grads):
            p.grad = g
        self.actor_optimizer.step()

        with torch.no_grad():
            self.soft_update_targets()
        return {"critic_loss": critic_loss.detach(), "actor_loss": actor_loss.detach()}

    # -- hooks: the seed-batched learner (``torch/stacked.py``) runs this update over a seed axis
    def seed_mean(self, x):
        """A loss's mean over the batch (per seed, stacked)."""
        return torch.mean(x)

    def total(self, loss):
        """What the gradient is taken of (stacked: the sum of the seeds' losses)."""
        return loss

    def soft_update_targets(self) -> None:
        for target, source in self._soft_pairs:
            soft_update(target, source, self.tau)

    def actor_gradients(self, states, actions):
        """The actor's gradients, as in ``DDPGLearner.actor_gradients``, and -mean Q to report."""
        params = self._actor_params
        if self.actor_gradient == "mean_q":
            actor_loss = -self.seed_mean(self.critic(states, self.actor(states)))
            return torch.autograd.grad(self.total(actor_loss), params), actor_loss
        policy_actions = self.actor(states)  # [B, act], with its graph for the step below
        at = (actions if self.dqda_at_buffer_actions else policy_actions).detach().requires_grad_(True)
        q_values = self.critic(states, at)
        (dq_da,) = torch.autograd.grad(q_values.sum(), at)  # a constant for the actor's step
        actor_loss = -self.seed_mean(q_values)
        if self.actor_gradient == "dpg_intended":
            return torch.autograd.grad(policy_actions, params, grad_outputs=-dq_da), actor_loss
        # dpg_literal: the gradient of the sum of every entry of the first-order gradients.
        first = torch.autograd.grad(policy_actions, params, grad_outputs=-dq_da, create_graph=True)
        total = sum(g.sum() for g in first)
        second = torch.autograd.grad(total, params, allow_unused=True)
        return tuple(torch.zeros_like(p) if g is None else g for p, g in zip(params, second)), actor_loss

    def save(self, run_dir: Path) -> None:
        """``actor.pt`` and ``critic.pt`` (state dicts)."""
        save_state(self.actor, Path(run_dir) / "actor.pt")
        save_state(self.critic, Path(run_dir) / "critic.pt")

    def load_policy(self, run_dir: Path) -> None:
        load_state(self.actor, Path(run_dir) / "actor.pt")


def post000_learner(config, spec: EnvSpec) -> TorchDDPGLearner:
    """Post 000's learner in PyTorch (the agent is ``keras_rl.posts.pendulum.assemble``'s)."""
    c = config
    single_threaded()
    torch.manual_seed(c.seed)
    nets = four_networks(
        lambda: Actor(spec.obs_dim, spec.action_dim, spec.action_bound, c.actor_hidden_units),
        lambda: Critic(spec.obs_dim, spec.action_dim, c.critic_hidden_units),
        None if c.matched_init or c.target_copy_is_noop else hard_copy,
    )
    if c.matched_init:
        from keras_rl.learners.ddpg import post000_networks  # the Keras learner's draws, same seed and order

        match_keras(nets, post000_networks(c, spec))
    return TorchDDPGLearner(
        *nets,
        actor_lr=c.actor_lr,
        critic_lr=c.critic_lr,
        gamma=c.gamma,
        tau=c.tau,
        broadcast_target=c.broadcast_target,
        layout=Layout(spec.obs_dim, spec.action_dim),
    )


def post001_learner(config, spec: EnvSpec) -> TorchDDPGLearner:
    """Post 001's learner in PyTorch (the agent is ``keras_rl.posts.mountaincar.assemble``'s)."""
    c = config
    single_threaded()
    torch.manual_seed(c.seed)
    nets = four_networks(
        lambda: MountainCarActor(
            spec.obs_dim, spec.action_dim, c.actor_hidden_units, c.actor_input_noise, c.learning_phase_training
        ),
        lambda: MountainCarCritic(spec.obs_dim, spec.action_dim, c.critic_hidden_units, c.learning_phase_training),
        None if c.matched_init else hard_copy,
    )  # Agent.__init__'s set_weights copy
    if c.matched_init:
        from keras_rl.learners.ddpg import post001_networks

        match_keras(nets, post001_networks(c, spec))
    return TorchDDPGLearner(
        *nets,
        actor_lr=c.actor_lr,
        critic_lr=c.critic_lr,
        gamma=c.gamma,
        tau=c.tau,
        broadcast_target=False,
        layout=Layout(spec.obs_dim, spec.action_dim),
        actor_gradient=c.actor_gradient,
        dqda_at_buffer_actions=c.dqda_at_buffer_actions,
    )
