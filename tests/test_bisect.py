"""``keras-rl bisect`` (issue #21, item 5) on a throwaway repository with a planted regression.

The repository's own ``keras_rl`` is a stand-in whose ``check`` reads ``learner.txt``: a commit
that writes "broken" there makes the learner's p tiny, as a real regression would. Bisect runs
each commit's own ``python -m keras_rl check``, so the stand-in is what it drives."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from keras_rl.check.bisect import judge, step_budget
from keras_rl.cli import main

FAKE_CHECK = """
import json, sys
from pathlib import Path
args = sys.argv[1:]
out = Path(args[args.index("--out") + 1])
names = [a for a in args[1:args.index("--tier")]]
state = Path("learner.txt").read_text().strip()
if state == "crash":
    sys.exit(3)
if state == "sleep":  # a check that takes long: bisect is stopped while it runs
    import time
    time.sleep(120)
p = {"broken": 1e-6, "slightly": 0.006, "moderately": 0.001}.get(state, 0.5)
out.mkdir(parents=True, exist_ok=True)
# the real check's levels: --sequential --alpha splits alpha over the posts and 6 looks; else 0.01
level = float(args[args.index("--alpha") + 1]) / len(names) / 6 if "--sequential" in args else 0.01
experiments = [
    {"experiment": n, "decision": {"p": q, "changed": q < level}, "new": {"1000": 0.0}}
    for n, q in ((n, p if n == "pendulum" else 0.5) for n in names)
]
(out / "check.json").write_text(json.dumps({"experiments": experiments}))
(out / "args.json").write_text(json.dumps(args))
sys.exit(1 if any(e["decision"]["changed"] for e in experiments) else 0)
"""


def make_repo(root: Path, states: list[str]) -> list[str]:
    """A repository whose i-th commit sets learner.txt to states[i]; the commits' hashes."""
    root.mkdir()
    (root / "keras_rl").mkdir()
    (root / "keras_rl" / "__init__.py").write_text("")
    (root / "keras_rl" / "__main__.py").write_text(FAKE_CHECK)

    def git(*args):
        return subprocess.run(["git", *args], cwd=root, check=True, capture_output=True, text=True).stdout.strip()

    git("init", "-q")
    git("config", "user.email", "t@example.invalid")
    git("config", "user.name", "t")
    shas = []
    for i, state in enumerate(states):
        (root / "learner.txt").write_text(state + "\n")
        (root / f"file_{i}.txt").write_text(str(i))
        git("add", "-A")
        git("commit", "-q", "-m", f"commit {i}: learner {state}")
        shas.append(git("rev-parse", "HEAD"))
    return shas


@pytest.fixture
def baseline(tmp_path):
    folder = tmp_path / "checks"
    (folder / "pendulum" / "baseline" / "seed_0").mkdir(parents=True)
    return folder


def run(repo, baseline, out, *args):
    return main(["bisect", *args, "pendulum", "--repo", str(repo), "--against", str(baseline), "--out", str(out)])


def test_bisect_finds_the_planted_regression_and_leaves_the_repository_alone(tmp_path, baseline, capsys):
    shas = make_repo(tmp_path / "repo", ["ok"] * 5 + ["broken"] * 4)  # commit 5 breaks it
    before = subprocess.run(["git", "status", "--porcelain"], cwd=tmp_path / "repo", capture_output=True, text=True)
    code = run(tmp_path / "repo", baseline, tmp_path / "out", shas[0], shas[-1])
    assert code == 0, capsys.readouterr().err
    assert f"first changed commit: {shas[5]}" in capsys.readouterr().out
    report = json.loads((tmp_path / "out" / "bisect.json").read_text())
    assert report["first_changed"] == shas[5] and report["outcome"] == "found"
    assert report["commits"] == 8 and report["alpha_per_step"] == pytest.approx(0.01 / 4)  # BAD + ceil(log2 8)
    assert report["steps"][0]["commit"] == shas[-1] and report["steps"][0]["verdict"] == "changed"
    assert report["sequential"]  # each step ran the sequential check at its share of alpha
    args = json.loads((tmp_path / "out" / "step_1" / "args.json").read_text())
    assert args[args.index("--alpha") - 1] == "--sequential" and float(args[args.index("--alpha") + 1]) == 0.01 / 4
    assert len(report["steps"]) <= step_budget(8)
    assert (tmp_path / "out" / "baseline" / "pendulum" / "baseline").is_dir()  # the baseline copied out of the tree
    assert "the first changed commit" in (tmp_path / "out" / "bisect.md").read_text()
    after = subprocess.run(["git", "status", "--porcelain"], cwd=tmp_path / "repo", capture_output=True, text=True)
    assert after.stdout == before.stdout
    worktrees = subprocess.run(["git", "worktree", "list"], cwd=tmp_path / "repo", capture_output=True, text=True)
    assert len(worktrees.stdout.strip().splitlines()) == 1  # its temporary worktree is gone


