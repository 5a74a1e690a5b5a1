"""The compiled engine (``keras_rl/train/compiled.py``) against the Gymnasium loop, and the run
features it must keep: records, threshold, resume bit for bit, extension, stops between
chunks (a dispatcher's flag here; Ctrl-C and SIGTERM to the command in tests/test_resume.py's
life of a seed), evaluation, TensorBoard, refusals; for post 000 and post 003 each.

Equivalence, measured (over 100 seeds: ``results/engines/pendulum/report.md``): with the
same streams (reset states, noise, sample indices), post 000's seed 0 agrees with the Gymnasium
loop to about 1e-13 in every episode's score and to float32 rounding in its losses over the
first 8 episodes; the runs part later (episode 43 of seed 0 past 1e-6), as two roundings of a
chaotic run do: XLA fuses the whole episode (the env's multiply-adds, the update's kernels)
where the loop runs the env in NumPy and the update as its own XLA program.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from keras_rl.errors import ConfigError, RunFolderError
from keras_rl.registry import get_experiment
from keras_rl.runs.evaluate import EvalSchedule
from keras_rl.runs.files import read_episodes
from keras_rl.train.engine import get_engine
from keras_rl.train.settings import TrainSettings

QUIET = TrainSettings(progress=False)


def config(**changes):
    values = {"seed": 0, "episodes": 6, "train_start": 300, **changes}
    return get_experiment("pendulum").config_cls.for_variant("faithful", **values)


def train(engine: str, c, folder: Path, settings: TrainSettings = QUIET, should_stop=None):
    return get_engine(engine).train(get_experiment("pendulum"), [c], [folder], settings, should_stop=should_stop)[0]


def columns(folder: Path) -> dict[str, list]:
    rows = read_episodes(folder / "episodes.csv")
    return {k: [r[k] for r in rows] for k in ("episode", "steps", "total_steps", "score", "metric", *LOSSES)}


LOSSES = ("critic_loss", "actor_loss")


@pytest.mark.slow
def test_both_engines_agree_over_the_first_episodes(tmp_path):
    c = config()
    loop, compiled = train("gymnasium", c, tmp_path / "loop"), train("compiled", c, tmp_path / "compiled")
    assert loop.status == compiled.status == "completed"
    a, b = columns(tmp_path / "loop"), columns(tmp_path / "compiled")
    assert a["episode"] == b["episode"] and a["total_steps"] == b["total_steps"]
    np.testing.assert_allclose(b["score"], a["score"], rtol=1e-9)
    trained = [i for i, v in enumerate(a["critic_loss"]) if v is not None]
    assert trained and trained == [i for i, v in enumerate(b["critic_loss"]) if v is not None]
    for name in LOSSES:
        np.testing.assert_allclose([b[name][i] for i in trained], [a[name][i] for i in trained], rtol=1e-5)
    summary = json.loads((tmp_path / "compiled" / "summary.json").read_text())
    assert (
        summary["provenance"]["engine"] == "compiled"
        and "engine" not in json.loads((tmp_path / "loop" / "summary.json").read_text())["provenance"]
    )
    assert (tmp_path / "compiled" / "actor.weights.h5").is_file()


@pytest.mark.slow
def test_an_interrupted_run_resumes_bit_for_bit_and_a_finished_one_extends(tmp_path):
    straight = train("compiled", config(episodes=8), tmp_path / "straight")
    assert straight.status == "completed"
    played = []

    def after_three():
        played.append(1)
        return len(played) >= 3

    cut = train(
        "compiled", config(episodes=8), tmp_path / "cut", TrainSettings(progress=False, checkpoint_every=2), after_three
    )
    assert cut.status == "interrupted" and cut.episodes_run == 3
    resumed = train("compiled", config(episodes=8), tmp_path / "cut", TrainSettings(progress=False, resume=True))
    assert resumed.status == "completed" and resumed.episodes_run == 8
    assert columns(tmp_path / "cut") == columns(tmp_path / "straight")  # bit for bit
    short = train("compiled", config(episodes=5), tmp_path / "short")
    assert short.status == "completed" and (tmp_path / "short" / "checkpoint.pkl").is_file()  # kept: it can extend
    longer = train("compiled", config(episodes=8), tmp_path / "short", TrainSettings(progress=False, resume=True))
    assert longer.episodes_run == 8 and columns(tmp_path / "short") == columns(tmp_path / "straight")


@pytest.mark.slow
def test_the_threshold_stops_the_run_as_the_loop_stops_it(tmp_path):
    c = config(threshold=-1e9)  # every EMA is above it: the run stops after its first episode
    summary = train("compiled", c, tmp_path / "run")
    assert summary.status == "completed" and summary.success and summary.reached_at_episode == 1
    assert summary.episodes_run == 1 and not (tmp_path / "run" / "checkpoint.pkl").exists()


@pytest.mark.slow
def test_a_non_finite_loss_stops_the_run_naming_the_update(tmp_path):
    summary = train("compiled", config(critic_lr=1e38, train_start=64), tmp_path / "run")
    assert summary.status == "non_finite_loss"
    assert "became" in summary.message and "at update" in summary.message and "env step" in summary.message


@pytest.mark.slow
def test_evaluation_and_tensorboard_during_training(tmp_path):
    settings = TrainSettings(progress=False, tensorboard=tmp_path / "tb", evaluation=EvalSchedule(every=2, episodes=1))
    summary = train("compiled", config(episodes=4), tmp_path / "run", settings)
    assert summary.status == "completed"
    evaluations = (tmp_path / "run" / "evaluations.csv").read_text().splitlines()
    assert len(evaluations) == 3  # a header, then episodes 2 and 4
    assert list((tmp_path / "tb").rglob("events.out.tfevents.*"))


def test_what_the_compiled_engine_cannot_run_is_refused_before_training(tmp_path):
    engine = get_engine("compiled")
    mountaincar = get_experiment("mountaincar")
    assert engine.refusal(mountaincar, mountaincar.config_cls.for_variant("faithful")) is None
    assert engine.refusal(mountaincar, mountaincar.config_cls.for_variant("faithful-intended")) is None
    fixed = engine.refusal(mountaincar, mountaincar.config_cls.for_variant("fixed"))
    off = [f for f, v in (("popping_buffer", False), ("episode_returns_as_rewards", False), ("exploration", "ou"),
                          ("learning_phase_training", True))
           if getattr(mountaincar.config_cls.for_variant("fixed"), f) == v]  # fmt: skip
    assert len(off) >= 2 and all(f"{f}=" in fixed for f in off)  # every switch the variant turns, named at once
    assert "(P001-POP wants True" in fixed and "engine=gymnasium" in fixed
    for field, value, quirk in (
        ("episode_returns_as_rewards", False, "P001-RETURNS"),
        ("exploration", "ou", "P001-NOEXPLORE"),
        ("learning_phase_training", True, "P001-PHASE"),
    ):
        why = engine.refusal(mountaincar, mountaincar.config_cls.for_variant("faithful", **{field: value}))
        assert f"{field}=" in why and quirk in why
    torch = config(framework="torch")
    assert "Keras learner" in engine.refusal(get_experiment("pendulum"), torch)
    with pytest.raises(ConfigError, match="one seed per program"):
        engine.train(get_experiment("pendulum"), [config(), config(seed=1)], [tmp_path / "a", tmp_path / "b"], QUIET)
    assert not (tmp_path / "a").exists()


def test_the_compiled_engines_refusals_need_no_tensorflow():
    """``--engine compiled --framework torch --dry-run`` is refused before TensorFlow (or torch) loads."""
    import subprocess
    import sys

    code = (
        "import sys; from keras_rl.cli import main; "
        "code = main(['reproduce', 'pendulum', '--engine', 'compiled', '--framework', 'torch', '--dry-run', "
        "'--out', sys.argv[1]]); "
        "print(code, 'tensorflow' in sys.modules, 'torch' in sys.modules)"
    )
    import tempfile

    with tempfile.TemporaryDirectory() as out:
        proc = subprocess.run([sys.executable, "-c", code, out], capture_output=True, text=True, timeout=120)
    assert proc.stdout.split() == ["2", "False", "False"], proc.stdout + proc.stderr
    assert "Keras learner" in proc.stderr


@pytest.mark.slow
def test_a_checkpoint_resumes_only_on_the_engine_that_wrote_it(tmp_path):
    stop = iter([False, True])
    cut = train("gymnasium", config(episodes=4), tmp_path / "loop", QUIET, lambda: next(stop))
    assert cut.status == "interrupted"
    with pytest.raises(RunFolderError, match="written by the gymnasium engine"):
        train("compiled", config(episodes=4), tmp_path / "loop", TrainSettings(progress=False, resume=True))
    stop = iter([False, True])
    cut = train("compiled", config(episodes=4), tmp_path / "compiled", QUIET, lambda: next(stop))
    assert cut.status == "interrupted"
    with pytest.raises(RunFolderError, match="written by the compiled engine"):
        train("gymnasium", config(episodes=4), tmp_path / "compiled", TrainSettings(progress=False, resume=True))


def test_every_engine_is_named_once_and_naming_them_loads_no_framework():
    """``--engine``'s choices and ``RunOptions``' check read ``train/engine.ENGINE_NAMES``, which is
    the engine table itself (issue 71, item 6: it was a copy, held equal by this test)."""
    import subprocess
    import sys

    from keras_rl.commands.flags import FLAGS
    from keras_rl.dispatch.options import AUTO
    from keras_rl.train.engine import ENGINE_NAMES, get_engine

    assert FLAGS["--engine"]["choices"] == (AUTO, *ENGINE_NAMES)
    assert [get_engine(name).name for name in ENGINE_NAMES] == list(ENGINE_NAMES)
    loaded = subprocess.run(
        [sys.executable, "-c", "import sys, keras_rl.dispatch.options, keras_rl.train.engine as e; "
         "print(sorted(m for m in ('tensorflow', 'torch', 'keras') if m in sys.modules), e.ENGINE_NAMES)"],
        capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    assert loaded.startswith("[] ('gymnasium', 'compiled', 'vectorised', 'vectorised-compiled')"), loaded


def twin_learners(post: str, c):
    """Two Keras learners of ``c`` with the same initial weights (one to train alone, one traced)."""
    from keras_rl.learners.table import implementation
    from keras_rl.seeding import seed_everything

    experiment = get_experiment(post)
    spec = experiment.env_spec(experiment.make_env(c))

    def learner():
        seed_everything(0)
        return implementation(post, "keras").load()(c, spec)

    return learner(), learner()


def random_rows(*shape: int) -> np.ndarray:
    """Packed transition rows of ``shape`` (the last axis the row width), done flags 0 or 1."""
    rows = np.random.default_rng(0).normal(size=shape).astype(np.float32)
    rows[..., -1] = rows[..., -1] > 0
    return rows


@pytest.mark.slow
def test_one_update_inside_the_episode_program_equals_the_learners_own_within_1e_6():
    """The learner's update traced into the bigger program (a loop, a ``tf.cond``, the ring) against
    the learner's own compiled ``train`` on the same rows, from the same weights."""
    import tensorflow as tf

    c = config()
    solo, traced = twin_learners("pendulum", c)
    rows = random_rows(c.batch_size, solo.layout.width)
    losses = solo.train(rows)

    ring = tf.Variable(tf.zeros([c.buffer_size, traced.layout.width], tf.float32))
    ring[: c.batch_size].assign(rows)

    @tf.function(jit_compile=True)
    def program(indices, train):
        out = tf.zeros([2])
        for _ in tf.range(1):
            out = tf.cond(
                train,
                lambda: tf.stack([v for v in traced.update(tf.gather(ring, indices)).values()]),
                lambda: tf.zeros([2]),
            )
        return out

    inside = program(tf.range(c.batch_size), tf.constant(True)).numpy()
    np.testing.assert_allclose(inside, [float(losses[n]) for n in traced.loss_names], rtol=1e-6)
    for name, weights in solo.weights().items():
        for a, b in zip(weights, traced.weights()[name]):
            np.testing.assert_allclose(b, a, rtol=1e-6, atol=1e-6)


