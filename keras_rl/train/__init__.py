"""Training: a run's parts and settings in, per-seed records, checkpoints and weights out.

- ``settings.py``: ``TrainSettings``, everything about *how* a set of seeds trains that is
  not in their configs (resume, checkpoints, TensorBoard, evaluation, progress), one typed
  object from the command to the loop;
- ``engine.py``: the seam. ``Engine`` is what ``dispatch/jobs.execute`` calls; ``ENGINES`` names
  each implementation: ``gymnasium``, ``compiled`` and ``vectorised``;
- ``life.py``: one seed's life, the same on every engine (records, resume and extension,
  checkpoints at close, signals, TensorBoard, evaluation);
- ``loop.py``: the ``gymnasium`` engine's episode loop over a seed axis (Gymnasium envs in
  NumPy, the learner's compiled updates, one host round trip per env step);
- ``compiled.py``: the ``compiled`` engine (a post's episode as one XLA program, Keras);
- ``vectorised.py``: the ``vectorised`` engine (post 003 in PyTorch, S seeds in one program).

Nothing above this package (``commands/``, ``dispatch/jobs.py``, ``report/``) knows which engine
ran a seed: each writes the same run folder.
"""
