"""Learners: the networks, optimizers and compiled updates of each post, behind one protocol.

``protocol.py`` says what a learner is; ``table.py`` picks one per (experiment, framework);
the Keras learners live here, the PyTorch ones in ``keras_rl/torch/``. Importing this
package imports neither TensorFlow nor torch.
"""
