"""The vectorised engine (``keras_rl/train/vectorised.py``, ``--engine vectorised``): post 003's
PyTorch tutorial on a batch of seeds in one program writes the run folders every engine writes; a
seed's folder is the same alone and inside a batch (its episodes and its final weights, bit for
bit); a batch stopped by Ctrl-C or killed, then ``--resume``d, equals the straight batch, also
after it shed a finished seed; a solo
run extended by ``--resume --episodes N`` equals a straight run of N, and its checkpoint resumes
on no other engine; evaluation during training and TensorBoard write their files and leave
training as it is; a non-finite loss stops its seed, naming the episode; what it cannot run is
refused with exit 2, naming why, before TensorFlow or torch loads.

Eager, on the CPU, 12-episode budgets (the tutorial trains from its 128th env step, episode 8 or
so of seeds 0-2, so the last episodes train); the core's own tests are
``tests/test_torch_vectorised.py``."""

from __future__ import annotations

import csv
import json
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from clitools import CLI
from test_resume import stop_when, stop_when_on_disk

from keras_rl.cli import main
from keras_rl.errors import ConfigError
from keras_rl.runs.checkpoint import read_checkpoint

BUDGET = 12
SEEDS = [0, 1, 2]
IN_A_RUN_FOLDER = {"config.json", "episodes.csv", "summary.json", "q_network.pt"}

TRAINS = pytest.mark.xdist_group("vectorised-engine")
"""A test that trains: its module's runs are made once, in one process (and it is ``slow``)."""


def needs_torch():
    pytest.importorskip("torch", reason="needs the torch extra")


def reproduce(out: Path, seeds: str, *extra: str, episodes: int = BUDGET, engine: str = "vectorised") -> list[str]:
    """``reproduce``'s arguments for post 003 in PyTorch on the vectorised engine."""
    return [
        "reproduce",
        "cartpole",
        "--framework",
        "torch",
        "--engine",
        engine,
        "--seeds",
        seeds,
        "--episodes",
        str(episodes),
        "--no-progress",
        "--out",
        str(out),
        *extra,
    ]


def rows(path: Path) -> list[dict[str, str]]:
    """``episodes.csv``'s rows but their wall time."""
    with open(path, newline="") as fh:
        return [{k: v for k, v in r.items() if k != "wall_seconds"} for r in csv.DictReader(fh)]


def episodes(run_dir: Path) -> list[dict[str, str]]:
    return rows(run_dir / "episodes.csv")


def summary(run_dir: Path) -> dict:
    return json.loads((run_dir / "summary.json").read_text())


@pytest.fixture(scope="module")
def batch(tmp_path_factory) -> Path:
    """Seeds 0-2 as one batch of 3 (``--seed-batch 3``), 12 episodes: its ``--out`` folder."""
    needs_torch()
    out = tmp_path_factory.mktemp("vectorised") / "batch"
    assert main(reproduce(out, "0-2", "--seed-batch", "3")) == 1  # 12 episodes cannot reach 475
    return out


@pytest.fixture(scope="module")
def solo(tmp_path_factory) -> Path:
    """Seed 1 alone (a batch of one), 12 episodes: its seed folder."""
    needs_torch()
    out = tmp_path_factory.mktemp("vectorised") / "solo"
    assert main(reproduce(out, "1")) == 1
    return out / "seed_1"


