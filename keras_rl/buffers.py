"""Replay buffers: one numpy matrix preallocated once, batches as a NamedTuple.

A transition is one float32 row ``[state | action | reward | next_state | done]``.
Sampling gathers rows with a single fancy index, and the compiled update receives
that one matrix and splits it (``Layout.split``): one host-to-graph conversion per
step instead of five. Discrete actions are stored as exact small floats.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from keras_rl.rngs import rng_state, set_rng_state


class Batch(NamedTuple):
    states: Any  # [B, obs]
    actions: Any  # [B, act]
    rewards: Any  # [B]
    next_states: Any  # [B, obs]
    dones: Any  # [B], 1.0 where the stored transition is terminal


class Layout(NamedTuple):
    """Column layout of a packed transition row."""

    obs_dim: int
    action_dim: int

    @property
    def width(self) -> int:
        return 2 * self.obs_dim + self.action_dim + 2

    def split(self, rows) -> Batch:
        """Views of a packed [..., width] array (numpy or tf: [B, width], or [S, B, width]
        for seed-batched learners) as a Batch."""
        o, a = self.obs_dim, self.action_dim
        return Batch(
            rows[..., :o],
            rows[..., o : o + a],
            rows[..., o + a],
            rows[..., o + a + 1 : 2 * o + a + 1],
            rows[..., 2 * o + a + 1],
        )

    def pack(self, batch) -> np.ndarray:
        """The inverse of ``split`` for numpy batches (any 5-tuple in Batch order)."""
        batch = Batch(*batch)
        return np.concatenate(
            [
                np.asarray(batch.states, np.float32).reshape(len(batch.rewards), -1),
                np.asarray(batch.actions, np.float32).reshape(len(batch.rewards), -1),
                np.asarray(batch.rewards, np.float32).reshape(-1, 1),
                np.asarray(batch.next_states, np.float32).reshape(len(batch.rewards), -1),
                np.asarray(batch.dones, np.float32).reshape(-1, 1),
            ],
            axis=1,
        )


class ReplayBuffer:
    """A ring buffer with FIFO eviction at capacity, like ``deque(maxlen=capacity)``.

    ``sample_rows`` draws without replacement by default, as ``random.sample`` does in
    posts 000 and 003; ``replace=True`` gives the usual SB3/CleanRL sampling.
    """

    def __init__(self, capacity: int, layout: Layout, rng: np.random.Generator):
        if capacity <= 0:
            raise ValueError(f"capacity must be positive, got {capacity}")
        self.capacity = int(capacity)
        self.layout = layout
        self.rng = rng
        self.data = np.zeros((self.capacity, layout.width), dtype=np.float32)
        self._next = 0  # the slot the next transition is written to
        self._size = 0

    def __len__(self) -> int:
        return self._size

    def add_rows(self, rows: np.ndarray) -> None:
        """Append packed rows (oldest first), evicting the oldest at capacity."""
        for row in rows:
            self.data[self._next] = row
            self._next = (self._next + 1) % self.capacity
            self._size = min(self._size + 1, self.capacity)

    def sample_rows(self, batch_size: int, replace: bool = False) -> np.ndarray:
        if not replace and batch_size > self._size:
            raise ValueError(f"cannot sample {batch_size} without replacement from {self._size}")
        if replace:
            idx = self.rng.integers(0, self._size, size=batch_size)
        else:
            idx = self.rng.choice(self._size, size=batch_size, replace=False)
        return self.data[idx]

    def state_dict(self) -> dict[str, Any]:
        return {
            "data": self.data[: self._size].copy() if self._size < self.capacity else self.data.copy(),
            "next": self._next,
            "size": self._size,
            "rng": rng_state(self.rng),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.data[: len(state["data"])] = state["data"]
        self._next, self._size = int(state["next"]), int(state["size"])
        set_rng_state(self.rng, state["rng"])

    def sample(self, batch_size: int, replace: bool = False) -> Batch:
        return self.layout.split(self.sample_rows(batch_size, replace))

    def ordered(self) -> Batch:
        """All stored transitions, oldest first (for tests and inspection)."""
        start = self._next if self._size == self.capacity else 0
        idx = (start + np.arange(self._size)) % self.capacity
        return self.layout.split(self.data[idx])


class PoppingBuffer:
    """Post 001's ``ReplayBuffer``: ``sample`` shuffles the whole deque and pops a batch.

    Sampling without replacement that consumes the buffer. To draw exactly what the post
    drew, ``sample_rows`` shuffles a list of row indices in deque order with
    ``random.Random.shuffle`` (the post calls ``random.shuffle(self.memory)``) and pops the
    first ``batch_size``; new transitions are appended on the right, like ``deque.append``.
    The post's ``maxlen`` argument is ignored (its deque is unbounded); ``capacity`` here is
    preallocation only and is sized by the caller so it is never reached (an error says so
    if it is).
    """

    def __init__(self, capacity: int, layout: Layout, rng):
        self.capacity = int(capacity)
        self.layout = layout
        self.rng = rng  # a random.Random
        self.data = np.zeros((self.capacity, layout.width), dtype=np.float32)
        self.order: list[int] = []  # row indices, oldest first, as the deque holds them
        self._free = list(range(self.capacity - 1, -1, -1))

    def __len__(self) -> int:
        return len(self.order)

    def add_rows(self, rows: np.ndarray) -> None:
        if len(rows) > len(self._free):
            raise ValueError(
                f"PoppingBuffer capacity {self.capacity} exceeded: {len(self.order)} held, "
                f"{len(rows)} more; size it for train_start + the longest episode"
            )
        for row in rows:
            i = self._free.pop()
            self.data[i] = row
            self.order.append(i)

    def state_dict(self) -> dict[str, Any]:
        return {
            "data": self.data.copy(),
            "order": list(self.order),
            "free": list(self._free),
            "rng": rng_state(self.rng),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.data[:] = state["data"]
        self.order, self._free = list(state["order"]), list(state["free"])
        set_rng_state(self.rng, state["rng"])

    def sample_rows(self, batch_size: int) -> np.ndarray:
        if batch_size > len(self.order):
            raise ValueError(f"cannot pop {batch_size} from {len(self.order)}")
        self.rng.shuffle(self.order)
        taken, self.order = self.order[:batch_size], self.order[batch_size:]
        rows = self.data[taken]
        self._free.extend(taken)
        return rows