def cartpole(**changes):
    values = {"seed": 0, "episodes": 30, **changes}
    return get_experiment("cartpole").config_cls.for_variant("faithful", **values)


def train_cartpole(engine: str, c, folder: Path, settings: TrainSettings = QUIET, should_stop=None):
    return get_engine(engine).train(get_experiment("cartpole"), [c], [folder], settings, should_stop=should_stop)[0]


def cartpole_columns(folder: Path) -> dict[str, list]:
    rows = read_episodes(folder / "episodes.csv")
    return {k: [r[k] for r in rows] for k in ("episode", "steps", "total_steps", "score", "metric", "loss")}


@pytest.mark.slow
def test_post_003_on_both_engines_plays_the_same_episodes(tmp_path):
    """Post 003's draws (epsilon-greedy's uniforms and random actions, the sample indices, the
    resets) all come from the loop's own generators, and CartPole's dynamics are bit for bit
    Gymnasium's where they decide an episode's length: the episodes are the same ones (measured:
    seed 0's first 158 episodes), the losses agree to float32 rounding."""
    c = cartpole()
    train_cartpole("gymnasium", c, tmp_path / "loop")
    train_cartpole("compiled", c, tmp_path / "compiled")
    a, b = cartpole_columns(tmp_path / "loop"), cartpole_columns(tmp_path / "compiled")
    assert a["steps"] == b["steps"] and a["score"] == b["score"] and a["metric"] == b["metric"]
    trained = [i for i, v in enumerate(a["loss"]) if v is not None]
    assert trained and trained == [i for i, v in enumerate(b["loss"]) if v is not None]
    np.testing.assert_allclose([b["loss"][i] for i in trained], [a["loss"][i] for i in trained], rtol=1e-5)