@pytest.mark.slow
@TRAINS
def test_a_seed_plays_the_same_episodes_and_ends_with_the_same_weights_alone_and_in_a_batch(batch, solo):
    """The run folders are every engine's (the loss column, the provenance naming the engine, the
    device and the batch; no checkpoint once a batch ends); seed 1's rows and ``q_network.pt``
    are the same bytes inside the batch as alone, though the batch's chunks end elsewhere (its
    weights are read at its last episode's end in both); the seeds of the batch are not one
    seed thrice; the set is read by ``RunSet`` and its weights by ``keras-rl evaluate``."""
    from keras_rl.runs.evaluate import evaluate_run
    from keras_rl.runs.run_set import RunSet

    for seed in SEEDS:
        run_dir = batch / f"seed_{seed}"
        assert IN_A_RUN_FOLDER <= {p.name for p in run_dir.iterdir()}
        assert not (run_dir / "checkpoint.pkl").exists()  # a batch that ended removes them
        s = summary(run_dir)
        assert (s["status"], s["episodes_run"], s["framework"]) == ("completed", BUDGET, "torch")
        assert s["provenance"]["engine"] == "vectorised" and s["provenance"]["device"] == "cpu"
        assert s["provenance"]["seed_batch"] == SEEDS
        played = episodes(run_dir)
        assert [int(r["episode"]) for r in played] == list(range(1, BUDGET + 1))
        assert all(r["score"] == f"{int(r['steps'])}.0" for r in played)
        assert played[0]["loss"] == "" and played[-1]["loss"] != ""  # it trained from step 128 on
    assert episodes(batch / "seed_1") == episodes(solo)
    assert (batch / "seed_1" / "q_network.pt").read_bytes() == (solo / "q_network.pt").read_bytes()
    assert "seed_batch" not in summary(solo)["provenance"]
    assert (solo / "checkpoint.pkl").is_file()  # a solo run keeps its final one, to be extended
    scores = [[r["score"] for r in episodes(batch / f"seed_{s}")] for s in SEEDS]
    assert scores[0] != scores[1] != scores[2] != scores[0]

    runs = RunSet(batch)
    assert runs.seeds == SEEDS and [len(r.rows()) for r in runs.runs()] == [BUDGET] * 3
    result = evaluate_run(batch / "seed_1", episodes=2)
    assert result["episodes"] == 2 and all(1 <= score <= 500 for score in result["scores"])


@pytest.mark.slow
@TRAINS
def test_a_seed_stopped_at_its_threshold_keeps_the_weights_it_had_then_alone_and_in_a_batch(tmp_path):
    """Where the run stops at the threshold (here a 2-episode mean of 25, which seed 1 reaches at
    its 5th episode), no chunk runs past an episode that could reach it: seed 1 stops there with
    the same rows and weights in a batch of 3 as alone, while the batch plays on."""
    stop = ("--set", "stop_at_threshold=true", "--set", "threshold=25", "--set", "mean_window=2")
    main(reproduce(tmp_path / "batch", "0-2", "--seed-batch", "3", *stop, episodes=20))
    main(reproduce(tmp_path / "solo", "1", *stop, episodes=20))
    in_batch, alone = tmp_path / "batch" / "seed_1", tmp_path / "solo" / "seed_1"
    assert (summary(alone)["status"], summary(alone)["reached_at_episode"]) == ("completed", 5)
    assert episodes(in_batch) == episodes(alone) and len(episodes(alone)) == 5
    assert (in_batch / "q_network.pt").read_bytes() == (alone / "q_network.pt").read_bytes()
    assert max(summary(tmp_path / "batch" / f"seed_{s}")["episodes_run"] for s in SEEDS) > 5


@pytest.mark.slow
@TRAINS
def test_a_solo_run_extended_by_resume_equals_a_straight_run_of_the_larger_budget(solo, tmp_path):
    """``--resume --episodes 16`` on seed 1's 12 episodes continues from the final checkpoint,
    taken at the end of its last episode, as a straight run of 16 plays: rows and weights."""
    out = tmp_path / "extended"
    shutil.copytree(solo, out / "seed_1")
    assert main(reproduce(out, "1", "--resume", episodes=16)) == 1
    assert main(reproduce(tmp_path / "straight", "1", episodes=16)) == 1
    extended, straight = out / "seed_1", tmp_path / "straight" / "seed_1"
    assert episodes(extended)[:BUDGET] == episodes(solo)
    assert episodes(extended) == episodes(straight) and len(episodes(straight)) == 16
    assert (extended / "q_network.pt").read_bytes() == (straight / "q_network.pt").read_bytes()
    assert (summary(extended)["episodes_run"], summary(extended)["budget_episodes"]) == (16, 16)


@pytest.mark.slow
@TRAINS
def test_its_checkpoint_resumes_on_no_other_engine(solo, tmp_path, capsys):
    """Seed 1's final checkpoint, extended on the Gymnasium loop: refused before anything runs,
    naming the engine that wrote it."""
    out = tmp_path / "other"
    shutil.copytree(solo, out / "seed_1")
    assert main(reproduce(out, "1", "--resume", episodes=16, engine="gymnasium")) == 2
    assert "written by the vectorised engine; resume it with --engine vectorised" in capsys.readouterr().err
    assert episodes(out / "seed_1") == episodes(solo)


