"""A set holds one kind of run, a config checks its fields at construction, and the API's switches
and seeds are what they say: what a new user found (issue 72, items 2-5 and 8-10), each refused by
name before anything is written (exit 2 on the command line, a ConfigError in the API)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys

import pytest
from committed import RESULTS, copy_seeds

from keras_rl import api
from keras_rl.cli import main
from keras_rl.errors import ConfigError, RunFolderError


def _listing(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.fixture
def pendulum_set(tmp_path):
    return copy_seeds(RESULTS / "pendulum/faithful", tmp_path / "pend", lambda s: s in (0, 1))


def test_a_set_of_one_post_refuses_the_seeds_of_another(pendulum_set, capsys):
    """Item 2: ``reproduce cartpole --seeds 7 --out <a pendulum set>`` exited 0 and left a folder of
    two posts, which ``aggregate`` then refused."""
    from keras_rl.posts.cartpole import CartPoleDQNConfig

    before = _listing(pendulum_set)
    code = main(["reproduce", "cartpole", "--seeds", "7", "--episodes", "1", "--out", str(pendulum_set)])
    assert code == 2
    err = capsys.readouterr().err
    assert "holds runs of pendulum (faithful, keras), seeds 0, 1" in err and "this is cartpole" in err
    with pytest.raises(ConfigError, match="a set holds one experiment, variant and framework"):
        api.reproduce(CartPoleDQNConfig(episodes=1), seeds=[5], out=pendulum_set)
    with pytest.raises(ConfigError, match=r"pendulum \(faithful, keras\).*this is pendulum \(fixed, keras\)"):
        api.reproduce("pendulum", variant="fixed", seeds=[5], episodes=1, out=pendulum_set)
    assert _listing(pendulum_set) == before


def test_an_unknown_environment_is_named_before_any_folder_is_made(tmp_path):
    """Item 9: the ConfigError came after the empty folder was made."""
    from keras_rl.posts.pendulum import PendulumDDPGConfig

    out = tmp_path / "new"
    with pytest.raises(ConfigError, match="unknown environment 'Bogus-v0'"):
        api.reproduce(PendulumDDPGConfig(env_id="Bogus-v0", episodes=1), seeds=0, out=out)
    assert not out.exists()


@pytest.mark.parametrize(
    "argument, value, words",
    [
        ("resume", "yes", "resume must be True or False, got 'yes'"),
        ("overwrite", 1, "overwrite must be True or False, got 1"),
        ("progress", "no", "progress must be True or False, got 'no'"),
        ("seeds", {0: 1}, "seeds must be a whole number or several (a list, a range), not a mapping"),
    ],
)
def test_switches_and_seeds_of_the_wrong_type_are_refused(tmp_path, argument, value, words):
    """Item 10: these were accepted silently (a dict's keys used as seeds)."""
    out = tmp_path / "new"
    kwargs = {"seeds": 0, "episodes": 1, argument: value}
    with pytest.raises(ConfigError) as caught:
        api.reproduce("pendulum", out=out, **kwargs)
    assert words in str(caught.value)
    assert not out.exists()


def test_a_seed_given_as_a_string_is_named_as_such(pendulum_set):
    """Item 10: ``load(...).run("0")`` said the set "holds no finished seed 0"."""
    runs = api.load(pendulum_set)
    with pytest.raises(ConfigError, match="a seed is a whole number, got '0'"):
        runs.run("0")
    with pytest.raises(RunFolderError, match="holds no finished seed 9"):
        runs.run(9)
    assert runs.run(1).seed == 1


WITHOUT_ROOTS_OVERRIDE = (
    ["setpriv", "--bounding-set=-dac_override,-dac_read_search", "--inh-caps=-dac_override,-dac_read_search", "--"]
    if os.geteuid() == 0
    else []
)
"""As root, the command runs without the capabilities that let root write into a read-only folder
(``setpriv``, util-linux): still uid 0, so it reads the interpreter under /root, but a 0555 folder
refuses its writes as it would a user's."""


@pytest.mark.skipif(os.geteuid() == 0 and not shutil.which("setpriv"), reason="root needs setpriv to drop its override")
def test_a_seed_folder_that_cannot_be_written_is_named_with_exit_2(tmp_path):
    """Item 4: ``--out ro3`` where ``ro3/seed_0`` is read-only exited 1 after TensorFlow loaded,
    on a temporary file it could not make. Now exit 2, naming the folder, before TensorFlow loads."""
    out = tmp_path / "ro3"
    seed = out / "seed_0"
    seed.mkdir(parents=True)
    seed.chmod(0o555)
    probe = subprocess.run([*WITHOUT_ROOTS_OVERRIDE, "touch", str(seed / "probe")], capture_output=True)
    assert probe.returncode != 0, "the read-only folder took a write: the test would prove nothing"
    try:
        done = subprocess.run(
            [*WITHOUT_ROOTS_OVERRIDE, sys.executable, "-X", "importtime", "-m", "keras_rl", "reproduce", "pendulum"]
            + ["--seeds", "0", "--episodes", "1", "--out", str(out)],
            capture_output=True,
            text=True,
            timeout=300,
        )
    finally:
        seed.chmod(0o755)
    assert done.returncode == 2, done.stderr[-2000:]
    assert f"{seed} is not a writable folder" in done.stderr and "Traceback" not in done.stderr
    # -X importtime lists every module imported, nested ones indented: TensorFlow never was
    assert not re.search(r"\|\s+tensorflow$", done.stderr, re.MULTILINE)
    assert _listing(out) == ["seed_0"]


def test_pack_keep_folders_works_where_its_refusal_recommends_it(pendulum_set, capsys):
    """Item 3: ``pack --keep-folders`` on a set whose folders hold weights exited 2 recommending
    ``--keep-folders``, and the set ``--keep-folders`` left held each seed twice, which every reader
    refused. Now the folders keep only their weights, the packed set holds the records, and readers
    take the set."""
    for seed in (0, 1):
        (pendulum_set / f"seed_{seed}" / "actor.weights.h5").write_bytes(b"\0" * 64)
    assert main(["pack", str(pendulum_set)]) == 2
    assert "pack with --keep-folders" in capsys.readouterr().err
    assert not (pendulum_set / "runs.parquet").exists()
    assert main(["pack", str(pendulum_set), "--keep-folders"]) == 0
    assert (pendulum_set / "runs.parquet").is_file() and (pendulum_set / "seed_0" / "actor.weights.h5").is_file()
    from keras_rl.runs.packed import open_packed

    packed = open_packed(pendulum_set / "runs.parquet")
    assert packed.seeds == [0, 1] and "actor.weights.h5" not in packed.record(0).files
    assert _listing(pendulum_set / "seed_0") == ["actor.weights.h5"]
    assert api.load(pendulum_set).seeds == [0, 1]
    assert main(["aggregate", str(pendulum_set)]) == 0
    assert main(["pack", str(pendulum_set)]) == 0  # packed again: the kept folders are not runs to pack
    assert _listing(pendulum_set / "seed_0") == ["actor.weights.h5"]


def test_a_torch_study_in_a_keras_set_names_the_framework_not_an_engine(pendulum_set):
    """Item 5: ``reproduce("pendulum", framework="torch", resume=True, out=<a Keras set>)`` said
    "--engine compiled: it runs the Keras learner", though no engine was given."""
    pytest.importorskip("torch")
    with pytest.raises(ConfigError) as caught:
        api.reproduce("pendulum", framework="torch", resume=True, seeds=[0], out=pendulum_set)
    said = str(caught.value)
    assert "holds runs of pendulum (faithful, keras)" in said and "this is pendulum (faithful, torch)" in said
    assert "--engine" not in said


@pytest.mark.parametrize(
    "fields, words",
    [
        ({"tau": "0.005"}, "tau must be a number, got '0.005'"),
        ({"tau": float("nan")}, "tau must be finite"),
        ({"episodes": 2.5}, "episodes must be a whole number, got 2.5"),
        ({"bogus": 1}, "unknown pendulum config field(s): bogus"),
        ({"env_id": 3}, "env_id must be a string, got 3"),
    ],
)
def test_a_config_checks_its_fields_at_construction(fields, words):
    """Item 8: these all constructed, and an unknown field raised a plain TypeError."""
    from keras_rl.posts.pendulum import PendulumDDPGConfig

    with pytest.raises(ConfigError) as caught:
        PendulumDDPGConfig(**fields)
    assert words in str(caught.value)


def test_a_config_takes_fields_by_name_and_holds_them_as_their_types():
    """Item 8: ``PendulumDDPGConfig(0.1)`` set ``variant``; a list of widths stayed a list and a NumPy
    whole number stayed NumPy."""
    import numpy as np

    from keras_rl.posts.pendulum import PendulumDDPGConfig

    with pytest.raises(ConfigError, match="takes its fields by name"):
        PendulumDDPGConfig(0.1)
    config = PendulumDDPGConfig(actor_hidden_units=[32, 32], batch_size=np.int64(32))
    assert config.actor_hidden_units == (32, 32) and type(config.batch_size) is int
    assert config == PendulumDDPGConfig.for_variant("faithful", actor_hidden_units=(32, 32), batch_size=32)
