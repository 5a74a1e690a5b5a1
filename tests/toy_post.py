"""A fourth post in one file, for ``tests/test_fourth_post.py``: a tiny env, its config, a tiny
learner (NumPy, no TensorFlow) and its agent parts, registered with ``keras_rl.registry.register``
without touching any file under ``keras_rl/``."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from keras_rl.agents.explorers import EpsilonGreedy, decaying_epsilon
from keras_rl.agents.schedules import EveryStep
from keras_rl.agents.skeleton import Agent
from keras_rl.agents.transitions import TransitionRule
from keras_rl.buffers import Layout, ReplayBuffer
from keras_rl.config import ExperimentConfig, positive, unit
from keras_rl.envs import discrete_spec
from keras_rl.experiment import Experiment
from keras_rl.metrics import RollingMean


class Corridor(gym.Env):
    """Walk a corridor of 6 cells from the middle; reaching the right end pays 1 and ends the
    episode, the left end ends it with nothing; at most 12 steps."""

    def __init__(self):
        self.observation_space = gym.spaces.Box(0.0, 5.0, shape=(1,), dtype=np.float32)
        self.action_space = gym.spaces.Discrete(2)
        self.position, self.steps = 3, 0

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.position, self.steps = int(self.np_random.integers(2, 4)), 0
        return np.array([self.position], np.float32), {}

    def step(self, action):
        self.position += 1 if int(action) == 1 else -1
        self.steps += 1
        terminated = self.position in (0, 5)
        reward = 1.0 if self.position == 5 else 0.0
        return np.array([self.position], np.float32), reward, terminated, self.steps >= 12 and not terminated, {}


@dataclass(frozen=True)
class ToyConfig(ExperimentConfig):
    experiment: ClassVar[str] = "toy"
    post: ClassVar[str] = "a toy post of the tests"

    episodes: int = positive(6)
    threshold: float = 0.5
    """The 3-episode mean return: success once it reaches 0.5."""
    buffer_size: int = positive(64)
    batch_size: int = positive(4)
    train_start: int = positive(8)
    lr: float = positive(0.1)
    gamma: float = unit(0.9)
    stop_at_threshold: bool = False


class TableLearner:
    """Q-learning on a table indexed by the (integer) position: the Learner protocol in NumPy."""

    loss_names = ("loss",)

    def __init__(self, config: ToyConfig, spec):
        self.lr, self.gamma = config.lr, config.gamma
        self.q = np.random.default_rng(config.seed).normal(0.0, 0.01, (6, spec.n_actions))

    def compile(self) -> None:
        """Nothing to trace: NumPy runs eagerly (the Learner protocol asks every learner)."""

    def train(self, rows: np.ndarray) -> dict[str, float]:
        s, a, r = rows[:, 0].astype(int), rows[:, 1].astype(int), rows[:, 2]
        s2, done = rows[:, 3].astype(int), rows[:, 4]
        target = r + self.gamma * (1.0 - done) * self.q[s2].max(axis=1)
        error = target - self.q[s, a]
        np.add.at(self.q, (s, a), self.lr * error)
        return {"loss": float(np.mean(error**2))}

    def act(self, state: np.ndarray) -> int:
        return int(np.argmax(self.q[int(state[0])]))

    def train_and_act(self, rows, state):
        return self.train(rows), self.act(state)

    def step_without_batch(self, state, want_action: bool):
        return self.act(state) if want_action else None

    def save(self, run_dir: Path) -> None:
        (Path(run_dir) / "q.json").write_text(json.dumps(self.q.tolist()))

    def load_policy(self, run_dir: Path) -> None:
        self.q = np.array(json.loads((Path(run_dir) / "q.json").read_text()))

    def weights(self) -> dict[str, list[np.ndarray]]:
        return {"q": [self.q.copy()]}

    def state_dict(self) -> dict[str, Any]:
        return {"q": self.q.copy()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.q = np.array(state["q"])


def assemble(config: ToyConfig, spec, learner, action_space) -> Agent:
    layout = Layout(spec.obs_dim, 1)
    buffer_rng, explore_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(config.seed).spawn(2))
    return Agent(
        learner,
        ReplayBuffer(config.buffer_size, layout, buffer_rng),
        TransitionRule(layout, done_flag="terminated"),
        EveryStep(config.train_start, config.batch_size, fuse_act=True),
        EpsilonGreedy(decaying_epsilon(0.9, 0.05, 20.0), explore_rng, action_space),
    )


EXPERIMENT = Experiment(
    name="toy",
    config_cls=ToyConfig,
    make_env=lambda config, render_mode=None: Corridor(),
    env_spec=lambda env: discrete_spec(env, "the toy post's Q-table"),
    assemble=assemble,
    make_metric=lambda config: RollingMean(3),
    metric_label=lambda config: "3-episode mean return",
    description="a toy post: Q-learning in a corridor",
)
LEARNERS = {"keras": "toy_post:TableLearner"}
"""The framework slot a post's own learner takes (this one is NumPy; ``keras`` is the default)."""
