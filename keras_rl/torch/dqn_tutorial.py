"""Post 003 as the PyTorch tutorial wrote it: ``DQN``, ``ReplayMemory``, ``select_action``,
``optimize_model`` and the state-dict soft update, wrapped in our agent verbs.

What changed from the notebook: globals became attributes (``steps_done``, the networks,
the optimizer, ``memory``), Python's ``random`` became a seeded ``random.Random``, and the
device is the CPU. The arithmetic and its order are the tutorial's.

Three pieces run faster than written, to the same bits (``as_written=True`` runs them as
written; ``tests/test_dqn_tutorial_fast.py`` trains both and compares every weight, and the
committed PyTorch runs replay bit for bit):
- the batch: the memory also keeps its transitions as rows of preallocated tensors
  (``TransitionRows``), and a sample draws the same indices from the same ``random.Random``
  (``sample(range(n), k)`` makes the draws ``sample(memory, k)`` makes) and gathers them by
  index, instead of ``torch.cat`` over 128 one-row tensors per field;
- the soft update: each target parameter becomes ``policy * TAU + target * (1 - TAU)`` in
  place, instead of building and loading two state dicts; the same two products and sum;
- AdamW's multi-tensor step (``foreach=True``, the default the tutorial's optimizer takes on a
  GPU): on a CPU the same per-tensor operations as its single-tensor loop. A checkpoint from
  before keeps its own setting on resume (``load_state_dict`` restores the param groups), and
  steps to the same bits either way.
``benchmarks/torch_tutorial_step.py`` measures what that saves.
"""

from __future__ import annotations

import copy
import math
import random
from collections import deque, namedtuple
from pathlib import Path

import numpy as np

from keras_rl.agents.skeleton import EpisodeStats, LossTally
from keras_rl.envs import EnvSpec
from keras_rl.torch import load_state, portable_arithmetic, require_torch, save_state, single_threaded
from keras_rl.torch.optimizers import check_same_arithmetic

require_torch()  # a clear error, naming the extra, when torch is missing
import torch  # noqa: E402
from torch import nn  # noqa: E402

F = nn.functional

Transition = namedtuple("Transition", ("state", "action", "next_state", "reward"))


class TransitionRows:
    """The memory's transitions as rows of preallocated tensors: a ring that mirrors the
    ``deque``'s eviction (``maxlen``), so row ``(oldest + j) % capacity`` is the deque's item
    ``j``. Each field is allocated by the first transition that has it (its dtype and row
    shape); one that does not fit (another dtype or shape, or not one row) stops the mirror,
    and the memory samples as written from then on."""

    def __init__(self, capacity: int):
        self.capacity = capacity
        self.clear()

    def clear(self) -> None:
        self.pushed = 0
        self.fields: dict[str, torch.Tensor] = {}
        self.final = torch.zeros(self.capacity, dtype=torch.bool)
        self.last: Transition | None = None
        self.broken = False

    def append(self, t: Transition) -> None:
        if self.broken:
            return
        values = {"state": t.state, "action": t.action, "reward": t.reward}
        if t.next_state is not None:
            values["next_state"] = t.next_state
        for name, value in values.items():
            if value.dim() == 0 or value.shape[0] != 1:
                self.broken = True
                return
            row = self.fields.setdefault(name, torch.zeros((self.capacity, *value.shape[1:]), dtype=value.dtype))
            if value.dtype != row.dtype or value.shape[1:] != row.shape[1:]:
                self.broken = True
                return
        at = self.pushed % self.capacity
        for name, value in values.items():
            self.fields[name][at : at + 1] = value
        self.final[at] = t.next_state is None
        self.pushed += 1
        self.last = t

    def rebuild(self, memory: deque) -> None:
        """Rows for every transition of ``memory`` at once (a restored checkpoint's), oldest
        first from row 0; broken, as ``append`` would leave it, where they do not fit."""
        self.clear()
        items = list(memory)
        if not items:
            return
        final = [t.next_state is None for t in items]
        columns = {name: [getattr(t, name) for t in items] for name in ("state", "action", "reward")}
        columns["next_state"] = [t.next_state for t, f in zip(items, final) if not f]
        for name, values in columns.items():
            if not values:
                continue
            kinds = {(v.dtype, v.shape) for v in values}
            first = values[0]
            if len(kinds) > 1 or first.dim() == 0 or first.shape[0] != 1:
                self.broken = True
                return
            self.fields[name] = torch.zeros((self.capacity, *first.shape[1:]), dtype=first.dtype)
        n, mask = len(items), torch.tensor(final)
        self.final[:n] = mask
        for name, values in columns.items():
            if not values:
                continue
            if name == "next_state":
                self.fields[name][:n][~mask] = torch.cat(values)
            else:
                self.fields[name][:n] = torch.cat(values)
        self.pushed, self.last = n, items[-1]

    def mirrors(self, memory: deque) -> bool:
        held = min(self.pushed, self.capacity)
        return not self.broken and held > 0 and len(memory) == held and memory[-1] is self.last

    def gather(self, picks: list[int]):
        """The rows of the deque's items ``picks``, in that order: the state, action and reward
        batches, the non-final mask, and the non-final next states (``None`` when none)."""
        oldest = self.pushed % self.capacity if self.pushed >= self.capacity else 0
        at = (torch.tensor(picks) + oldest) % self.capacity
        non_final_mask = ~self.final.index_select(0, at)
        live = at[non_final_mask]
        next_states = self.fields["next_state"].index_select(0, live) if len(live) else None
        return (
            self.fields["state"].index_select(0, at),
            self.fields["action"].index_select(0, at),
            self.fields["reward"].index_select(0, at),
            non_final_mask,
            next_states,
        )


