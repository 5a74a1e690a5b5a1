"""TensorBoard logging: the scalars a run writes read back, solo and seed-batched."""

from __future__ import annotations

import pytest
from clitools import run_cli

from keras_rl.runs.files import read_episodes


@pytest.mark.parametrize("seed_batch", [1, 2])
@pytest.mark.slow
def test_tensorboard_scalars_read_back(tmp_path, seed_batch):
    import tensorflow as tf

    proc = run_cli(
        "reproduce",
        "cartpole",
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
    assert runs == ["cartpole-faithful-keras-seed0", "cartpole-faithful-keras-seed1"]
    scores = {}
    for event_file in (tmp_path / "tb" / runs[0]).glob("events.out.tfevents.*"):
        for event in tf.compat.v1.train.summary_iterator(str(event_file)):
            for value in event.summary.value:
                if value.tag == "score":
                    scores[event.step] = float(tf.make_ndarray(value.tensor))
    expected = {r["episode"]: r["score"] for r in read_episodes(tmp_path / "runs" / "seed_0" / "episodes.csv")}
    assert scores == expected
