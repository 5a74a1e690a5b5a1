"""Post 001's ``Agent.train`` as written, mirrored eagerly in Keras 3 (the yardstick for speed).

Keras 3 has no ``K.function``/``get_updates``, so each graph function becomes the eager
code that computes the same thing: ``predict_on_batch`` for the targets, one GradientTape
for the critic's MSE step, one for dQ/da at the stored actions, nested tapes for the literal
actor step (the gradient of the sum of ``tf.gradients(mu, theta, -dQ/da)``), and the
``get_weights``/``set_weights`` soft updates of ``Critic.soft_update``/``Actor.soft_update``.
"""

from __future__ import annotations

import random
from collections import deque, namedtuple

import keras
import numpy as np
import tensorflow as tf

Experience = namedtuple("Experience", field_names=["state", "action", "reward", "next_state", "done"])


class PostAgent:
    def __init__(self, actor, critic, target_actor, target_critic, tau=0.001, gamma=0.999, seed=0):
        self.main_actor, self.main_critic = actor, critic
        self.target_actor, self.target_critic = target_actor, target_critic
        self.tau, self.gamma = tau, gamma
        self.actor_optimizer = keras.optimizers.Adam(learning_rate=0.00005)
        self.critic_optimizer = keras.optimizers.Adam(learning_rate=0.0005)
        self.memory = deque()
        self.random = random.Random(seed)
        self.batch_size = 32

    def sample(self):
        self.random.shuffle(self.memory)
        return [self.memory.popleft() for x in range(self.batch_size)]

    def soft_update(self, model, target):
        weights = model.get_weights()
        target_weights = target.get_weights()
        target.set_weights([self.tau * w + (1 - self.tau) * t for w, t in zip(weights, target_weights)])

    def train(self):
        batches = 0
        while len(self.memory) > 100:
            data = self.sample()
            states = np.vstack([e.state for e in data if e is not None])
            actions = np.array([e.action for e in data if e is not None]).astype(np.float32).reshape(-1, 1)
            rewards = np.array([e.reward for e in data if e is not None]).astype(np.float32).reshape(-1, 1)
            dones = np.array([e.done for e in data if e is not None]).astype(np.uint8).reshape(-1, 1)
            next_states = np.vstack([e.next_state for e in data if e is not None])
            actions_next = self.target_actor.predict_on_batch(next_states)
            q_targets_next = self.target_critic.predict_on_batch([next_states, actions_next])
            q_targets = rewards + self.gamma * q_targets_next * (1 - dones)
            # self.main_critic.train(states, actions, Q_targets)
            with tf.GradientTape() as tape:
                critic_loss = tf.reduce_mean(tf.square(q_targets - self.main_critic([states, actions])))
            grads = tape.gradient(critic_loss, self.main_critic.trainable_weights)
            self.critic_optimizer.apply_gradients(zip(grads, self.main_critic.trainable_weights))
            # action_gradients = self.main_critic.get_gradient(states, actions)
            a, s = tf.constant(actions), tf.constant(states)
            with tf.GradientTape() as tape:
                tape.watch(a)
                q = self.main_critic([s, a])
            action_gradients = np.reshape(tape.gradient(q, a).numpy(), (-1, 1))
            # self.main_actor.train(states, action_gradients): get_updates on tf.gradients(...)
            params = self.main_actor.trainable_weights
            with tf.GradientTape() as outer:
                with tf.GradientTape() as inner:
                    mu = self.main_actor(states)
                first = inner.gradient(mu, params, output_gradients=-action_gradients)
                total = tf.add_n([tf.reduce_sum(g) for g in first])
            self.actor_optimizer.apply_gradients(zip(outer.gradient(total, params), params))
            self.soft_update(self.main_actor, self.target_actor)
            self.soft_update(self.main_critic, self.target_critic)
            batches += 1
        return batches


def functional_models():
    """The post's functional Keras models (``Critic.__make_model``, ``Actor.__make_model``)."""
    layers = keras.layers
    s_in, a_in = layers.Input(shape=(2,)), layers.Input(shape=(1,))
    x = layers.BatchNormalization()(s_in)
    x = layers.Dense(32, activation="selu")(x)
    x = layers.concatenate([x, a_in])
    x = layers.Dense(32, activation="selu")(x)
    critic = keras.Model([s_in, a_in], layers.Dense(1)(x))
    inp = layers.Input(shape=(2,))
    x = layers.GaussianNoise(1.0)(inp)
    x = layers.BatchNormalization()(x)
    for _ in range(3):
        x = layers.Dense(32, activation="selu")(x)
    actor = keras.Model(inp, layers.Dense(1, activation="tanh")(x))
    return actor, critic


def fill(agent: PostAgent, n: int, rng: np.random.Generator) -> None:
    for _ in range(n):
        agent.memory.append(
            Experience(
                rng.random((1, 2)).astype(np.float32),
                rng.uniform(-1, 1, (1, 1)),
                float(rng.normal()),
                rng.normal(size=(1, 2)).astype(np.float32),
                False,
            )
        )
