import numpy as np, tensorflow as tf
tf.compat.v1.disable_eager_execution()
import tf_keras as keras
from tf_keras import layers, backend as K
from tf_keras.models import Model
from tf_keras.optimizers import legacy as optimizers
print("tf_keras", keras.__version__, "learning_phase:", K.learning_phase())
np.random.seed(0); tf.compat.v1.set_random_seed(0)
inp = layers.Input(shape=(2,))
x = layers.GaussianNoise(1.0)(inp)
x = layers.BatchNormalization()(x)
x = layers.Dense(32, activation='selu')(x)
x = layers.Dense(32, activation='selu')(x)
x = layers.Dense(32, activation='selu')(x)
x = layers.Dense(1, activation='tanh')(x)
actor = Model(inp, x)
q_grad = K.placeholder(shape=(None, 1), name='q_gradient_placeholder')
loss = tf.gradients(actor.output, actor.trainable_weights, -q_grad)
opt = optimizers.Adam(lr=0.00005)
updates = opt.get_updates(loss=loss, params=actor.trainable_weights)
update_fn = K.function(inputs=[actor.input, q_grad], outputs=[actor.output], updates=updates)  # tf_keras needs one output
s = np.random.rand(5, 2).astype(np.float32)
p1, p2 = actor.predict(s), actor.predict(s)
print("predict deterministic (noise off):", np.allclose(p1, p2))
f_out = K.function([actor.input], [actor.output])
print("K.function deterministic:", np.allclose(f_out([s])[0], f_out([s])[0]), " equals predict:", np.allclose(f_out([s])[0], p1))
bn = [l for l in actor.layers if isinstance(l, layers.BatchNormalization)][0]
mm0 = K.get_value(bn.moving_mean).copy(); mv0 = K.get_value(bn.moving_variance).copy(); g0 = K.get_value(bn.gamma).copy()
# what does get_updates differentiate? build the second-order expression explicitly
grads_of_sum = tf.gradients(loss, actor.trainable_weights)   # what get_updates does with a list
sess = tf.compat.v1.keras.backend.get_session() if False else __import__("tf_keras.src.backend", fromlist=["get_session"]).get_session()
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
    tot = 0; n = 0
    for a, b, g in zip(w0, w1, gs):
        d = b - a; m = np.abs(g) > 1e-6
        tot += np.sum(np.sign(-g[m]) == np.sign(d[m])); n += m.sum()
    return tot / max(n, 1)
print("sign agreement of the update with -second-order:", agree(second), " with -first-order:", agree(first))
print("BN moving mean/var unchanged after updates:", np.array_equal(mm0, K.get_value(bn.moving_mean)), np.array_equal(mv0, K.get_value(bn.moving_variance)), " gamma changed:", not np.array_equal(g0, K.get_value(bn.gamma)))
print("BN moving stats", mm0, mv0)