class ReplayMemory:
    def __init__(self, capacity: int, rng: random.Random):
        self.memory: deque = deque([], maxlen=capacity)
        self.rng = rng
        self.rows = TransitionRows(capacity)

    def push(self, *args):
        transition = Transition(*args)
        self.memory.append(transition)
        self.rows.append(transition)

    def sample(self, batch_size):
        return self.rng.sample(self.memory, batch_size)

    def sample_rows(self, batch_size):
        """``sample``'s draw as ``TransitionRows.gather``'s tensors, or ``None`` where the rows do
        not mirror the deque (then nothing is drawn). ``random.sample`` picks indices from the
        population's length alone, so sampling ``range(n)`` spends the same draws and picks the
        same items."""
        if not self.rows.mirrors(self.memory):
            return None
        return self.rows.gather(self.rng.sample(range(len(self.memory)), batch_size))

    def __len__(self):
        return len(self.memory)

    def arrays(self) -> dict | list:
        """The memory as one array per field, for a checkpoint: pickling it as 40,000 small
        tensors took seconds per checkpoint (``benchmarks/checkpoint.py``).
        Each field keeps its dtype; a memory whose items differ in dtype (none that the loop
        writes) stays a list of transitions, so ``restore`` gives back the same values always."""
        items = list(self.memory)
        if not items:
            return items
        fields = {
            name: [getattr(t, name) for t in items if getattr(t, name) is not None] for name in Transition._fields
        }
        if any(len({(v.dtype, v.shape) for v in values}) > 1 for values in fields.values()):
            return items
        final = np.array([t.next_state is None for t in items], dtype=bool)
        arrays = {name: torch.cat(values).numpy() for name, values in fields.items() if values}
        return {"final": final, **arrays, "shapes": {name: tuple(v[0].shape) for name, v in fields.items() if v}}

    def restore(self, saved: dict | list) -> None:
        """The memory ``arrays`` wrote (or a list of transitions, as checkpoints before it held)."""
        self.memory.clear()
        if isinstance(saved, list):
            self.memory.extend(saved)
            self.rows.rebuild(self.memory)
            return
        rows = {name: torch.from_numpy(saved[name]).reshape(-1, *shape) for name, shape in saved["shapes"].items()}
        live = iter(rows["next_state"]) if "next_state" in rows else iter(())
        for i, final in enumerate(saved["final"]):
            next_state = None if final else next(live).clone()
            self.memory.append(  # each its own storage, as the loop's are (a view would pickle all of its rows)
                Transition(rows["state"][i].clone(), rows["action"][i].clone(), next_state, rows["reward"][i].clone())
            )
        self.rows.rebuild(self.memory)


