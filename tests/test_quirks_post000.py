"""Each post-000 quirk switch, shown by its effect (see reproductions/FIDELITY.md)."""

import keras
import numpy as np
import pytest

from keras_rl.envs import EnvSpec
from keras_rl.learners.networks import Actor
from keras_rl.posts.pendulum import PendulumDDPGConfig
from keras_rl.registry import agent_for
from keras_rl.seeding import seed_everything

OBS = np.array([1.0, 0.0, 0.5], np.float32)


def make_agent(variant="faithful", **overrides):
    seed_everything(0)
    return agent_for(PendulumDDPGConfig.for_variant(variant, **overrides), EnvSpec(3, 1, 2.0))


def noise_sequence(agent, n=2000):
    agent.begin_episode(OBS)
    return np.array([agent.explorer.noise()[0] for _ in range(n)])


def test_P000_NOISE_faithful_noise_restarts_from_zero_every_step():
    faithful, fixed = noise_sequence(make_agent("faithful")), noise_sequence(make_agent("fixed"))
    assert abs(np.corrcoef(faithful[:-1], faithful[1:])[0, 1]) < 0.1
    assert faithful.std() == pytest.approx(0.2 * np.sqrt(0.1), rel=0.1)
    assert np.corrcoef(fixed[:-1], fixed[1:])[0, 1] > 0.9


def test_P000_NOISE_fixed_noise_resets_each_episode():
    agent = make_agent("fixed")
    noise_sequence(agent, 100)
    assert np.any(agent.explorer.noise.state != 0)
    agent.begin_episode(OBS)  # §2.4 resets pre_noise at every episode start; so does OUNoise.reset
    # after begin_episode one draw has been taken from a zero state
    assert abs(agent.explorer.noise.state[0]) < 5 * 0.2 * np.sqrt(0.1)


@pytest.mark.parametrize("variant,on_truncation,on_termination", [("faithful", 1.0, 0.0), ("fixed", 0.0, 1.0)])
def test_P000_DONE_which_flag_is_stored_as_terminal(variant, on_truncation, on_termination):
    agent = make_agent(variant)
    agent.begin_episode(OBS)
    agent.step(-1.0, OBS, terminated=False, truncated=True)  # Pendulum's time limit
    agent.begin_episode(OBS)
    agent.step(-1.0, OBS, terminated=True, truncated=False)  # a true terminal (other envs)
    np.testing.assert_array_equal(agent.buffer.ordered().dones, [on_truncation, on_termination])


def test_P000_TARGETINIT_unbuilt_subclassed_models_have_no_weights():
    # Why the post's update_target_networks(1.0) is a no-op: it runs before any call.
    assert Actor(1, 2.0).get_weights() == []
    target = Actor(1, 2.0)
    target.set_weights(Actor(1, 2.0).get_weights())  # "copies" nothing, raises nothing


def test_P000_TARGETINIT_faithful_targets_start_independent_fixed_start_equal():
    faithful, fixed = make_agent("faithful"), make_agent("fixed")
    for agent, same in ((faithful, False), (fixed, True)):
        for online, target in (
            (agent.learner.actor, agent.learner.target_actor),
            (agent.learner.critic, agent.learner.target_critic),
        ):
            equal = all(np.array_equal(a, b) for a, b in zip(online.get_weights(), target.get_weights()))
            assert equal is same


def test_stored_action_is_the_clipped_noisy_action():
    agent = make_agent("faithful", noise_sigma=50.0)  # noise far beyond the bound
    executed = [agent.begin_episode(OBS)]
    for _ in range(30):
        executed.append(agent.step(-1.0, OBS, False, False))
    stored = agent.buffer.ordered().actions[:, 0]
    np.testing.assert_array_equal(stored, np.concatenate(executed[:-1]))
    assert np.all(np.abs(stored) <= 2.0) and np.any(np.abs(stored) == 2.0)
    greedy = agent.greedy_action(OBS)
    assert np.any(stored != greedy[0])


def test_training_runs_every_step_from_train_start():
    agent = make_agent("faithful", train_start=100, batch_size=16)
    agent.begin_episode(OBS)
    for step in range(1, 131):
        agent.step(-1.0, OBS, False, False)
        assert agent.updates == max(0, step - 99)  # first update when len(memory) >= 100


@pytest.mark.slow
def test_stop_at_threshold_ends_the_run_at_the_first_crossing(tmp_path):
    from keras_rl.registry import get_experiment
    from keras_rl.train.loop import run_seed
    from keras_rl.train.settings import TrainSettings

    exp = get_experiment("pendulum")
    config = PendulumDDPGConfig.for_variant("faithful", threshold=-1e9, episodes=5, train_start=2000)
    summary = run_seed(exp, config, tmp_path / "stop", TrainSettings(progress=False))
    assert summary.reached_at_episode == 1 and summary.episodes_run == 1
    config = config.replace(stop_at_threshold=False, episodes=3)
    summary = run_seed(exp, config, tmp_path / "go-on", TrainSettings(progress=False))
    assert summary.reached_at_episode == 1 and summary.episodes_run == 3


def test_tensorflow_backend_is_pinned():
    assert keras.backend.backend() == "tensorflow"


def test_P000_TEST_the_post_test_section_lines():
    """§3's lines that `evaluate` does not copy (FIDELITY P000-TEST-*), shown doing what the ledger says."""
    import keras

    # P000-TEST-SCORE: env.step((action,)) gives a (1,) reward, so score becomes an ndarray ...
    env = __import__("gymnasium").make("Pendulum-v1", g=10)
    env.reset(seed=0)
    _, reward, _, _, _ = env.step((np.array([0.0], np.float32),))
    score = 0
    score += reward
    assert isinstance(score, np.ndarray) and score.shape == (1,)
    # ... and "{:3f}".format of a 1-element ndarray raises on numpy 2
    with pytest.raises(TypeError):
        f"episode: {0:3d} | score: {score:3f}"
    # P000-TEST-SAVE: Keras 3's save_weights takes no save_format and wants a .weights.h5 name
    agent = make_agent("faithful")
    with pytest.raises((TypeError, ValueError)):
        agent.learner.actor.save_weights("./save_model/model", save_format="tf")
    # P000-TEST-EPSILON: nothing in the agent reads an epsilon: setting it changes no action
    state = np.array([0.1, 0.2, 0.3], np.float32)
    before = agent.greedy_action(state)
    agent.epsilon = 0.01
    np.testing.assert_array_equal(agent.greedy_action(state), before)
    assert isinstance(keras.__version__, str)
