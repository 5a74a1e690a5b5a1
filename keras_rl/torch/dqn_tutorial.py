"""Post 003 as the PyTorch tutorial wrote it: ``DQN``, ``ReplayMemory``, ``select_action``,
``optimize_model`` and the state-dict soft update, wrapped in our agent verbs.

What changed from the notebook: globals became attributes (``steps_done``, the networks,
the optimizer, ``memory``), Python's ``random`` became a seeded ``random.Random``, and the
device is the CPU. The arithmetic and its order are the tutorial's.
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
from keras_rl.torch import load_state, require_torch, save_state, single_threaded

require_torch()  # a clear error, naming the extra, when torch is missing
import torch  # noqa: E402
from torch import nn  # noqa: E402

F = nn.functional

Transition = namedtuple("Transition", ("state", "action", "next_state", "reward"))


class ReplayMemory:
    def __init__(self, capacity: int, rng: random.Random):
        self.memory: deque = deque([], maxlen=capacity)
        self.rng = rng

    def push(self, *args):
        self.memory.append(Transition(*args))

    def sample(self, batch_size):
        return self.rng.sample(self.memory, batch_size)

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
            return
        rows = {name: torch.from_numpy(saved[name]).reshape(-1, *shape) for name, shape in saved["shapes"].items()}
        live = iter(rows["next_state"]) if "next_state" in rows else iter(())
        for i, final in enumerate(saved["final"]):
            next_state = None if final else next(live).clone()
            self.memory.append(  # each its own storage, as the loop's are (a view would pickle all of its rows)
                Transition(rows["state"][i].clone(), rows["action"][i].clone(), next_state, rows["reward"][i].clone())
            )


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

    def __init__(self, config, spec: EnvSpec, action_space):
        self.config = c = config
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
            self.policy_net.parameters(), lr=c.q_lr, amsgrad=c.amsgrad, weight_decay=c.weight_decay, eps=c.adam_eps
        )
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
            transitions = self.memory.sample(c.batch_size)
        batch = Transition(*zip(*transitions))
        non_final_mask = torch.tensor(tuple(map(lambda s: s is not None, batch.next_state)), dtype=torch.bool)
        non_final_next_states = [s for s in batch.next_state if s is not None]
        state_batch = torch.cat(batch.state)
        action_batch = torch.cat(batch.action)
        reward_batch = torch.cat(batch.reward)

        state_action_values = self.policy_net(state_batch).gather(1, action_batch)
        next_state_values = torch.zeros(
            len(transitions), dtype=reward_batch.dtype
        )  # float32 as in the tutorial, float64 in a parity test
        with torch.no_grad():
            if non_final_next_states:
                next_state_values[non_final_mask] = self.target_net(torch.cat(non_final_next_states)).max(1)[0]
        expected_state_action_values = (next_state_values * c.gamma) + reward_batch

        loss = self.criterion(state_action_values, expected_state_action_values.unsqueeze(1))
        self.optimizer.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_value_(self.policy_net.parameters(), c.grad_clip_value)
        self.optimizer.step()
        return loss

    def soft_update(self):
        target_net_state_dict = self.target_net.state_dict()
        policy_net_state_dict = self.policy_net.state_dict()
        for key in policy_net_state_dict:
            target_net_state_dict[key] = policy_net_state_dict[key] * self.config.tau + target_net_state_dict[key] * (
                1 - self.config.tau
            )
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
