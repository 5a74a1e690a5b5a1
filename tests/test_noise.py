import numpy as np

from keras_rl.agents.explorers import OUNoise

SIGMA_STEP = 0.2 * np.sqrt(0.1)


def post_ou_noise(x, eps, rho=0.15, mu=0, dt=1e-1, sigma=0.2):
    """Post 000 §2.3.2's formula with the Gaussian draw passed in."""
    return x + rho * (mu - x) * dt + sigma * np.sqrt(dt) * eps


def test_post_variant_matches_the_posts_loop_exactly():
    # §2.4: pre_noise = zeros at episode start, never reassigned within the episode.
    noise = OUNoise(1, np.random.default_rng(7), carry_state=False)
    draws = np.random.default_rng(7).normal(size=(50, 1))
    noise.reset()
    pre_noise = np.zeros(1)
    for eps in draws:
        np.testing.assert_allclose(noise(), post_ou_noise(pre_noise, eps))


def test_post_variant_is_iid_gaussian_with_sigma_0_2_sqrt_0_1():
    noise = OUNoise(1, np.random.default_rng(0), carry_state=False)
    xs = np.array([noise()[0] for _ in range(20000)])
    assert abs(xs.mean()) < 0.003
    assert abs(xs.std() - SIGMA_STEP) < 0.002
    lag1 = np.corrcoef(xs[:-1], xs[1:])[0, 1]
    assert abs(lag1) < 0.03  # no memory: each step starts from zero


def test_real_ou_carries_state_and_resets():
    noise = OUNoise(1, np.random.default_rng(3), carry_state=True)
    draws = np.random.default_rng(3).normal(size=(30, 1))
    x = np.zeros(1)
    for eps in draws:
        x = post_ou_noise(x, eps)
        np.testing.assert_allclose(noise(), x)
    noise.reset()
    np.testing.assert_array_equal(noise.state, np.zeros(1))


def test_real_ou_is_strongly_autocorrelated():
    noise = OUNoise(1, np.random.default_rng(0), carry_state=True)
    xs = np.array([noise()[0] for _ in range(20000)])
    lag1 = np.corrcoef(xs[:-1], xs[1:])[0, 1]
    assert lag1 > 0.95  # 1 - theta*dt = 0.985
    # stationary std sigma*sqrt(dt/(2*theta*dt - (theta*dt)^2)) ~ 0.365, far above the post's 0.063
    assert xs.std() > 3 * SIGMA_STEP
