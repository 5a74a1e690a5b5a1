"""The PyTorch ports of posts 000 and 001 against the Keras learners: same weights, same
batch, one update, every weight within atol 1e-5 (issue #5)."""

import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="parity tests need the torch extra")

import keras  # noqa: E402
import tensorflow as tf  # noqa: E402

from keras_rl.envs import EnvSpec  # noqa: E402
from keras_rl.errors import ConfigError, RunFolderError  # noqa: E402
from keras_rl.posts.cartpole import CartPoleDQNConfig  # noqa: E402
from keras_rl.posts.mountaincar import MountainCarDDPGConfig  # noqa: E402
from keras_rl.posts.pendulum import PendulumDDPGConfig  # noqa: E402
from keras_rl.registry import agent_for  # noqa: E402
from keras_rl.seeding import seed_everything  # noqa: E402
from keras_rl.torch.networks import KerasBatchNorm  # noqa: E402
from keras_rl.torch.optimizers import KerasAdam  # noqa: E402

ATOL = 1e-5
LOW, HIGH = np.array([-1.2, -0.07]), np.array([0.6, 0.07])


def max_abs_difference(module, keras_model) -> float:
    """The largest |torch - Keras| over every paired weight (for parity tests)."""
    worst = 0.0
    for tensor, variable, transpose in module.keras_pairs(keras_model):
        value = np.asarray(variable.numpy())
        value = value.T if transpose else value
        worst = max(worst, float(np.max(np.abs(tensor.detach().numpy() - value))))
    return worst


def pendulum(config):
    return agent_for(config, EnvSpec(3, 1, 2.0))


def mountaincar(config):
    return agent_for(config, EnvSpec(2, 1, 1.0, obs_low=LOW, obs_high=HIGH, max_episode_steps=999))


def twins(make, config):
    """A Keras agent and a torch agent (matched init) built as ``run_seed`` builds them."""
    seed_everything(config.seed)
    keras_agent = make(config)
    seed_everything(config.seed)
    torch_agent = make(config.replace(framework="torch", matched_init=True))
    return keras_agent.learner, torch_agent.learner


def networks(keras_learner, torch_learner):
    return {
        name: (getattr(torch_learner, name), getattr(keras_learner, name))
        for name in ("actor", "critic", "target_actor", "target_critic")
    }


def random_rows(batch, obs_dim, seed=0, done_share=0.3):
    rng = np.random.default_rng(seed)
    return np.concatenate(
        [
            rng.normal(size=(batch, obs_dim)),
            rng.uniform(-1, 1, (batch, 1)),
            rng.normal(size=(batch, 1)),
            rng.normal(size=(batch, obs_dim)),
            rng.uniform(size=(batch, 1)) < done_share,
        ],
        axis=1,
    ).astype(np.float32)


CASES = [
    (PendulumDDPGConfig, "faithful", pendulum, 64, 3),
    (PendulumDDPGConfig, "fixed", pendulum, 64, 3),
    (MountainCarDDPGConfig, "faithful", mountaincar, 32, 2),  # dpg_literal, dQ/da at buffer actions
    (MountainCarDDPGConfig, "faithful-intended", mountaincar, 32, 2),
    (MountainCarDDPGConfig, "fixed", mountaincar, 32, 2),
]


@pytest.mark.parametrize(
    "config_cls,variant,make,batch,obs_dim", CASES, ids=[f"{c.experiment}-{v}" for c, v, *_ in CASES]
)
@pytest.mark.slow
def test_one_update_agrees_with_keras(config_cls, variant, make, batch, obs_dim):
    keras_learner, torch_learner = twins(make, config_cls.for_variant(variant, seed=3))
    nets = networks(keras_learner, torch_learner)
    assert all(max_abs_difference(t, k) == 0.0 for t, k in nets.values())  # matched init copies exactly
    initial = {name: [v.numpy() for v in k.weights] for name, (_, k) in nets.items()}
    rows = random_rows(batch, obs_dim)
    keras_losses = keras_learner.train(rows)
    torch_losses = torch_learner.train(rows)
    for name in ("critic_loss", "actor_loss"):
        assert float(torch_losses[name]) == pytest.approx(float(keras_losses[name]), rel=1e-5, abs=ATOL)
    for name, (t, k) in nets.items():
        gap = max_abs_difference(t, k)
        moved = max(float(np.max(np.abs(v.numpy() - w))) for v, w in zip(k.weights, initial[name]))
        assert gap <= ATOL, (name, gap)
        if not name.startswith("target"):  # (a target moves by tau times that: 1e-3 of it)
            # small against how far the update moved the network: not two networks that barely changed
            assert gap < 0.02 * moved, (name, gap, moved)