@pytest.mark.slow
@pytest.mark.parametrize("post", ["cartpole", "mountaincar"])
def test_an_interrupted_run_resumes_bit_for_bit_on_the_compiled_engine(tmp_path, post):
    """Post 003 (its generators' states) and post 001 (the popping buffer's rows and generator,
    so its bursts continue from the same buffer) travel in the checkpoint with the learner's state."""
    make, run, read = (
        (cartpole, train_cartpole, cartpole_columns)
        if post == "cartpole"
        else (
            mountaincar,
            train_mountaincar,
            columns,
        )
    )
    episodes, cut_after = (20, 10) if post == "cartpole" else (6, 3)
    run("compiled", make(episodes=episodes), tmp_path / "straight")
    stops = iter([False] * (cut_after - 1) + [True])
    cut = run("compiled", make(episodes=episodes), tmp_path / "cut", TrainSettings(progress=False), lambda: next(stops))
    assert cut.status == "interrupted" and cut.episodes_run == cut_after
    resumed = run("compiled", make(episodes=episodes), tmp_path / "cut", TrainSettings(progress=False, resume=True))
    assert resumed.status == "completed"
    assert read(tmp_path / "cut") == read(tmp_path / "straight")


@pytest.mark.slow
@pytest.mark.parametrize("post", ["pendulum", "cartpole", "mountaincar"])
def test_a_seed_on_a_kept_program_plays_what_it_plays_alone(tmp_path, post):
    """A worker keeps each config's compiled program for its next seed (``ProgramCache``): seed 1
    run after seed 0 on seed 0's program (its learner loaded with seed 1's initial state, the
    ring zeroed, seed 0's weights and Adam slots gone) writes the same episodes, bit for bit, as
    seed 1 on a program traced for it alone (every column but the wall time: measured, seed 1's
    first pendulum episode ended 1.44 s after its start alone and 0.008 s after it on a kept
    program)."""
    from keras_rl.train.compiled import PROGRAMS

    make, run, read = {
        "pendulum": (config, train, columns),
        "cartpole": (cartpole, train_cartpole, cartpole_columns),
        "mountaincar": (mountaincar, train_mountaincar, columns),
    }[post]
    episodes = {"pendulum": {"episodes": 4}, "cartpole": {"episodes": 25}, "mountaincar": {"episodes": 3}}[post]
    PROGRAMS.clear()
    run("compiled", make(seed=1, **episodes), tmp_path / "alone")
    PROGRAMS.clear()
    run("compiled", make(seed=0, **episodes), tmp_path / "first")
    (kept,) = PROGRAMS.kept.values()
    run("compiled", make(seed=1, **episodes), tmp_path / "after")
    assert list(PROGRAMS.kept.values()) == [kept]  # the same learner and program, not a new one
    assert read(tmp_path / "after") == read(tmp_path / "alone") != read(tmp_path / "first")  # all but wall time


