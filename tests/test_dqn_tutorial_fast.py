"""Post 003's PyTorch agent runs two pieces faster than the tutorial wrote them (the batch
gathered by index from rows that mirror the memory, the soft update in place, AdamW's
multi-tensor step): the same bits as the code as written (``as_written=True``), step by step,
through the memory's eviction, terminal transitions and a checkpoint's restore."""

from __future__ import annotations

import pickle
import random

import gymnasium as gym
import numpy as np
import pytest

from keras_rl.envs import EnvSpec
from keras_rl.posts.cartpole import CartPoleDQNConfig

torch = pytest.importorskip("torch", reason="needs the torch extra: pip install -e '.[torch]'")

from keras_rl.torch.dqn_tutorial import ReplayMemory, TransitionRows, TutorialDQNAgent  # noqa: E402

SPEC = EnvSpec(4, 1, n_actions=2)


def make(as_written: bool, **changes):
    config = CartPoleDQNConfig(seed=5, framework="torch").replace(**changes)
    env = gym.make("CartPole-v1")
    env.action_space.seed(5)
    agent = TutorialDQNAgent(config, SPEC, env.action_space, as_written=as_written)
    return agent, env


def train(agent, env, steps: int, losses: list):
    obs, _ = env.reset(seed=5)
    action = agent.begin_episode(obs)
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(action)
        action = agent.step(reward, obs, terminated, truncated)
        if action is None:
            losses.append(agent.end_episode())
            obs, _ = env.reset()
            action = agent.begin_episode(obs)


def assert_same_agent(a, b):
    for net in ("policy_net", "target_net"):
        for x, y in zip(getattr(a, net).parameters(), getattr(b, net).parameters(), strict=True):
            assert torch.equal(x, y), net
    sa, sb = a.optimizer.state_dict()["state"], b.optimizer.state_dict()["state"]
    for i in sa:
        for key in sa[i]:
            assert torch.equal(sa[i][key], sb[i][key]), (i, key)
    assert a.random.getstate() == b.random.getstate() and a.steps_done == b.steps_done


@pytest.mark.parametrize("changes", [{}, {"amsgrad": False, "weight_decay": 0.0}], ids=["faithful", "plain-adam"])
def test_gathered_batches_train_to_the_same_bits_as_the_code_as_written(changes):
    """A small memory (300) is full after 300 steps, so most of these updates sample from a
    memory that has evicted and wrapped; CartPole's terminal steps put ``None`` next states in it."""
    changes = {"buffer_size": 300, **changes}
    (slow, env_a), (fast, env_b) = make(True, **changes), make(False, **changes)
    assert fast.memory.rows.mirrors(fast.memory.memory) is False  # empty: nothing to mirror yet
    losses_a: list = []
    losses_b: list = []
    train(slow, env_a, 1500, losses_a)
    train(fast, env_b, 1500, losses_b)
    assert fast.memory.rows.pushed == 1500 and fast.memory.rows.mirrors(fast.memory.memory)
    assert any(t.next_state is None for t in fast.memory.memory)
    assert len(losses_a) > 5 and losses_a == losses_b
    assert_same_agent(slow, fast)


def test_a_sample_of_the_rows_is_the_sample_of_the_memory_the_same_draws():
    """``random.sample`` below and above its pool-or-set switch (1,045 items for 128): the same
    transitions, in the same order, and the generator left in the same state."""
    for n, capacity in ((200, 500), (1045, 2000), (1046, 2000), (5000, 3000)):
        memory = ReplayMemory(capacity, random.Random(n))
        rng = np.random.default_rng(n)
        for i in range(n):
            final = rng.random() < 0.1
            memory.push(
                torch.tensor(rng.normal(size=(1, 4)), dtype=torch.float32),
                torch.tensor([[int(rng.integers(2))]]),
                None if final else torch.tensor(rng.normal(size=(1, 4)), dtype=torch.float32),
                torch.tensor([float(i)]),
            )
        state = memory.rng.getstate()
        picked = memory.sample(128)
        after = memory.rng.getstate()
        memory.rng.setstate(state)
        states, actions, rewards, non_final, next_states = memory.sample_rows(128)
        assert memory.rng.getstate() == after
        assert torch.equal(states, torch.cat([t.state for t in picked]))
        assert torch.equal(actions, torch.cat([t.action for t in picked]))
        assert torch.equal(rewards, torch.cat([t.reward for t in picked]))
        assert non_final.tolist() == [t.next_state is not None for t in picked]
        assert torch.equal(next_states, torch.cat([t.next_state for t in picked if t.next_state is not None]))


