"""TensorBoard logging: the scalars a run writes read back, solo (Keras) and seed-batched (post
000's PyTorch port, which still batches); the loop writes them alike for every learner, so a
solo PyTorch run adds nothing to these two. The compiled engine's are
tests/test_compiled_engine.py's."""

from __future__ import annotations

import numpy as np
import pytest
from clitools import run_cli

from keras_rl.runs.files import read_episodes


@pytest.mark.parametrize("framework, seed_batch", [("keras", 1), ("torch", 2)])
@pytest.mark.slow
def test_tensorboard_scalars_read_back(tmp_path, framework, seed_batch):
    import tensorflow as tf

    proc = run_cli(
        "reproduce",
        "pendulum",
        "--framework",
        framework,
        "--seeds",
        "0-1",
        "--episodes",
        "3",
        "--no-progress",
        "--out",
        str(tmp_path / "runs"),
        "--tensorboard",
        str(tmp_path / "tb"),
        "--seed-batch",
        str(seed_batch),
    )
    assert proc.returncode == 1, proc.stderr
    runs = sorted(p.name for p in (tmp_path / "tb").iterdir())
    assert runs == [f"pendulum-faithful-{framework}-seed0", f"pendulum-faithful-{framework}-seed1"]
    scores = {}
    for event_file in (tmp_path / "tb" / runs[0]).glob("events.out.tfevents.*"):
        for event in tf.compat.v1.train.summary_iterator(str(event_file)):
            for value in event.summary.value:
                if value.tag == "score":
                    scores[event.step] = float(tf.make_ndarray(value.tensor))
    # TensorBoard keeps float32 scalars: each score as float32 rounds it, exactly
    expected = {
        r["episode"]: float(np.float32(r["score"]))
        for r in read_episodes(tmp_path / "runs" / "seed_0" / "episodes.csv")
    }
    assert scores == expected
