"""Settle P000-TARGETINIT: is post 000's ``agent.update_target_networks(1.0)`` a no-op?

    pip install "tf-keras~=2.21.0"      # Keras 2 (tf.keras 2.x) on TF 2.21, not a project dependency
    python reproductions/settlements/post000_target_init.py

The post calls ``agent.update_target_networks(1.0)`` (§2.4) right after ``Agent(...)``, before
any network has been called. Its networks are subclassed ``tf.keras.Model``s (§2.2), which
have no weights until their first call. The script builds the post's Actor and Critic as
written, unbuilt, runs the post's ``update_target_networks`` (§2.3.4) verbatim with tau 1.0,
then calls all four networks once and checks whether the targets equal their networks.
It does this under Keras 2 (``tf_keras``) and under Keras 3, whichever are installed.

Output recorded on 2026-11-22 (tf_keras 2.21.0, keras 3.15.1, tensorflow 2.21.0), quoted
in reproductions/FIDELITY.md:

    tf_keras 2.21.0: get_weights() of the unbuilt actor: [] (length 0); set_weights([]) raised nothing
    tf_keras 2.21.0: after the first calls, target actor == actor: False; target critic == critic: False
    keras 3.15.1: get_weights() of the unbuilt actor: [] (length 0); set_weights([]) raised nothing
    keras 3.15.1: after the first calls, target actor == actor: False; target critic == critic: False
"""

import importlib

import numpy as np
import tensorflow as tf


def settle(keras):
    Dense, Lambda = keras.layers.Dense, keras.layers.Lambda

    class Actor(keras.Model):  # §2.2, verbatim
        def __init__(self, action_dim, action_bound):
            super(Actor, self).__init__()
            self.action_bound = action_bound
            self.fc1 = Dense(64, activation="relu")
            self.fc2 = Dense(64, activation="relu")
            self.fc3 = Dense(action_dim, activation="tanh")

        def call(self, state):
            x = self.fc1(state)
            x = self.fc2(x)
            a = self.fc3(x)
            a = Lambda(lambda x: x * self.action_bound)(a)
            return a

    class Critic(keras.Model):  # §2.2, verbatim
        def __init__(self):
            super(Critic, self).__init__()
            self.fc1 = Dense(64, activation="relu")
            self.fc2 = Dense(64, activation="relu")
            self.fc3 = Dense(1, activation="linear")

        def call(self, state, action):
            x = tf.concat([state, action], axis=-1)
            x = self.fc1(x)
            x = self.fc2(x)
            x = self.fc3(x)
            return x

    class Agent:
        def __init__(self):
            self.actor, self.target_actor = Actor(1, 2.0), Actor(1, 2.0)
            self.critic, self.target_critic = Critic(), Critic()

        def update_target_networks(self, tau):  # §2.3.4, verbatim
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

    keras.utils.set_random_seed(0)
    agent = Agent()
    name = f"{keras.__name__} {keras.__version__}"
    weights = agent.actor.get_weights()
    agent.update_target_networks(1.0)  # §2.4: agent.update_target_networks(1.0)
    print(
        f"{name}: get_weights() of the unbuilt actor: {weights} (length {len(weights)}); set_weights([]) raised nothing"
    )
    state, action = np.zeros((1, 3), np.float32), np.zeros((1, 1), np.float32)
    for net in (agent.actor, agent.target_actor):
        net(state)
    for net in (agent.critic, agent.target_critic):
        net(state, action)
    same = [
        all(np.array_equal(a, b) for a, b in zip(n.get_weights(), t.get_weights()))
        for n, t in ((agent.actor, agent.target_actor), (agent.critic, agent.target_critic))
    ]
    print(f"{name}: after the first calls, target actor == actor: {same[0]}; target critic == critic: {same[1]}")


for module in ("tf_keras", "keras"):
    try:
        settle(importlib.import_module(module))
    except ImportError:
        print(f"{module} is not installed; skipped (pip install 'tf-keras~=2.21.0' for Keras 2)")