def test_rows_that_cannot_mirror_the_memory_fall_back_to_the_code_as_written():
    """Another dtype, another shape, or a deque changed behind the rows' back: ``sample_rows``
    draws nothing and says so, and ``optimize_model`` samples as written."""
    rows = TransitionRows(10)
    memory = ReplayMemory(10, random.Random(0))
    memory.push(torch.zeros(1, 4), torch.zeros(1, 1, dtype=torch.long), None, torch.ones(1))
    assert memory.rows.mirrors(memory.memory)
    memory.push(torch.zeros(1, 4, dtype=torch.float64), torch.zeros(1, 1, dtype=torch.long), None, torch.ones(1))
    assert memory.rows.broken and memory.sample_rows(1) is None
    assert rows.mirrors(memory.memory) is False
    other = ReplayMemory(10, random.Random(0))
    other.push(torch.zeros(2, 4), torch.zeros(2, 1, dtype=torch.long), None, torch.ones(2))
    assert other.rows.broken
    mixed = ReplayMemory(10, random.Random(0))
    mixed.restore(list(memory.memory))  # a checkpoint's list layout, mixed dtypes: restored, not mirrored
    assert len(mixed) == 2 and mixed.rows.broken and mixed.sample_rows(1) is None
    third = ReplayMemory(10, random.Random(0))
    third.push(torch.zeros(1, 4), torch.zeros(1, 1, dtype=torch.long), torch.ones(1, 4), torch.ones(1))
    third.memory.append(third.memory[0])  # behind the rows' back, as a test may fill a memory
    state = third.rng.getstate()
    assert third.sample_rows(1) is None and third.rng.getstate() == state


def test_a_restored_memory_gathers_again_and_trains_to_the_same_bits():
    """A checkpoint's memory (``arrays``, pickled) restores the rows too; training on from it
    matches training on from the code as written, restored the same way."""
    (slow, env_a), (fast, env_b) = make(True, buffer_size=400), make(False, buffer_size=400)
    train(slow, env_a, 700, [])
    train(fast, env_b, 700, [])
    saved = pickle.dumps(fast.state_dict())
    (slow2, _), (fast2, _) = make(True, buffer_size=400), make(False, buffer_size=400)
    slow2.load_state_dict(pickle.loads(saved))  # each its own copy: a loaded optimizer keeps the tensors it is given
    fast2.load_state_dict(pickle.loads(saved))
    assert fast2.memory.rows.mirrors(fast2.memory.memory) and fast2.memory.rows.pushed == 400
    for agent in (slow2, fast2):
        for _ in range(50):
            agent.memory.push(torch.zeros(1, 4), torch.zeros(1, 1, dtype=torch.long), torch.zeros(1, 4), torch.ones(1))
            agent.optimize_model()
            agent.soft_update()
    assert_same_agent(slow2, fast2)


def test_rows_start_from_a_terminal_transition_and_restore_from_a_list():
    """A memory whose oldest transition is terminal (a restored one may be) still mirrors: the
    next-state rows are laid out by the first transition that has one. A checkpoint's list
    layout restores the rows in one pass, and they gather what ``sample`` picks."""
    memory = ReplayMemory(4, random.Random(1))
    for i in range(6):  # evicts two: the ring has wrapped
        terminal = i in (0, 3)
        memory.push(
            torch.full((1, 4), float(i)),
            torch.tensor([[i % 2]]),
            None if terminal else torch.full((1, 4), float(i) + 0.5),
            torch.tensor([float(i)]),
        )
        assert memory.rows.mirrors(memory.memory)
    restored = ReplayMemory(4, random.Random(1))
    restored.restore(list(memory.memory))
    assert restored.rows.mirrors(restored.memory) and restored.rows.pushed == 4
    for source in (memory, restored):
        state = source.rng.getstate()
        picked = source.sample(3)
        source.rng.setstate(state)
        states, _, rewards, non_final, _ = source.sample_rows(3)
        assert torch.equal(states, torch.cat([t.state for t in picked]))
        assert rewards.tolist() == [t.reward.item() for t in picked]
        assert non_final.tolist() == [t.next_state is not None for t in picked]