@pytest.mark.slow
@TRAINS
def test_a_seed_whose_loss_is_not_finite_stops_alone_naming_the_episode(tmp_path):
    """A learning rate of 1e30 makes the loss NaN within a few updates: the seed stops at the
    episode whose mean loss is not finite (read at the episode's end), keeps the episodes before
    it and saves no weights; the exit code says a seed stopped with an error."""
    out = tmp_path / "nan"
    assert main(reproduce(out, "0", "--set", "q_lr=1e30", "--set", "weight_decay=0", episodes=30)) == 1
    s = summary(out / "seed_0")
    assert s["status"] == "non_finite_loss"
    assert re.search(rf"loss became (nan|-?inf) in episode {s['episodes_run'] + 1} ", s["message"]), s["message"]
    assert len(episodes(out / "seed_0")) == s["episodes_run"] < 30
    assert not (out / "seed_0" / "q_network.pt").exists()


def resumes_to_the_straight_batch(out: Path, batch: Path, when: str) -> None:
    """``--resume`` of the stopped batch in ``out`` completes every seed with the straight batch's
    rows and final weights, bit for bit, and leaves no checkpoint."""
    assert main(reproduce(out, "0-2", "--seed-batch", "3", "--resume")) == 1
    for seed in SEEDS:
        run_dir = out / f"seed_{seed}"
        assert episodes(run_dir) == episodes(batch / f"seed_{seed}"), f"seed {seed}, {when}"
        assert (run_dir / "q_network.pt").read_bytes() == (batch / f"seed_{seed}" / "q_network.pt").read_bytes()
        assert summary(run_dir)["status"] == "completed" and not (run_dir / "checkpoint.pkl").exists()


@pytest.mark.parametrize("stop", ["SIGINT", "SIGKILL"])
@pytest.mark.slow
@TRAINS
def test_a_batch_stopped_mid_run_and_resumed_equals_the_straight_batch(batch, tmp_path, stop):
    """The batch of 3 in another process, stopped once seed 0 has 5 episodes on disk: by Ctrl-C
    (taken after the chunk: exit 130, every running seed ``interrupted`` naming the signal, every
    seed's checkpoint written at one env step) or by SIGKILL (the periodic checkpoint of
    ``--checkpoint-every 2``); ``--resume`` then gives every seed the straight batch's rows and
    final weights, bit for bit."""
    out = tmp_path / "stopped"
    command = [*CLI, *reproduce(out, "0-2", "--seed-batch", "3", "--checkpoint-every", "2")]
    code, stderr = stop_when_on_disk(command, out / "seed_0" / "episodes.csv", 5, getattr(signal, stop))
    kept = [len(episodes(out / f"seed_{s}")) for s in SEEDS]
    assert 5 <= kept[0] < BUDGET, f"the run had played {kept} episodes when it stopped"
    for seed in SEEDS:
        assert (out / f"seed_{seed}" / "checkpoint.pkl").is_file()
    if stop == "SIGKILL":
        assert code == -signal.SIGKILL, stderr[-2000:]
    else:
        assert code == 130, stderr[-2000:]
        for seed in SEEDS:
            s = summary(out / f"seed_{seed}")
            assert s["status"] == "interrupted" and "SIGINT" in s["message"], s
            assert s["episodes_run"] == kept[seed]
    resumes_to_the_straight_batch(out, batch, f"resumed after {kept}")


