"""PyTorch's portable arithmetic (``KERAS_RL_PORTABLE_TORCH=1``, ``keras_rl.torch.portable_arithmetic``):
the switch, its bad input, and what it changes. That it gives one set of bits on every CPU with AVX2
is measured under the emulator (``tests/replay_references/portable-torch/emulation-*.md``) and
replayed on every host by ``tests/test_committed_runs_replay.py``."""

from __future__ import annotations

import re
import subprocess
import sys

import gymnasium as gym
import pytest

from keras_rl.envs import discrete_spec
from keras_rl.errors import ConfigError
from keras_rl.posts.cartpole import CartPoleDQNConfig
from keras_rl.torch import PORTABLE_CAPS, PORTABLE_SWITCH, portable_arithmetic

torch = pytest.importorskip("torch", reason="needs the torch extra")

from keras_rl.torch import dqn_tutorial, optimizers, stacked, vectorised  # noqa: E402


@pytest.fixture
def env(monkeypatch):
    """A process environment without the switch or its caps (restored after), read afresh."""
    for key in (PORTABLE_SWITCH, *PORTABLE_CAPS):
        monkeypatch.delenv(key, raising=False)
    portable_arithmetic.cache_clear()
    yield monkeypatch
    portable_arithmetic.cache_clear()


@pytest.mark.parametrize("value", [None, "", "0"])
def test_unset_or_zero_is_torchs_own_arithmetic(env, value):
    if value is not None:
        env.setenv(PORTABLE_SWITCH, value)
    assert portable_arithmetic() is False
    assert all(key not in __import__("os").environ for key in PORTABLE_CAPS)


@pytest.mark.parametrize(
    "setting, message",
    [
        ({PORTABLE_SWITCH: "yes"}, "is 1 (portable arithmetic) or unset, not 'yes'"),
        ({PORTABLE_SWITCH: "1", "MKL_CBWR": "AVX2"}, "this environment has MKL_CBWR=AVX2"),
        ({PORTABLE_SWITCH: "1", "ATEN_CPU_CAPABILITY": "avx512"}, "this environment has ATEN_CPU_CAPABILITY=avx512"),
        ({PORTABLE_SWITCH: "1"}, "must be set before torch is imported"),  # it is, in this process
    ],
)
def test_bad_settings_are_named(env, setting, message):
    for key, value in setting.items():
        env.setenv(key, value)
    with pytest.raises(ConfigError, match=re.escape(message)):
        portable_arithmetic()


def test_the_switch_sets_its_caps_before_torch_is_imported(env):
    import os

    env.setenv(PORTABLE_SWITCH, "1")
    env.delitem(sys.modules, "torch")  # as in a fresh process, before its first torch import
    assert portable_arithmetic() is True
    assert {key: os.environ[key] for key in PORTABLE_CAPS} == PORTABLE_CAPS
    env.setitem(sys.modules, "torch", torch)
    portable_arithmetic.cache_clear()
    assert portable_arithmetic() is True  # the caps already set: a process that set them itself


def keras_adam_steps(fused: bool, monkeypatch, steps: int = 5) -> list:
    """A small net's weights after ``steps`` of ``KerasAdam`` on gradients near 1e-6, where Keras'
    epsilon placement matters."""
    monkeypatch.setattr(optimizers, "portable_arithmetic", lambda: fused)
    torch.manual_seed(0)
    net = torch.nn.Linear(8, 4)
    adam = optimizers.KerasAdam(net.parameters(), lr=1e-3)
    assert bool(adam.param_groups[0].get("fused")) is fused
    x = torch.randn(32, 8, generator=torch.Generator().manual_seed(1))
    for _ in range(steps):
        adam.zero_grad()
        (1e-6 * net(x).square().mean()).backward()
        adam.step()
    return [p.detach().clone() for p in net.parameters()]