def test_the_program_cache_keys_on_what_shapes_the_program_and_keeps_a_few():
    from keras_rl.train.compiled import ProgramCache

    cache = ProgramCache(size=2)
    assert cache.key("pendulum", config(seed=0)) == cache.key("pendulum", config(seed=7, episodes=99))
    assert cache.key("pendulum", config(tau=0.01)) != cache.key("pendulum", config())
    assert cache.key("cartpole", cartpole()) != cache.key("cartpole", cartpole(q_lr=5e-4))

    class Learner:
        def __init__(self, n):
            self.n = n

        def state_dict(self):
            return {"n": self.n}

        def load_state_dict(self, state):
            self.n = state["n"]

    class Program:
        def __init__(self):
            import tensorflow as tf

            self.ring = tf.Variable([1.0, 2.0])

        def reset(self):
            self.ring.assign([0.0, 0.0])

    made = []

    def make(c, learner):
        made.append(learner)
        return Program()

    first, program = cache.take("pendulum", config(seed=0), Learner(0), make)
    learner, again = cache.take("pendulum", config(seed=1), Learner(1), make)
    assert learner is first and again is program and learner.n == 1 and len(made) == 1
    assert program.ring.numpy().tolist() == [0.0, 0.0]  # zeroed for the next seed
    cache.take("pendulum", config(tau=0.01), Learner(2), make)
    cache.take("pendulum", config(tau=0.02), Learner(3), make)  # a third config: the oldest goes
    assert len(cache.kept) == 2 and cache.key("pendulum", config()) not in cache.kept