@pytest.mark.parametrize("fixed", [False, True])
def test_a_change_below_the_per_step_alpha_is_not_a_regression(fixed, tmp_path, baseline, capsys):
    """p = 0.006 clears the check's own 0.01 but not bisect's 0.01 / 2 per step (2 commits: BAD
    and one more), with the fixed rule or the sequential check: BAD is consistent."""
    shas = make_repo(tmp_path / "repo", ["ok", "ok", "slightly"])
    flags = ["--fixed-n"] if fixed else []
    assert run(tmp_path / "repo", baseline, tmp_path / "out", *flags, shas[0], shas[-1]) == 1
    assert "nothing to bisect" in capsys.readouterr().out


def test_the_sequential_step_splits_its_share_over_the_looks(tmp_path, baseline, capsys):
    """p = 0.001 at the last look clears a fixed-rule step's 0.005 but not the sequential step's
    0.005 / 6 looks: the two modes differ exactly by the union bound, and the report says which ran."""
    shas = make_repo(tmp_path / "repo", ["ok", "ok", "moderately"])
    assert run(tmp_path / "repo", baseline, tmp_path / "seq", shas[0], shas[-1]) == 1
    assert run(tmp_path / "repo", baseline, tmp_path / "fixed", "--fixed-n", shas[0], shas[-1]) == 0
    assert "p at the last look" in (tmp_path / "seq" / "bisect.md").read_text()
    assert "Holm" in (tmp_path / "fixed" / "bisect.md").read_text()
    fixed = json.loads((tmp_path / "fixed" / "bisect.json").read_text())
    assert not fixed["sequential"] and fixed["first_changed"] == shas[2]
    args = json.loads((tmp_path / "fixed" / "step_1" / "args.json").read_text())
    assert "--sequential" not in args and "--alpha" not in args


def test_a_commit_whose_check_crashes_is_skipped(tmp_path, baseline, capsys):
    shas = make_repo(tmp_path / "repo", ["ok", "ok", "crash", "broken", "broken"])
    """Commit 2 cannot be checked and commit 3 is broken: the first change is 2 or 3, and bisect
    says so (exit 3, no verdict) rather than guess."""
    assert run(tmp_path / "repo", baseline, tmp_path / "out", shas[0], shas[-1]) == 3
    report = json.loads((tmp_path / "out" / "bisect.json").read_text())
    assert "no verdict" in [s["verdict"] for s in report["steps"]] and report["first_changed"] is None
    assert sorted(report["candidates"]) == sorted([shas[2], shas[3]])


def test_bad_input_exits_2(tmp_path, baseline, capsys):
    shas = make_repo(tmp_path / "repo", ["ok", "broken"])
    repo, out = tmp_path / "repo", tmp_path / "out"
    assert run(repo, baseline, out, shas[1], shas[0]) == 2  # GOOD after BAD
    assert "is not an ancestor" in capsys.readouterr().err
    assert run(repo, baseline, out, "nope", shas[1]) == 2
    assert "is not a commit" in capsys.readouterr().err
    assert run(repo, baseline, out, shas[0], shas[0]) == 2
    assert "nothing to bisect" in capsys.readouterr().err
    assert main(["bisect", shas[0], shas[1], "nosuch", "--repo", str(repo)]) == 2
    assert run(repo, tmp_path / "empty", out, shas[0], shas[1]) == 2
    assert "holds no pendulum/baseline" in capsys.readouterr().err


def test_holm_within_a_step_and_the_step_budget():
    assert judge({"pendulum": 0.001, "cartpole": 0.5}, 0.0025)[0] == "changed"  # 2 * 0.001 < 0.0025
    assert judge({"pendulum": 0.002, "cartpole": 0.5}, 0.0025)[0] == "consistent"  # 0.004 > 0.0025
    assert [step_budget(n) for n in (1, 2, 3, 8, 9, 100)] == [2, 2, 3, 4, 5, 8]


def test_the_bisect_levels_page_says_when_a_rate_is_over_its_share():
    """``maintainers/calibrate/bisect_levels.py`` flags a level only when its measured rate's
    whole interval lies above the share (here the second row), and says the bound holds otherwise."""
    import maintainers.calibrate.bisect_levels as module

    row = {"post": "pendulum", "statistic": "s", "commits": 8, "posts": 1, "share": 0.0025, "efficacy": 0.0004}
    fine = {**row, "changed": 3, "draws": 1000, "rate": 0.003, "ci": [0.0006, 0.0088]}
    over = {**row, "post": "cartpole", "changed": 30, "draws": 1000, "rate": 0.03, "ci": [0.02, 0.042]}
    assert "the bound holds" in module.render([fine])
    text = module.render([fine, over])
    assert "Above its share beyond its interval: cartpole at 0.0025" in text and "bound holds" not in text