def test_the_broadcast_target_is_the_same_64_by_64_matrix_in_both():
    keras_learner, torch_learner = twins(pendulum, PendulumDDPGConfig(seed=5))
    rows = random_rows(64, 3, seed=1)
    k_batch = keras_learner.layout.split(tf.constant(rows))
    t_batch = torch_learner.layout.split(torch.from_numpy(rows))
    k_targets = keras_learner.td_targets(*k_batch[2:]).numpy()
    t_targets = torch_learner.td_targets(*t_batch[2:]).numpy()
    assert k_targets.shape == t_targets.shape == (64, 64)
    np.testing.assert_allclose(t_targets, k_targets, atol=1e-6)  # the networks' float rounding only
    # With Q' made exactly representable in both (a constant critic), the (B,B) arithmetic
    # itself is bit-identical: targets[i, j] = r_i + gamma * Q'_i * (1 - d_j).
    for v in keras_learner.target_critic.weights:
        v.assign(tf.zeros_like(v) + (0.5 if v is keras_learner.target_critic.out.bias else 0.0))
    with torch.no_grad():
        for p in torch_learner.target_critic.parameters():
            p.zero_()
        torch_learner.target_critic.out.bias.fill_(0.5)
    k_targets = keras_learner.td_targets(*k_batch[2:]).numpy()
    t_targets = torch_learner.td_targets(*t_batch[2:]).numpy()
    np.testing.assert_array_equal(t_targets, k_targets)
    r, d = rows[:, 4], rows[:, -1]
    np.testing.assert_array_equal(t_targets, (r[:, None] + np.float32(0.99) * np.float32(0.5) * (1 - d[None, :])))


def test_keras_adam_follows_keras_arithmetic_where_torch_adam_does_not():
    # Tiny gradients are where the two epsilon placements differ.
    grads = [np.array([1e-7, -3e-6, 2e-4, 0.3], np.float32), np.array([5e-7, -1e-7, 1e-5, -0.02], np.float32)]
    k_var = keras.Variable(np.zeros(4, np.float32))
    k_opt = keras.optimizers.Adam(learning_rate=1e-3)
    t_param = torch.nn.Parameter(torch.zeros(4))
    t_opt = KerasAdam([t_param], lr=1e-3)
    plain = torch.nn.Parameter(torch.zeros(4))
    plain_opt = torch.optim.Adam([plain], lr=1e-3, eps=1e-7)
    for g in grads:
        k_opt.apply_gradients([(tf.constant(g), k_var)])
        for p, opt in ((t_param, t_opt), (plain, plain_opt)):
            p.grad = torch.from_numpy(g.copy())
            opt.step()
    np.testing.assert_allclose(t_param.detach().numpy(), k_var.numpy(), rtol=1e-4, atol=5e-8)  # float32 rounding
    assert np.max(np.abs(plain.detach().numpy() - k_var.numpy())) > 1e-5  # why KerasAdam exists
    with pytest.raises(ValueError, match="learning rate must be positive"):
        KerasAdam([t_param], lr=-1e-3)


def test_keras_batch_norm_matches_keras_in_both_learning_phases():
    x = np.random.default_rng(0).normal(2.0, 3.0, size=(16, 2)).astype(np.float32)
    for phase in (False, True):
        k_bn = keras.layers.BatchNormalization()
        k_out = k_bn(tf.constant(x), training=phase).numpy()
        t_bn = KerasBatchNorm(2, training=phase)
        t_out = t_bn(torch.from_numpy(x)).detach().numpy()
        np.testing.assert_allclose(t_out, k_out, atol=1e-5)
        np.testing.assert_allclose(t_bn.running_var.numpy(), k_bn.moving_variance.numpy(), atol=1e-6)
        np.testing.assert_allclose(t_bn.running_mean.numpy(), k_bn.moving_mean.numpy(), atol=1e-6)