@pytest.mark.parametrize("stop", ["SIGINT", "SIGKILL"])
@pytest.mark.slow
@TRAINS
def test_a_batch_that_shed_a_finished_seed_resumes_to_the_straight_batch(batch, tmp_path, stop):
    """A seed done with its budget leaves the batch (``VectorisedDQN.keep``) instead of stepping
    on to the end of its longest seed. Stopped once one seed has completed: by Ctrl-C, the seeds
    still in the batch write their checkpoints and the shed seed's goes; by SIGKILL, often while
    the periodic checkpoints of ``--checkpoint-every 1`` are written, what was written stands
    (the shed seed's checkpoint too, until the batch writes its next). Either way ``--resume``
    gives every seed the straight batch's rows and final weights, bit for bit."""
    out = tmp_path / "stopped"
    command = [*CLI, *reproduce(out, "0-2", "--seed-batch", "3", "--checkpoint-every", "1")]
    completed = lambda d: (d / "summary.json").is_file() and summary(d)["status"] == "completed"  # noqa: E731
    code, stderr = stop_when(command, lambda: any(completed(out / f"seed_{s}") for s in SEEDS), getattr(signal, stop))
    done = [s for s in SEEDS if summary(out / f"seed_{s}")["status"] == "completed"]
    assert 1 <= len(done) < len(SEEDS) and code != 0, (f"seeds {done} completed before the stop", stderr[-2000:])
    if stop == "SIGINT":
        for seed in SEEDS:
            held = (out / f"seed_{seed}" / "checkpoint.pkl").is_file()
            assert held == (seed not in done), seed
            assert not held or read_checkpoint(out / f"seed_{seed}")["batch"] == SEEDS
    resumes_to_the_straight_batch(out, batch, f"seeds {done} done at the stop")


@pytest.mark.slow
@TRAINS
def test_evaluation_during_training_and_tensorboard_write_their_files_and_leave_training_as_it_is(solo, tmp_path):
    """``--eval-every 4 --eval-episodes 2 --tensorboard``: ``evaluations.csv`` after episodes 4, 8
    and 12, the best mean's weights in ``best/``, one TensorBoard run with the episodes' scalars;
    the rows and final weights are the solo run's (an evaluation reads the policy between chunks
    and draws nothing from the seed's streams)."""
    out, board = tmp_path / "eval", tmp_path / "tb"
    args = reproduce(out, "1", "--eval-every", "4", "--eval-episodes", "2", "--tensorboard", str(board))
    assert main(args) == 1
    run_dir = out / "seed_1"
    assert episodes(run_dir) == episodes(solo)
    assert (run_dir / "q_network.pt").read_bytes() == (solo / "q_network.pt").read_bytes()
    with open(run_dir / "evaluations.csv", newline="") as fh:
        evaluated = list(csv.DictReader(fh))
    assert [int(r["episode"]) for r in evaluated] == [4, 8, 12]
    assert all(1 <= float(r["mean"]) <= 500 for r in evaluated)
    best = json.loads((run_dir / "best" / "best.json").read_text())
    assert best["episode"] in (4, 8, 12) and (run_dir / "best" / "q_network.pt").is_file()
    (seed_board,) = board.iterdir()
    assert seed_board.name == "cartpole-faithful-torch-seed1"
    assert any(p.name.startswith("events.out.tfevents") for p in seed_board.iterdir())


# -- refusals ---------------------------------------------------------------------------------------

REFUSED = [  # reproduce's arguments, what the refusal names
    (["pendulum", "--framework", "torch"], "runs cartpole (post 003's PyTorch tutorial) only; run pendulum"),
    (["cartpole"], "not framework 'keras'"),
    (["cartpole", "--framework", "torch", "--set", "init=keras"], "not init='keras' (P003-INIT)"),
    (["cartpole", "--framework", "torch", "--matched-init"], "drop --matched-init"),
    (["cartpole", "--framework", "torch", "--set", "amsgrad=false"], "amsgrad=false"),
    (["cartpole", "--framework", "torch", "--seed-batch", "auto"], "takes --seed-batch S, a whole number"),
]