def test_the_fused_step_is_keras_adam_too(monkeypatch):
    """Under the switch ``KerasAdam`` takes torch's fused step with the same per-step epsilon: its
    weights agree with the native step's to float32 rounding, and a constant epsilon (torch's own
    placement) is further off than that."""
    fused, native = keras_adam_steps(True, monkeypatch), keras_adam_steps(False, monkeypatch)
    gap = max(float((a - b).abs().max()) for a, b in zip(fused, native, strict=True))
    assert gap <= 1e-6
    torch.manual_seed(0)
    net = torch.nn.Linear(8, 4)
    plain = torch.optim.Adam(net.parameters(), lr=1e-3, eps=1e-7)
    x = torch.randn(32, 8, generator=torch.Generator().manual_seed(1))
    for _ in range(5):
        plain.zero_grad()
        (1e-6 * net(x).square().mean()).backward()
        plain.step()
    off = max(float((a - b.detach()).abs().max()) for a, b in zip(native, net.parameters(), strict=True))
    assert off > 10 * max(gap, 1e-9)


def test_the_tutorials_adamw_takes_the_fused_step_under_the_switch(monkeypatch):
    spec_env = gym.make("CartPole-v1")
    for portable in (False, True):
        monkeypatch.setattr(dqn_tutorial, "portable_arithmetic", lambda portable=portable: portable)
        agent = dqn_tutorial.TutorialDQNAgent(CartPoleDQNConfig(seed=0), discrete_spec(spec_env, "post 003"), None)
        group = agent.optimizer.param_groups[0]
        assert bool(group.get("fused")) is portable and group["amsgrad"]


@pytest.mark.parametrize("made_fused", [False, True])
def test_a_checkpoint_resumes_only_under_the_arithmetic_it_was_made_with(monkeypatch, made_fused):
    """A run resumed across the switch would mix two arithmetics: refused before the learner loads
    anything (its network keeps its weights)."""
    spec_env = gym.make("CartPole-v1")
    spec = discrete_spec(spec_env, "post 003")

    def agent(portable: bool, seed: int):
        for module in (dqn_tutorial, optimizers):
            monkeypatch.setattr(module, "portable_arithmetic", lambda: portable)
        return dqn_tutorial.TutorialDQNAgent(CartPoleDQNConfig(seed=seed), spec, None)

    state = agent(made_fused, 0).state_dict()
    agent(made_fused, 1).load_state_dict(state)  # the same arithmetic: fine
    resumed = agent(not made_fused, 1)
    before = [p.detach().clone() for p in resumed.policy_net.parameters()]
    made = "with" if made_fused else "without"
    with pytest.raises(ConfigError, match=f"made {made} the portable arithmetic"):
        resumed.load_state_dict(state)
    assert all(torch.equal(a, b) for a, b in zip(before, resumed.policy_net.parameters(), strict=True))


def test_engines_that_write_their_own_step_refuse_the_switch(monkeypatch):
    monkeypatch.setattr(optimizers, "portable_arithmetic", lambda: True)
    with pytest.raises(ConfigError, match="the vectorised engine writes its own optimizer step"):
        vectorised.VectorisedDQN([CartPoleDQNConfig(seed=0)])
    with pytest.raises(ConfigError, match="the seed-batched PyTorch DDPG writes its own optimizer step"):
        stacked.StackedTorchDDPGLearner([], actor_lr=1e-3, critic_lr=1e-3)


def test_a_bad_switch_exits_2_before_anything_is_written(tmp_path):
    import os

    out = tmp_path / "run"
    argv = ["--seeds", "0", "--episodes", "1", "--framework", "torch", "--no-progress", "--out", str(out)]
    proc = subprocess.run(
        [sys.executable, "-m", "keras_rl", "reproduce", "cartpole", *argv],
        capture_output=True,
        text=True,
        env={**os.environ, PORTABLE_SWITCH: "true"},
        timeout=300,
    )
    assert proc.returncode == 2, proc.stderr
    assert f"{PORTABLE_SWITCH} is 1 (portable arithmetic) or unset, not 'true'" in proc.stderr
    assert not out.exists()