def mountaincar(**changes):
    values = {"seed": 0, "episodes": 8, **changes}
    return get_experiment("mountaincar").config_cls.for_variant("faithful", **values)


def train_mountaincar(engine: str, c, folder: Path, settings: TrainSettings = QUIET, should_stop=None):
    return get_engine(engine).train(get_experiment("mountaincar"), [c], [folder], settings, should_stop=should_stop)[0]


@pytest.mark.slow
def test_post_001_on_both_engines_agrees_over_the_first_episodes(tmp_path):
    """Post 001's acting has no draws (P001-NOEXPLORE) and its bursts pop from the loop's own
    buffer and generator, so the engines differ only by rounding: the actor inside the episode
    program against its own XLA program (measured, seed 0: scores within about 1e-7 relative,
    losses within 2e-7, over the first 8 episodes, every burst at the same episode)."""
    c = mountaincar()
    loop, compiled = (
        train_mountaincar("gymnasium", c, tmp_path / "loop"),
        train_mountaincar("compiled", c, tmp_path / "compiled"),
    )
    assert loop.status == compiled.status == "completed"
    a, b = columns(tmp_path / "loop"), columns(tmp_path / "compiled")
    assert a["episode"] == b["episode"] and a["steps"] == b["steps"] and a["total_steps"] == b["total_steps"]
    np.testing.assert_allclose(b["score"], a["score"], rtol=1e-5)
    trained = [i for i, v in enumerate(a["critic_loss"]) if v is not None]
    assert len(trained) >= 6 and trained == [i for i, v in enumerate(b["critic_loss"]) if v is not None]
    for name in LOSSES:
        np.testing.assert_allclose([b[name][i] for i in trained], [a[name][i] for i in trained], rtol=1e-5, atol=1e-6)
    assert json.loads((tmp_path / "compiled" / "summary.json").read_text())["provenance"]["engine"] == "compiled"


@pytest.mark.slow
def test_a_post_001_burst_equals_the_learners_own_updates_within_1e_6():
    """The burst program (the learner's own update traced into a loop over padded batches, the
    pad never trained) against the learner's compiled ``train`` batch by batch, from the same
    weights: the losses and the weights after it."""
    import tensorflow as tf

    from keras_rl.train.compiled import MountainCarProgram

    c = mountaincar()
    solo, traced = twin_learners("mountaincar", c)
    program = MountainCarProgram(c, traced)
    count = 5
    rows = random_rows(count, c.batch_size, solo.layout.width)
    expected = [[float(v) for v in solo.train(batch).values()] for batch in rows]
    padded = np.zeros((program.burst_size, c.batch_size, solo.layout.width), np.float32)
    padded[:count] = rows
    padded[count:] = 1e6  # never trained on: a pad that did train would wreck the weights
    got = program.burst(tf.constant(padded), tf.constant(count)).numpy()
    np.testing.assert_allclose(got[:count], expected, rtol=1e-6)
    assert not got[count:].any()
    for name, weights in solo.weights().items():
        for a, b in zip(weights, traced.weights()[name]):
            np.testing.assert_allclose(b, a, rtol=1e-6, atol=1e-6)


@pytest.mark.slow
def test_post_003_evaluates_logs_and_stops_at_its_threshold_on_the_compiled_engine(tmp_path):
    """Post 000's features above, for post 003's chunked program: evaluation during training and
    TensorBoard from its chunks' records, and the threshold stopping the run where the loop would
    (its 100-episode mean is 0 before episode 100, P003-METRIC, so a threshold of -1 is reached at
    once)."""
    settings = TrainSettings(progress=False, tensorboard=tmp_path / "tb", evaluation=EvalSchedule(every=2, episodes=1))
    summary = train_cartpole("compiled", cartpole(episodes=4), tmp_path / "run", settings)
    assert summary.status == "completed" and summary.episodes_run == 4
    assert len((tmp_path / "run" / "evaluations.csv").read_text().splitlines()) == 3  # a header, episodes 2 and 4
    assert list((tmp_path / "tb").rglob("events.out.tfevents.*"))
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["provenance"]["engine"] == "compiled"
    stopped = train_cartpole("compiled", cartpole(threshold=-1.0, stop_at_threshold=True), tmp_path / "stop")
    loop = train_cartpole("gymnasium", cartpole(threshold=-1.0, stop_at_threshold=True), tmp_path / "loop")
    assert stopped.status == "completed" and stopped.success and stopped.reached_at_episode == 1
    assert (stopped.episodes_run, stopped.total_steps) == (loop.episodes_run, loop.total_steps) == (1, loop.total_steps)