class DQN(nn.Module):
    def __init__(self, n_observations, n_actions, hidden=(128, 128)):
        super().__init__()
        self.layer1 = nn.Linear(n_observations, hidden[0])
        self.layer2 = nn.Linear(hidden[0], hidden[1])
        self.layer3 = nn.Linear(hidden[1], n_actions)

    def forward(self, x):
        x = F.relu(self.layer1(x))
        x = F.relu(self.layer2(x))
        return self.layer3(x)


class TutorialDQNAgent:
    """The tutorial's code path behind the agent skeleton's verbs (``begin_episode``, ``step``,
    ``end_episode``); the Keras version is ``keras_rl.posts.cartpole.assemble``'s agent."""

    loss_names = ("loss",)

    def __init__(self, config, spec: EnvSpec, action_space, as_written: bool = False):
        self.config = c = config
        self.as_written = as_written
        """Batch and soft-update exactly as the tutorial wrote them (slower; the same bits)."""
        n_observations, n_actions = spec.obs_dim, spec.n_actions
        if n_actions is None:
            raise ValueError("the tutorial's DQN needs a Discrete action space (spec.n_actions)")
        single_threaded()
        torch.manual_seed(c.seed)
        self.policy_net = DQN(n_observations, n_actions, c.q_hidden_units)
        self.target_net = DQN(n_observations, n_actions, c.q_hidden_units)
        if c.matched_init:  # the Keras agent's first network, same seed (the target copies it)
            from keras_rl.learners.networks import QNetwork, build
            from keras_rl.torch.weights import copy_from_keras, dense_pairs

            q_network = build(QNetwork(n_observations, n_actions, c.q_hidden_units, c.init), n_observations)
            net = self.policy_net
            copy_from_keras(net, q_network, dense_pairs([net.layer1, net.layer2, net.layer3], q_network.dense))
        self.target_net.load_state_dict(self.policy_net.state_dict())
        self.optimizer = torch.optim.AdamW(
            self.policy_net.parameters(),
            lr=c.q_lr,
            amsgrad=c.amsgrad,
            weight_decay=c.weight_decay,
            eps=c.adam_eps,
            foreach=None if as_written or portable_arithmetic() else True,
            fused=portable_arithmetic() or None,
        )
        self._targets = list(self.target_net.parameters())
        self._policies = list(self.policy_net.parameters())
        self.criterion = nn.SmoothL1Loss()
        self.random = random.Random(c.seed)
        self.memory = ReplayMemory(c.buffer_size, self.random)
        self.action_space = action_space
        self.steps_done = 0
        self.tally = LossTally(self.loss_names)
        self._state: torch.Tensor | None = None
        self._action: torch.Tensor = torch.zeros((1, 1), dtype=torch.long)

    # -- the tutorial's functions ----------------------------------------------------------
    def select_action(self, state, sample: float | None = None):
        c = self.config
        sample = self.random.random() if sample is None else sample
        eps_threshold = c.eps_end + (c.eps_start - c.eps_end) * math.exp(-1.0 * self.steps_done / c.eps_decay)
        self.steps_done += 1
        if sample > eps_threshold:
            with torch.no_grad():
                return self.policy_net(state).max(1)[1].view(1, 1)
        return torch.tensor([[self.action_space.sample()]], dtype=torch.long)

    def optimize_model(self, transitions=None):
        c = self.config
        if transitions is None:
            if len(self.memory) < c.train_start:  # `< BATCH_SIZE` in the tutorial; train_start = BATCH_SIZE
                return None
            rows = None if self.as_written else self.memory.sample_rows(c.batch_size)
            if rows is not None:  # the same draw, gathered by index (the module's docstring)
                return self.learn(*rows)
            transitions = self.memory.sample(c.batch_size)
        batch = Transition(*zip(*transitions))
        non_final_mask = torch.tensor(tuple(map(lambda s: s is not None, batch.next_state)), dtype=torch.bool)
        non_final_next_states = [s for s in batch.next_state if s is not None]
        state_batch = torch.cat(batch.state)
        action_batch = torch.cat(batch.action)
        reward_batch = torch.cat(batch.reward)
        next_states = torch.cat(non_final_next_states) if non_final_next_states else None
        return self.learn(state_batch, action_batch, reward_batch, non_final_mask, next_states)

    def learn(self, state_batch, action_batch, reward_batch, non_final_mask, non_final_next_states):
        """The rest of the tutorial's ``optimize_model``, from its batches on."""
        c = self.config
        state_action_values = self.policy_net(state_batch).gather(1, action_batch)
        next_state_values = torch.zeros(
            len(state_batch), dtype=reward_batch.dtype
        )  # float32 as in the tutorial, float64 in a parity test
        with torch.no_grad():
            if non_final_next_states is not None:
                next_state_values[non_final_mask] = self.target_net(non_final_next_states).max(1)[0]
        expected_state_action_values = (next_state_values * c.gamma) + reward_batch

        loss = self.criterion(state_action_values, expected_state_action_values.unsqueeze(1))
        self.optimizer.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_value_(self.policy_net.parameters(), c.grad_clip_value)
        self.optimizer.step()
        return loss

    def soft_update(self):
        tau = self.config.tau
        if not self.as_written:  # the same products and sum, parameter by parameter, in place
            with torch.no_grad():
                mixed = torch._foreach_mul(self._policies, tau)
                torch._foreach_add_(mixed, torch._foreach_mul(self._targets, 1 - tau))
                torch._foreach_copy_(self._targets, mixed)
            return
        target_net_state_dict = self.target_net.state_dict()
        policy_net_state_dict = self.policy_net.state_dict()
        for key in policy_net_state_dict:
            target_net_state_dict[key] = policy_net_state_dict[key] * tau + target_net_state_dict[key] * (1 - tau)
        self.target_net.load_state_dict(target_net_state_dict)

    # -- our agent verbs --------------------------------------------------------------------
    def begin_episode(self, obs) -> int:
        self.tally.reset()
        self._state = torch.tensor(obs, dtype=torch.float32).unsqueeze(0)
        self._action = self.select_action(self._state)
        return int(self._action.item())

    def step(self, reward: float, obs, terminated: bool, truncated: bool) -> int | None:
        reward_t = torch.tensor([reward])
        next_state = None if terminated else torch.tensor(obs, dtype=torch.float32).unsqueeze(0)
        self.memory.push(self._state, self._action, next_state, reward_t)
        self._state = next_state
        loss = self.optimize_model()
        self.soft_update()
        if loss is not None:
            self.tally.add({"loss": loss.item()}, f"env step {self.steps_done}")
        if terminated or truncated:
            return None
        self._action = self.select_action(self._state)
        return int(self._action.item())

    def end_episode(self) -> EpisodeStats:
        return self.tally.stats()

    def state_dict(self) -> dict:
        return {
            "policy_net": {k: v.clone() for k, v in self.policy_net.state_dict().items()},
            "target_net": {k: v.clone() for k, v in self.target_net.state_dict().items()},
            "optimizer": copy.deepcopy(self.optimizer.state_dict()),
            "random": self.random.getstate(),
            "memory": self.memory.arrays(),
            "steps_done": self.steps_done,
            "total_updates": self.tally.total_updates,
            "torch_rng": torch.get_rng_state(),
        }

    def load_state_dict(self, state: dict) -> None:
        check_same_arithmetic(state["optimizer"])
        self.policy_net.load_state_dict(state["policy_net"])
        self.target_net.load_state_dict(state["target_net"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.random.setstate(state["random"])
        self.memory.restore(state["memory"])
        self.steps_done, self.tally.total_updates = int(state["steps_done"]), int(state["total_updates"])
        torch.set_rng_state(state["torch_rng"])

    @property
    def updates(self) -> int:
        return self.tally.total_updates

    def greedy_action(self, obs) -> int:
        with torch.no_grad():
            return int(self.policy_net(torch.tensor(np.asarray(obs), dtype=torch.float32).unsqueeze(0)).max(1)[1])

    def save(self, run_dir: Path) -> None:
        save_state(self.policy_net, Path(run_dir) / "q_network.pt")

    def load_policy(self, run_dir: Path) -> None:
        load_state(self.policy_net, Path(run_dir) / "q_network.pt")
