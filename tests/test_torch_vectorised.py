"""The vectorised PyTorch engine's core (``keras_rl/torch/vectorised.py``, issue 53): its random
streams, its draw of a batch, a seed's independence of the seeds beside it, and its update against
the tutorial's own code. Eager, on the CPU; ``benchmarks/thousand_seeds.py`` runs it compiled and on
a GPU."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from scipy import stats

torch = pytest.importorskip("torch", reason="needs the torch extra")

from keras_rl.envs import discrete_spec  # noqa: E402
from keras_rl.posts.cartpole import CartPoleDQNConfig  # noqa: E402
from keras_rl.torch.dqn_tutorial import TutorialDQNAgent  # noqa: E402
from keras_rl.torch.vectorised import SeedStreams, VectorisedDQN, distinct  # noqa: E402


@pytest.mark.parametrize("n", [128, 129, 300, 10_000])
def test_a_batch_is_128_distinct_slots_each_equally_likely(n):
    """Floyd's algorithm as ``distinct`` writes it, over 4,000 seeds' draws: every row is 128
    distinct slots of [0, n), and each slot is drawn 128/n of the time (a chi-square test at
    p > 0.001; the seeds are fixed, so this passes or fails the same way every run)."""
    streams = SeedStreams(torch.arange(4000))
    picks = distinct(streams.bits(SeedStreams.SAMPLE, torch.tensor(17), 128), n)
    assert picks.shape == (4000, 128) and int(picks.min()) >= 0 and int(picks.max()) < n
    assert all(len(set(row.tolist())) == 128 for row in picks)
    if n > 128:  # at n = 128 every row is every slot
        counts = torch.bincount(picks.flatten(), minlength=n).numpy()
        assert stats.chisquare(counts).pvalue > 1e-3


def test_a_seeds_streams_are_its_own_uniform_bits():
    alone = SeedStreams(torch.tensor([3]))
    among = SeedStreams(torch.tensor([9, 3, 0]))
    for stream in (SeedStreams.EXPLORE, SeedStreams.SAMPLE, SeedStreams.RESET):
        assert torch.equal(alone.bits(stream, torch.tensor(5), 8)[0], among.bits(stream, torch.tensor(5), 8)[1])
    u = SeedStreams(torch.arange(1000)).uniform64(SeedStreams.EXPLORE, torch.tensor(0), 50).flatten().numpy()
    assert 0 <= u.min() and u.max() < 1 and stats.kstest(u, "uniform").pvalue > 1e-3
    assert not torch.equal(alone.bits(1, torch.tensor(5), 4), alone.bits(2, torch.tensor(5), 4))


def _seed_3(seeds: list[int], steps: int = 400):
    engine = VectorisedDQN([CartPoleDQNConfig(seed=s) for s in seeds])
    ends = [e for _ in range(steps // 200) for e in engine.play(200) if e.seed == 3]
    at = seeds.index(3)
    return [(e.episode, e.steps, e.loss_sum, e.updates) for e in ends], {k: v[at] for k, v in engine.params.items()}


def test_seed_3_plays_the_same_episodes_alone_and_inside_two_different_batches():
    """Issue 53: each seed's streams are its own and independent of S and of the seeds beside it.
    400 steps in two chunks (training from step 128): the episodes, their losses and the weights,
    bit for bit, with seed 3 first, last and between others."""
    alone, weights = _seed_3([3])
    assert len(alone) > 10 and sum(e[3] for e in alone) > 0  # episodes ended and it trained
    for seeds in ([0, 1, 2, 3], [11, 3, 7]):
        episodes, theirs = _seed_3(seeds)
        assert episodes == alone, seeds
        assert all(torch.equal(weights[k], theirs[k]) for k in weights), seeds


def test_it_starts_as_the_tutorial_does_and_updates_as_its_code_does():
    """The same seed's initial policy as the tutorial's agent, bit for bit; then five updates with
    the tutorial's ``learn`` (Huber loss, clip, AdamW with AMSGrad) and soft update on the same
    batches agree to float32 rounding (the order of a few products differs)."""
    config = CartPoleDQNConfig(seed=5)
    env = gym.make("CartPole-v1")
    tutorial = TutorialDQNAgent(config, discrete_spec(env, "post 003"), env.action_space)
    engine = VectorisedDQN([config])
    names = [name for name, _ in tutorial.policy_net.named_parameters()]
    for name in names:
        assert torch.equal(engine.params[name][0], tutorial.policy_net.state_dict()[name])
    rng = np.random.default_rng(0)
    for step in range(1, 6):
        state = torch.tensor(rng.normal(0, 1, (128, 4)), dtype=torch.float32)
        action = torch.tensor(rng.integers(0, 2, 128))
        reward = torch.ones(128)
        next_state = torch.tensor(rng.normal(0, 1, (128, 4)), dtype=torch.float32)
        non_final = torch.tensor(rng.random(128) > 0.1)
        theirs = tutorial.learn(state, action[:, None], reward, non_final, next_state[non_final])
        tutorial.soft_update()
        batch = [x[None] for x in (state, action, reward, next_state, non_final)]
        ours = engine.learn(batch, torch.tensor(float(step), dtype=torch.float64))
        engine.soft_update()
        np.testing.assert_allclose(ours[0].item(), theirs.item(), rtol=1e-6)
    for net, mine in ((tutorial.policy_net, engine.params), (tutorial.target_net, engine.target)):
        for name, p in net.named_parameters():
            np.testing.assert_allclose(mine[name][0].numpy(), p.detach().numpy(), rtol=1e-5, atol=1e-7)


def test_seeds_resume_from_their_own_states_in_any_batch_bit_for_bit():
    """Two seeds played 400 steps straight against the same two cut after 200 (their states taken
    as a checkpoint keeps them, the engine rebuilt from them) and against seed 5 resumed alone:
    the same episodes and weights after the cut."""

    def play(engine, steps):
        return [(e.seed, e.episode, e.steps, e.loss_sum) for e in engine.play(steps)]

    configs = [CartPoleDQNConfig(seed=s) for s in (3, 5)]
    straight = VectorisedDQN(configs)
    play(straight, 200)
    after = play(straight, 200)
    cut = VectorisedDQN(configs)
    play(cut, 200)
    states = cut.seed_states()
    resumed = VectorisedDQN(configs)
    resumed.load_seed_states(states)
    assert play(resumed, 200) == after and resumed.t == straight.t == 400
    alone = VectorisedDQN(configs[1:])
    alone.load_seed_states(states[1:])
    assert play(alone, 200) == [e for e in after if e[0] == 5]
    for k in straight.params:
        assert torch.equal(resumed.params[k], straight.params[k])
        assert torch.equal(alone.params[k][0], straight.params[k][1])
    with pytest.raises(ValueError, match="same step"):
        VectorisedDQN(configs).load_seed_states([states[0], {**states[1], "t": 100}])


def test_a_batch_that_sheds_seeds_plays_the_rest_as_the_whole_batch_does():
    """``keep`` (how a batch sheds the seeds whose runs are done): seeds 3 and 11 of the batch
    [3, 7, 11], kept in the other order after 200 steps, play the next 200 as the whole batch
    plays them, episodes, losses and weights bit for bit; lanes that are not distinct rows of the
    batch are refused."""

    def play(engine, steps):
        return [(e.seed, e.episode, e.steps, e.loss_sum) for e in engine.play(steps)]

    configs = [CartPoleDQNConfig(seed=s) for s in (3, 7, 11)]
    whole, shed = VectorisedDQN(configs), VectorisedDQN(configs)
    play(whole, 200)
    play(shed, 200)
    shed.keep([2, 0])
    assert shed.seeds == [11, 3]
    after = play(whole, 200)
    assert sorted(play(shed, 200)) == sorted(e for e in after if e[0] != 7) and any(e[0] == 11 for e in after)
    for k in whole.params:
        assert torch.equal(shed.params[k], whole.params[k][[2, 0]])
    assert torch.equal(shed.memory["state"], whole.memory["state"][[2, 0]])
    for lanes in ([], [0, 0], [2]):
        with pytest.raises(ValueError, match="not distinct rows of a batch of 2"):
            shed.keep(lanes)


def test_a_cuda_graph_is_refused_on_a_cpu_and_beside_compile():
    """``cuda_graph=True`` records the eager step on a CUDA device (``GraphedStep``; checked bit
    for bit against the eager step where a GPU is lent, by ``benchmarks/thousand_seeds.py
    --cuda-graph``): asked for on a CPU, or with ``compile``, it is refused before anything is built."""
    configs = [CartPoleDQNConfig(seed=0)]
    for kwargs in ({"device": "cpu"}, {"device": "cpu", "compile": True}):
        with pytest.raises(ValueError, match="cuda_graph records the eager step on a CUDA device"):
            VectorisedDQN(configs, cuda_graph=True, **kwargs)


def test_batch_after_batch_in_one_process_stays_within_two_programs_per_size(monkeypatch):
    """The compiled step's programs are keyed by shape, per process (a pool worker builds engine
    after engine). A batch of 3 played in chunks of many lengths, before and after its memory
    trains, shedding to 2 seeds and to 1: four programs (3 seeds before and after training, 2 and
    1 after), within the 2 x 3 its engine adds to the limit; two more batches in the same process
    compile none. Past the limit torch fails rather than fall back (the certification's 40 errored
    seeds met a limit of 64 this way, when the records' length followed each chunk's: eight
    programs here). Dynamo's own backend, ``eager``: the programs and guards are dynamo's, and no
    inductor compile is paid."""
    import functools

    from torch._dynamo.eval_frame import _debug_get_cache_entry_list
    from torch._dynamo.utils import counters

    import keras_rl.torch.vectorised as vectorised

    torch._dynamo.reset()  # no programs from another test of this process
    compiled_before = counters["stats"]["unique_graphs"]  # counted over the process, through resets
    monkeypatch.setattr(torch, "compile", functools.partial(torch.compile, backend="eager"))
    monkeypatch.setattr(vectorised, "RECOMPILE_LIMIT", 0)
    monkeypatch.setattr(torch._dynamo.config, "recompile_limit", 0)
    monkeypatch.setattr(torch._dynamo.config, "accumulated_recompile_limit", 0)
    monkeypatch.setattr(torch._dynamo.config, "fail_on_recompile_limit_hit", False)

    def programs() -> tuple[int, int]:
        """The step's programs held, and compiled since the reset."""
        held = _debug_get_cache_entry_list(VectorisedDQN._train_step.__code__)
        return len(held), counters["stats"]["unique_graphs"] - compiled_before

    def batch(seeds):
        engine = VectorisedDQN([CartPoleDQNConfig(seed=s) for s in seeds], compile=True, chunk=50)
        assert torch._dynamo.config.recompile_limit == 6 * (seeds[0] // 3 + 1)  # 2 x 3 more per engine
        for steps in (1, 3, 50, 20, 7, 50):  # the 128th step trains: both programs
            engine.play(steps)
        for lanes in ([2, 0], [1]):
            engine.keep(lanes)
            for steps in (1, 30, 4):
                engine.play(steps)

    try:
        for seeds in ([0, 1, 2], [3, 4, 5], [6, 7, 8]):
            batch(seeds)
            assert programs() == (4, 4), seeds
        four = VectorisedDQN([CartPoleDQNConfig(seed=s) for s in range(4)], compile=True, chunk=50)
        assert torch._dynamo.config.fail_on_recompile_limit_hit
        torch._dynamo.config.recompile_limit = 4
        with pytest.raises(torch._dynamo.exc.FailOnRecompileLimitHit):  # a fifth program fails
            four.play(1)
    finally:
        torch._dynamo.reset()
