import numpy as np
import pytest

from keras_rl.buffers import Batch, Layout, ReplayBuffer

LAYOUT = Layout(obs_dim=3, action_dim=1)


def fill(buffer, n, start=0):
    """Transitions ``start .. start + n - 1`` one row at a time, as the training loop adds them."""
    for i in range(start, start + n):
        buffer.add_rows(LAYOUT.pack(([np.full(3, i)], [[i + 0.5]], [float(-i)], [np.full(3, i + 1)], [i % 7 == 0])))


def test_fifo_eviction_like_deque_maxlen(rng):
    buffer = ReplayBuffer(5, LAYOUT, rng)
    fill(buffer, 8)
    assert len(buffer) == 5
    batch = buffer.ordered()
    # deque(maxlen=5) after appending 0..7 holds 3..7, oldest first
    np.testing.assert_array_equal(batch.rewards, [-3, -4, -5, -6, -7])
    np.testing.assert_array_equal(batch.states[:, 0], [3, 4, 5, 6, 7])
    np.testing.assert_array_equal(batch.next_states[:, 0], [4, 5, 6, 7, 8])
    np.testing.assert_array_equal(batch.actions[:, 0], [3.5, 4.5, 5.5, 6.5, 7.5])
    np.testing.assert_array_equal(batch.dones, [0, 0, 0, 0, 1])


def test_storage_is_preallocated_once(rng):
    buffer = ReplayBuffer(100, LAYOUT, rng)
    data = buffer.data
    fill(buffer, 250)
    assert buffer.data is data and data.shape == (100, LAYOUT.width) and data.dtype == np.float32


def test_sample_without_replacement_like_random_sample(rng):
    buffer = ReplayBuffer(50, LAYOUT, rng)
    fill(buffer, 50)
    for _ in range(20):
        batch = buffer.sample(50)  # the whole buffer: every row exactly once
        assert sorted(batch.states[:, 0]) == list(range(50))
    with pytest.raises(ValueError, match="without replacement"):
        buffer.sample(51)


def test_sample_with_replacement_repeats(rng):
    buffer = ReplayBuffer(10, LAYOUT, rng)
    fill(buffer, 10)
    batch = buffer.sample(200, replace=True)
    assert len(set(batch.states[:, 0])) <= 10


def test_sampling_is_uniform_over_stored_rows(rng):
    buffer = ReplayBuffer(20, LAYOUT, rng)
    fill(buffer, 30)  # rows 10..29 remain
    counts = np.zeros(40)
    for _ in range(2000):
        for s in buffer.sample(5).states[:, 0]:
            counts[int(s)] += 1
    assert counts[:10].sum() == 0
    assert counts[10:30].min() > 0.8 * 500 and counts[10:30].max() < 1.2 * 500


def test_layout_pack_split_roundtrip(rng):
    batch = Batch(
        rng.normal(size=(4, 3)),
        rng.normal(size=(4, 1)),
        rng.normal(size=4),
        rng.normal(size=(4, 3)),
        np.array([0, 1, 0, 0]),
    )
    back = LAYOUT.split(LAYOUT.pack(batch))
    for a, b in zip(batch, back):
        np.testing.assert_allclose(np.asarray(a, np.float32).reshape(np.shape(b)), b)