@pytest.mark.parametrize("given, named", REFUSED, ids=[" ".join(g) for g, _ in REFUSED])
def test_what_it_cannot_run_is_refused_with_exit_2_naming_why(given, named, tmp_path, capsys):
    code = main(["reproduce", *given, "--engine", "vectorised", "--dry-run", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and named in err, err
    assert not any(tmp_path.iterdir())


def test_its_refusals_need_neither_tensorflow_nor_torch(tmp_path):
    """``--engine vectorised`` for pendulum is refused before TensorFlow or torch loads."""
    code = (
        "import sys; from keras_rl.cli import main; "
        "code = main(['reproduce', 'pendulum', '--engine', 'vectorised', '--dry-run', '--out', sys.argv[1]]); "
        "print(code, 'tensorflow' in sys.modules, 'torch' in sys.modules)"
    )
    proc = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert proc.stdout.split() == ["2", "False", "False"], proc.stdout + proc.stderr
    assert "--engine vectorised: the vectorised engine runs cartpole" in proc.stderr


def test_the_engine_refuses_before_it_trains_and_the_options_let_it_batch(tmp_path):
    """The engine itself refuses too (a notebook or a job reaches it without ``plan``), naming
    every reason at once; ``--seed-batch S`` is the vectorised engine's as it is the loop's."""
    from keras_rl.dispatch.options import RunOptions
    from keras_rl.registry import get_experiment
    from keras_rl.train.engine import get_engine
    from keras_rl.train.settings import TrainSettings

    engine, cartpole = get_engine("vectorised"), get_experiment("cartpole")
    config = cartpole.config_cls.for_variant("faithful", init="keras", amsgrad=False)
    why = engine.refusal(cartpole, config)
    assert "framework 'keras'" in why and "init='keras'" in why and "amsgrad=false" in why
    with pytest.raises(ConfigError, match="framework 'keras'"):
        engine.train(cartpole, [config], [tmp_path / "a"], TrainSettings(progress=False))
    assert not (tmp_path / "a").exists()
    assert engine.refusal(cartpole, cartpole.config_cls.for_variant("pr-3384", framework="torch")) is None
    assert RunOptions.checked(engine="vectorised", seed_batch=8).seed_batch == 8
    with pytest.raises(ConfigError, match="engine=compiled runs one seed per program"):
        RunOptions.checked(engine="compiled", seed_batch=8)


@pytest.mark.slow
@TRAINS
def test_the_compiled_program_is_an_engine_of_its_own_that_resumes_bit_for_bit(tmp_path, capsys):
    """``vectorised-compiled`` (the step through ``torch.compile``) rounds otherwise than the eager
    program, so its runs name it, a checkpoint of it resumes on it alone, and resumed it plays
    what a straight run of it plays."""
    straight, resumed = tmp_path / "straight", tmp_path / "resumed"
    compiled = "vectorised-compiled"
    assert main(reproduce(straight, "1", episodes=6, engine=compiled)) == 1
    assert summary(straight / "seed_1")["provenance"]["engine"] == compiled
    assert main(reproduce(resumed, "1", episodes=3, engine=compiled)) == 1
    capsys.readouterr()
    assert main(reproduce(resumed, "1", "--resume", episodes=6, engine="vectorised")) == 2
    assert f"written by the {compiled} engine; resume it with --engine {compiled}" in capsys.readouterr().err
    assert main(reproduce(resumed, "1", "--resume", episodes=6, engine="auto")) == 1  # the set's engine
    assert episodes(resumed / "seed_1") == episodes(straight / "seed_1")
    assert summary(resumed / "seed_1")["provenance"]["engine"] == compiled


@pytest.mark.parametrize(
    "queue, plan, sets",
    [
        ("vectorised.tsv", "results/cartpole/vectorised-torch/plan.md", 1),
        ("tutorial-fix-vectorised.tsv", "results/cartpole/tutorial-fix/plan.md", 2),
    ],
)
def test_the_vectorised_queues_run_the_commands_their_plans_name(queue, plan, sets):
    """``maintainers/queues/vectorised.tsv`` (the certification arm) and ``tutorial-fix-vectorised.tsv``
    (issue 53 item 5's proposals) make their sets as their plans word them (the queue adds
    ``--resume --out FOLDER``), into sets those plans govern."""
    from maintainers.plans import PLANS

    root = Path(__file__).resolve().parents[1]
    text = (root / plan).read_text()
    lines = (root / "maintainers" / "queues" / queue).read_text().splitlines()
    runs = [line.split("\t") for line in lines if line and not line.startswith("#")]
    assert len(runs) == sets
    governed = {folder for p in PLANS if p.path == plan for folder in p.governs}
    for folder, args in runs:
        assert f"keras-rl {args} --resume --out {folder}" in text
        assert folder.removeprefix("results/") in governed