def test_learning_phase_zero_means_no_input_noise_in_torch_too():
    config = MountainCarDDPGConfig(framework="torch", seed=0)
    learner = mountaincar(config).learner
    state = np.array([0.3, 0.5], np.float32)
    assert np.array_equal(learner.act(state), learner.act(state))  # GaussianNoise(1.0) is off
    noisy = mountaincar(config.replace(learning_phase_training=True)).learner
    assert not np.array_equal(
        noisy.actor(torch.ones(8, 2)).detach().numpy(), noisy.actor(torch.ones(8, 2)).detach().numpy()
    )


def test_default_init_is_each_frameworks_own():
    seed_everything(0)
    keras_learner = pendulum(PendulumDDPGConfig(seed=0)).learner
    seed_everything(0)
    torch_learner = pendulum(PendulumDDPGConfig(seed=0, framework="torch")).learner
    assert max_abs_difference(torch_learner.actor, keras_learner.actor) > 0.01
    assert np.all(keras_learner.actor.out.bias.numpy() == 0)  # Keras: zero biases
    bound = 1 / np.sqrt(64)
    bias = torch_learner.actor.out.bias.detach().numpy()
    assert np.all(np.abs(bias) <= bound) and np.any(bias != 0)  # nn.Linear: U(-1/sqrt(fan_in), ..)
    # faithful P000-TARGETINIT: the target is not a copy in torch either; fixed: it is
    faithful_gap = max_abs_difference(torch_learner.target_actor, keras_learner.target_actor)
    fixed = pendulum(
        PendulumDDPGConfig(seed=0, framework="torch", variant="fixed", **PendulumDDPGConfig.VARIANTS["fixed"])
    ).learner
    assert faithful_gap > 0.01
    assert all(torch.equal(a, b) for a, b in zip(fixed.actor.parameters(), fixed.target_actor.parameters()))
    seed_everything(0)
    again = pendulum(PendulumDDPGConfig(seed=0, framework="torch")).learner
    assert all(torch.equal(a, b) for a, b in zip(again.actor.parameters(), torch_learner.actor.parameters()))


def test_cartpole_matched_init_copies_the_keras_q_network():
    from keras_rl.torch.dqn_tutorial import TutorialDQNAgent

    space = __import__("gymnasium").spaces.Discrete(2)
    seed_everything(4)
    k = agent_for(CartPoleDQNConfig(seed=4), EnvSpec(4, 1, n_actions=2), space).learner.q_network
    seed_everything(4)
    t = TutorialDQNAgent(
        CartPoleDQNConfig(seed=4, framework="torch", matched_init=True), EnvSpec(4, 1, n_actions=2), space
    )
    np.testing.assert_array_equal(t.policy_net.layer1.weight.detach().numpy(), k.dense[0].kernel.numpy().T)
    np.testing.assert_array_equal(t.target_net.layer3.bias.detach().numpy(), k.dense[2].bias.numpy())


def test_matched_init_needs_the_torch_framework():
    with pytest.raises(ConfigError, match="matched_init .* needs framework 'torch'"):
        PendulumDDPGConfig(matched_init=True).validate()


def test_torch_checkpoints_round_trip_and_a_corrupt_one_is_named(tmp_path):
    learner = pendulum(PendulumDDPGConfig(framework="torch", seed=1)).learner
    learner.save(tmp_path)
    other = pendulum(PendulumDDPGConfig(framework="torch", seed=2)).learner
    other.load_policy(tmp_path)
    state = np.array([0.1, -0.2, 0.3], np.float32)
    assert np.array_equal(other.act(state), learner.act(state))
    (tmp_path / "actor.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(RunFolderError, match="actor.pt could not be loaded"):
        other.load_policy(tmp_path)
    (tmp_path / "actor.pt").unlink()
    with pytest.raises(RunFolderError, match="actor.pt is missing"):
        other.load_policy(tmp_path)
