"""Training: a run's parts and settings in, per-seed records, checkpoints and weights out.

- ``settings.py``: ``TrainSettings``, everything about *how* a set of seeds trains that is
  not in their configs (resume, checkpoints, TensorBoard, evaluation, progress), one typed
  object from the command to the loop;
- ``engine.py``: the seam. ``Engine`` is what ``runs/jobs.execute`` calls; ``ENGINES`` names
  each implementation. Today there is one, ``gymnasium``;
- ``loop.py``: the ``gymnasium`` engine's episode loop over a seed axis (Gymnasium envs in
  NumPy, the learner's compiled updates, one host round trip per env step).

Nothing above this package (``commands/``, ``runs/jobs.py``, ``report/``) knows which engine
ran a seed: each writes the same run folder.
"""
