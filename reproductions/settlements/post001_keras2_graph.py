"""Settle post 001's Keras 2 semantics by running its graph code under Keras 2 itself.

    pip install "tf-keras~=2.21.0"      # Keras 2 (tf.keras 2.x) on TF 2.21, not a project dependency
    python reproductions/settlements/post001_keras2_graph.py

Builds the post's Actor (GaussianNoise(1.0) -> BatchNormalization -> 3 x Dense 32 selu ->
Dense 1 tanh) in TF1 graph mode, with the post's own construction of the actor update:
``loss = tf.gradients(actor.output, actor.trainable_weights, -q_gradient)`` handed to
``Adam.get_updates(loss=loss, params=...)`` and run through ``K.function``. It prints:

- whether ``predict`` / ``K.function`` are deterministic (GaussianNoise active or not);
- the norms of the first-order gradients and of what ``get_updates`` differentiates;
- which of the two the weight change after one Adam step follows (Adam's first step moves
  every weight by about lr * sign(gradient), so sign agreement identifies the gradient);
- whether BatchNormalization's moving statistics ever change, and whether gamma trains.

Output recorded on 2026-11-22 (tf_keras 2.21.0; seeded with ``keras.utils.set_random_seed(0)``,
so repeated runs print the same numbers), quoted in reproductions/FIDELITY.md:

    tf_keras 2.21.0 learning_phase: Tensor("keras_learning_phase:0", shape=(), dtype=bool)
    predict deterministic (noise off): True
    K.function deterministic: True  equals predict: True
    first-order grads norms: [0.5499842762947083, 0.9523221850395203, 4.218005180358887, 5.142758369445801]
    second-order (what get_updates sees) norms: [15.191679954528809, 25.56804656982422, 55.37007522583008, 70.77508544921875]
    sign agreement of the update with -second-order: 1.0  with -first-order: 0.5073496659242762
    BN moving mean/var unchanged after updates: True True  gamma changed: True
    BN moving stats [0. 0.] [1. 1.]

(An earlier, unseeded version of this script printed 0.47-0.62 for the first-order
agreement across runs; the second-order agreement was 1.0 every time.)

tf_keras differs from standalone Keras 2.2 in one place that matters here: its
``K.function`` needs at least one output, so the update function gets ``actor.output``.
"""

import numpy as np, tensorflow as tf

tf.compat.v1.disable_eager_execution()
import tf_keras as keras
from tf_keras import layers, backend as K
from tf_keras.models import Model
from tf_keras.optimizers import legacy as optimizers

print("tf_keras", keras.__version__, "learning_phase:", K.learning_phase())
keras.utils.set_random_seed(0)  # Python, NumPy and TF (graph-level) seeds; tf_keras initialisers follow it
inp = layers.Input(shape=(2,))
x = layers.GaussianNoise(1.0)(inp)
x = layers.BatchNormalization()(x)
x = layers.Dense(32, activation="selu")(x)
x = layers.Dense(32, activation="selu")(x)
x = layers.Dense(32, activation="selu")(x)
x = layers.Dense(1, activation="tanh")(x)
actor = Model(inp, x)
q_grad = K.placeholder(shape=(None, 1), name="q_gradient_placeholder")
loss = tf.gradients(actor.output, actor.trainable_weights, -q_grad)
opt = optimizers.Adam(lr=0.00005)
updates = opt.get_updates(loss=loss, params=actor.trainable_weights)
update_fn = K.function(
    inputs=[actor.input, q_grad], outputs=[actor.output], updates=updates
)  # tf_keras needs one output
s = np.random.rand(5, 2).astype(np.float32)
p1, p2 = actor.predict(s), actor.predict(s)
print("predict deterministic (noise off):", np.allclose(p1, p2))
f_out = K.function([actor.input], [actor.output])
print(
    "K.function deterministic:",
    np.allclose(f_out([s])[0], f_out([s])[0]),
    " equals predict:",
    np.allclose(f_out([s])[0], p1),
)
bn = [l for l in actor.layers if isinstance(l, layers.BatchNormalization)][0]
mm0 = K.get_value(bn.moving_mean).copy()
mv0 = K.get_value(bn.moving_variance).copy()
g0 = K.get_value(bn.gamma).copy()
# what does get_updates differentiate? build the second-order expression explicitly
grads_of_sum = tf.gradients(loss, actor.trainable_weights)  # what get_updates does with a list
from tf_keras.src.backend import get_session  # noqa: E402

sess = get_session()
qg = np.random.randn(5, 1).astype(np.float32)
second = sess.run(grads_of_sum, {actor.input: s, q_grad: qg})
first = sess.run(loss, {actor.input: s, q_grad: qg})
print("first-order grads norms:", [float(np.linalg.norm(g)) for g in first][:4])
print("second-order (what get_updates sees) norms:", [float(np.linalg.norm(g)) for g in second][:4])
w0 = [K.get_value(w).copy() for w in actor.trainable_weights]
update_fn([s, qg])
w1 = [K.get_value(w) for w in actor.trainable_weights]


# Adam first step moves each weight by ~lr * sign(grad): compare signs with both candidates
def agree(gs):
    tot = 0
    n = 0
    for a, b, g in zip(w0, w1, gs):
        d = b - a
        m = np.abs(g) > 1e-6
        tot += np.sum(np.sign(-g[m]) == np.sign(d[m]))
        n += m.sum()
    return tot / max(n, 1)


print("sign agreement of the update with -second-order:", agree(second), " with -first-order:", agree(first))
print(
    "BN moving mean/var unchanged after updates:",
    np.array_equal(mm0, K.get_value(bn.moving_mean)),
    np.array_equal(mv0, K.get_value(bn.moving_variance)),
    " gamma changed:",
    not np.array_equal(g0, K.get_value(bn.gamma)),
)
print("BN moving stats", mm0, mv0)