@pytest.mark.slow
def test_sigterm_during_a_step_exits_143_and_removes_the_temporary_worktree(tmp_path, baseline):
    import signal
    import time

    from clitools import start_cli

    shas = make_repo(tmp_path / "repo", ["ok", "sleep"])
    repo = tmp_path / "repo"

    def worktrees() -> list[str]:
        listed = subprocess.run(["git", "worktree", "list", "--porcelain"], cwd=repo, capture_output=True, text=True)
        return [line.split(" ", 1)[1] for line in listed.stdout.splitlines() if line.startswith("worktree ")]

    argv = ["bisect", shas[0], shas[1], "pendulum", "--repo", str(repo), "--against", str(baseline)]
    proc = start_cli(*argv, "--out", str(tmp_path / "out"))
    deadline = time.monotonic() + 120
    while len(worktrees()) < 2 and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.1)
    added = [w for w in worktrees() if Path(w) != repo.resolve()]
    assert len(added) == 1, worktrees()
    time.sleep(1.0)  # the step's check is running
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    assert worktrees() == [str(repo.resolve())]
    assert not Path(added[0]).exists()


@pytest.mark.slow
def test_a_default_changed_by_accident_is_checked_and_bisected_in_the_real_package(tmp_path):
    """The regression check exists for: post 000's actor_lr default changed from 1e-3 to 1e-5 in
    a commit of a throwaway clone of the real package. The real ``bisect`` runs that commit's own
    ``check`` (sequential, its first look of 5 fresh seeds against the committed baseline): the
    check runs the changed default (it was refused: "not a faithful run"), names the field beside
    its verdict, and bisect names the commit."""
    import sys

    root = Path(__file__).resolve().parent.parent
    repo = tmp_path / "clone"
    subprocess.run(["git", "clone", "-q", str(root), str(repo)], check=True)

    def git(*args):
        return subprocess.run(["git", *args], cwd=repo, check=True, capture_output=True, text=True).stdout.strip()

    git("config", "user.email", "t@example.invalid")
    git("config", "user.name", "t")
    good = git("rev-parse", "HEAD")
    post = repo / "keras_rl" / "posts" / "pendulum.py"
    text = post.read_text()
    assert "    actor_lr: float = positive(1e-3)" in text
    post.write_text(text.replace("    actor_lr: float = positive(1e-3)", "    actor_lr: float = positive(1e-5)"))
    git("commit", "-q", "-am", "posts: a default changed by accident")
    bad = git("rev-parse", "HEAD")
    out = tmp_path / "bisect"
    argv = [sys.executable, "-m", "keras_rl", "bisect", good, bad, "pendulum", "--repo", str(repo)]
    argv += ["--against", str(root / "results" / "checks"), "--out", str(out), "--workers", "1"]
    done = subprocess.run(argv, cwd=tmp_path, capture_output=True, text=True, timeout=1200)
    assert done.returncode == 0, done.stderr
    assert f"first changed commit: {bad}" in done.stdout
    (step,) = [json.loads(p.read_text()) for p in out.glob("step_*/check.json")]
    (pendulum,) = step["experiments"]
    assert pendulum["verdict"] == "changed"
    assert pendulum["config_changes"] == ["actor_lr: 0.001 -> 1e-05"]


def test_a_stop_that_lands_while_the_worktree_is_added_still_removes_it(tmp_path, baseline, monkeypatch):
    """The signal a new user's pass sent as soon as the worktree was listed: it landed while
    ``git worktree add`` was still being waited on, before the clean-up was armed, and the
    worktree stayed. Here the add completes and the stop arrives at once."""
    from keras_rl.check import bisect as module

    shas = make_repo(tmp_path / "repo", ["ok", "broken"])
    repo = tmp_path / "repo"
    real_git = module.git
    added = []

    def git_then_stop(where, *args, check=True):
        out = real_git(where, *args, check=check)
        if args[:2] == ("worktree", "add"):
            added.append(Path(args[-2]))
            raise KeyboardInterrupt
        return out

    monkeypatch.setattr(module, "git", git_then_stop)
    with pytest.raises(KeyboardInterrupt):
        module.bisect(repo, shas[0], shas[1], ["pendulum"], "smoke", baseline, tmp_path / "out")
    listed = subprocess.run(["git", "worktree", "list"], cwd=repo, capture_output=True, text=True).stdout
    assert len(listed.strip().splitlines()) == 1, listed
    assert len(added) == 1 and not added[0].exists()
