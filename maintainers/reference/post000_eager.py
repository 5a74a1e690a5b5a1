"""Post 000's Agent, as written: eager Keras calls, a deque, get/set_weights soft updates.

Only what differs from the post is what it must: the networks are passed in (so a test
can give both sides the same weights), the RNGs are explicit, and ``broadcast=False``
reshapes the dones to (B,1) for the fixed-target comparison. Everything else (shapes,
dtypes, the tuple action, the order of operations) follows §2.3-§2.4 line by line.
"""

from __future__ import annotations

import random
from collections import deque

import keras
import numpy as np
import tensorflow as tf


class PostActor(keras.Model):
    """§2.2 verbatim, including the ``Lambda`` built on every call."""

    def __init__(self, action_dim, action_bound):
        super().__init__()
        self.action_bound = action_bound
        self.fc1 = keras.layers.Dense(64, activation="relu")
        self.fc2 = keras.layers.Dense(64, activation="relu")
        self.fc3 = keras.layers.Dense(action_dim, activation="tanh")

    def call(self, state):
        x = self.fc1(state)
        x = self.fc2(x)
        a = self.fc3(x)
        a = keras.layers.Lambda(lambda x: x * self.action_bound)(a)
        return a


class PostAgent:
    def __init__(
        self,
        actor,
        critic,
        target_actor,
        target_critic,
        actor_lr=1e-3,
        critic_lr=1e-3,
        gamma=0.99,
        tau=0.001,
        buffer_size=2000,
        batch_size=64,
        train_start=1000,
        broadcast=True,
        seed=0,
    ):
        self.actor, self.critic = actor, critic
        self.target_actor, self.target_critic = target_actor, target_critic
        self.actor_optimizer = keras.optimizers.Adam(learning_rate=actor_lr)
        self.critic_optimizer = keras.optimizers.Adam(learning_rate=critic_lr)
        self.train_start, self.gamma, self.tau = train_start, gamma, tau
        self.memory = deque(maxlen=buffer_size)
        self.batch_size = batch_size
        self.broadcast = broadcast
        self.random = random.Random(seed)
        self.np_random = np.random.RandomState(seed)

    def get_action(self, state):
        action = self.actor(state)[0][0]
        return action

    def append_sample(self, state, action, reward, next_state, done):
        self.memory.append((state, action, reward, next_state, done))

    def ou_noise(self, x, rho=0.15, mu=0, dt=1e-1, sigma=0.2, dim=1):
        return x + rho * (mu - x) * dt + sigma * np.sqrt(dt) * self.np_random.normal(size=dim)

    def train_model(self, mini_batch=None):
        if mini_batch is None:
            mini_batch = self.random.sample(self.memory, self.batch_size)
        states = np.array([sample[0][0] for sample in mini_batch])
        actions = np.array([sample[1] for sample in mini_batch])
        rewards = np.array([sample[2] for sample in mini_batch])
        next_states = np.array([sample[3][0] for sample in mini_batch])
        dones = np.array([sample[4] for sample in mini_batch])
        if not self.broadcast:
            dones = dones.reshape(-1, 1)
        actions = np.reshape(actions, [-1, 1])
        next_actions = self.target_actor(next_states)
        next_actions = np.reshape(next_actions, [-1, 1])
        q_values = self.target_critic(next_states, next_actions)
        targets = rewards + self.gamma * q_values * (1 - dones)

        with tf.GradientTape() as tape:
            q_values = self.critic(states, actions)
            critic_loss = tf.reduce_mean(tf.square(q_values - targets))
        critic_grads = tape.gradient(critic_loss, self.critic.trainable_variables)
        self.critic_optimizer.apply_gradients(zip(critic_grads, self.critic.trainable_variables))

        with tf.GradientTape() as tape:
            actions = self.actor(states)
            q_values = self.critic(states, actions)
            actor_loss = -tf.reduce_mean(q_values)
        actor_grads = tape.gradient(actor_loss, self.actor.trainable_variables)
        self.actor_optimizer.apply_gradients(zip(actor_grads, self.actor.trainable_variables))

        self.update_target_networks(self.tau)
        return {"critic_loss": float(critic_loss), "actor_loss": float(actor_loss), "targets": np.asarray(targets)}

    def update_target_networks(self, tau):
        actor_weights = self.actor.get_weights()
        target_actor_weights = self.target_actor.get_weights()
        critic_weights = self.critic.get_weights()
        target_critic_weights = self.target_critic.get_weights()
        for i in range(len(actor_weights)):
            target_actor_weights[i] = tau * actor_weights[i] + (1 - tau) * target_actor_weights[i]
        for i in range(len(critic_weights)):
            target_critic_weights[i] = tau * critic_weights[i] + (1 - tau) * target_critic_weights[i]
        self.target_actor.set_weights(target_actor_weights)
        self.target_critic.set_weights(target_critic_weights)


def run_steps(agent: PostAgent, env, n_steps: int, action_size: int = 1, state_size: int = 3) -> int:
    """§2.4's loop for ``n_steps`` env steps (episodes restart as in the post); returns updates."""
    updates = 0
    steps = 0
    while steps < n_steps:
        done = False
        state = env.reset()[0]
        state = np.array([state])
        pre_noise = np.zeros(action_size)
        while not done and steps < n_steps:
            action = agent.get_action(state)
            noise = agent.ou_noise(pre_noise, dim=action_size)
            action = np.clip(action + noise, -2, 2)
            next_state, reward, _, done, _ = env.step((action,))
            next_state = np.reshape(next_state, [1, state_size])
            agent.append_sample(state, action, reward, next_state, done)
            if len(agent.memory) >= agent.train_start:
                agent.train_model()
                updates += 1
            state = next_state
            steps += 1
    return updates
