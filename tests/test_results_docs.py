"""results/README.md's generated tables match the committed run folders and reports."""

import json
import re
import subprocess
from pathlib import Path

import pytest

from keras_rl.runs.run_set import RunSet

ROOT = Path(__file__).resolve().parents[1]


GENERATORS = {
    "findings_table": "maintainers.tables.findings",
    "ablation_table": "maintainers.tables.ablations",
    "compat_table": "maintainers.tables.compat",
    "forest": "maintainers.tables.forest",
    "manifest": "maintainers.manifest",
    "check_figure": "maintainers.tables.check_figure",
}


def load_generator(name: str = "findings_table"):
    from importlib import import_module

    return import_module(GENERATORS[name])


def block(text: str, begin: str, end: str) -> str:
    return text.split(begin, 1)[1].split(end, 1)[0].strip()


def test_the_findings_and_compare_tables_are_up_to_date():
    gen = load_generator()
    readme = (ROOT / "results" / "README.md").read_text()
    assert block(readme, gen.BEGIN, gen.END) == gen.table(), (
        "results/README.md is stale: run python -m maintainers tables findings --write"
    )
    assert block(readme, gen.COMPARE_BEGIN, gen.COMPARE_END) == gen.compare_table(), (
        "results/README.md is stale: run python -m maintainers tables findings --write"
    )
    assert block((ROOT / "README.md").read_text(), gen.SHORT_BEGIN, gen.SHORT_END) == gen.short_table(), (
        "README.md's findings are stale: run python -m maintainers tables findings --write"
    )
    assert "not run" not in gen.table()  # every row of the single table has its runs committed
    for experiment in ("pendulum", "cartpole", "mountaincar"):
        assert (ROOT / "results" / "compare" / experiment / "report.md").is_file(), experiment


def test_the_per_post_sections_are_up_to_date_and_name_the_seeds_that_failed():

    gen = load_generator()
    readme = (ROOT / "results" / "README.md").read_text()
    for post in gen.POSTS:
        assert block(readme, *gen.post_markers(post)) == gen.post_block(post), (
            f"results/README.md's {post} section is stale: run python -m maintainers tables findings --write"
        )
    failed = [
        s["seed"] for s in RunSet(ROOT / "results" / "cartpole" / "faithful").summary_records() if not s["success"]
    ]
    said = block(readme, *gen.post_markers("post003")).split("In Keras", 1)[1].split("never got there", 1)[0]
    assert said.rstrip().endswith(gen._seeds([{"seed": s} for s in failed]))


@pytest.mark.slow  # every ablation arm's 10,000-resample bootstraps
def test_fidelitys_measured_effect_tables_are_up_to_date():
    gen = load_generator("ablation_table")
    ledger = (ROOT / "reproductions" / "FIDELITY.md").read_text()
    for experiment in gen.SOURCES:
        assert block(ledger, *gen.markers(experiment)) == gen.table(experiment), (
            f"FIDELITY.md's {experiment} table is stale: run python -m maintainers tables ablations --write"
        )
    assert block(ledger, *gen.READINGS_MARKERS) == gen.readings_table(), (
        "FIDELITY.md's post 001 readings table is stale: run python -m maintainers tables ablations --write"
    )
    # every quirk switch of every post has its row, with numbers on 30 seeds or more (issue #20)
    from keras_rl.registry import get_experiment

    for experiment in gen.SOURCES:
        text = gen.table(experiment)
        for ledger_id in get_experiment(experiment).config_cls.QUIRKS.values():
            row = next(line for line in text.splitlines() if line.startswith(f"| {ledger_id[0]} |"))
            assert "not run yet" not in row and int(row.split("|")[3].split("/")[1].split()[0]) >= 30, row


def test_every_committed_run_records_the_commit_and_clean_tree_that_made_it():

    from keras_rl.runs.run_set import RunSet

    summaries = [(r.where, r.summary_record()) for s in RunSet.find(ROOT / "results") for r in s.runs()]
    assert len(summaries) > 500
    missing = [where for where, s in summaries if not s.get("provenance", {}).get("commit")]
    dirty = [where for where, s in summaries if s["provenance"].get("dirty")]
    assert not missing, f"runs without provenance (regenerate them): {missing[:5]}"
    assert not dirty, f"runs made from a dirty tree (regenerate them from a clean checkout): {dirty[:5]}"


def test_the_version_matrix_table_is_generated_from_the_committed_cells():
    gen = load_generator("compat_table")
    page = (ROOT / "results" / "compat" / "README.md").read_text()
    assert page == gen.page(), "results/compat/README.md is stale: run python -m maintainers tables compat --write"
    assert block((ROOT / "README.md").read_text(), gen.SHORT_BEGIN, gen.SHORT_END) == gen.short_table(), (
        "README.md's version table is stale: run python -m maintainers tables compat --write"
    )


def test_the_matrix_table_shows_failed_installs_unrun_cells_and_divergences(tmp_path, monkeypatch):
    import json

    gen = load_generator("compat_table")
    monkeypatch.setattr(gen, "COMPAT", tmp_path)
    spec = {"tensorflow": "2.19.1", "keras": None, "gymnasium": "1.4.0", "numpy": None}
    for name, code in (("broken", 1), ("waiting", 0), ("ran", 0)):
        (tmp_path / name).mkdir()
        install = {"spec": spec, "exit_code": code, "seconds": 120.0}
        (tmp_path / name / "install.json").write_text(json.dumps(install))
    posts = ("pendulum", "cartpole", "mountaincar")
    divergence = {"compared": 3, "first_episode": 3, "columns": ["score"]}
    cell = {
        "versions": {"versions": {"tensorflow": "2.19.1", "keras": "3.15.1", "gymnasium": "1.4.0", "numpy": "2.1.3"}},
        "tests": {"exit_code": 1, "passed": 900, "failures": 2, "errors": 0},
        "envs": {
            "exit_code": 1,
            "passed": 14,
            "failures": 1,
            "errors": 0,
            "failed": [
                "tests.test_tf_envs::test_one_step_is_gymnasiums_bit_for_bit_on_tensorflows_kernels[CartPole-v1]"
            ],
        },
        "replay": {
            "posts": {p: {"bit_exact": p != "cartpole", "divergence": divergence, "exit_code": 0} for p in posts}
        },
        "check": {
            "smoke": {
                "exit_code": 1,
                "posts": {p: {"verdict": "changed" if p == "pendulum" else "consistent", "p": 0.004} for p in posts},
            },
            "rerun_at_full_tier": ["pendulum"],
            "full": {"posts": {"pendulum": {"verdict": "consistent", "p": 0.3}}},
        },
        "speed": {"cell_over_reference": {gen.SPEED_KEYS[p]: 1.1 for p in posts}},
        "probe": {"max_abs_difference": {p: {"initial": 0.0, "loss": 9e-8} for p in posts}},
        "seconds": 1200.0,
    }
    (tmp_path / "ran" / "cell.json").write_text(json.dumps(cell))
    rows = {line.split("|")[1].strip(): line for line in gen.table().splitlines()[2:]}
    assert "**failed**" in rows["broken"] and "not run yet" in rows["waiting"]
    ran = rows["ran"]
    assert "2.1.3" in ran and "**2 failed**, 900 passed" in ran and "differs from ep 3 (score)" in ran
    assert "changed (p=0.004); full tier: consistent (p=0.3)" in ran and "1.10 / 1.10 / 1.10" in ran
    assert "rounding (9e-08)" in ran
    assert "**1 failed**: CartPole-v1 (1) (`envs.log`)" in ran
    del cell["envs"]
    (tmp_path / "ran" / "cell.json").write_text(json.dumps(cell))
    assert "| not run |" in next(line for line in gen.table().splitlines() if line.startswith("| ran "))
    short = gen.short_table()
    assert "000, 001 (2/3)" in short and "changed or no verdict: 000" in short and "install failed" in short


@pytest.mark.xdist_group("manifest")  # shares test_maintain_commands.py's reading of every set
def test_the_manifest_lists_every_committed_run_set_as_it_is():
    import json

    gen = load_generator("manifest")
    entries = gen.manifest()
    committed = json.loads((ROOT / "results" / "MANIFEST.json").read_text())
    assert entries == committed, "results/MANIFEST.json is stale: run python -m maintainers manifest --write"
    assert (ROOT / "results" / "MANIFEST.md").read_text() == gen.markdown(entries), (
        "results/MANIFEST.md is stale: run python -m maintainers manifest --write"
    )
    page = gen.SIZE_PAGE.read_text()  # docs/runs.md's count of what results/ commits (it read 95 sets at 137)
    block = page.split(gen.SIZE_BEGIN, 1)[1].split(gen.SIZE_END, 1)[0].strip()
    assert block == gen.size_text(entries), "docs/runs.md's count is stale: run python -m maintainers manifest --write"
    sets = {e["set"]: e for e in entries}
    for post in ("pendulum", "cartpole", "mountaincar"):
        assert f"{post}/faithful" in sets and f"checks/{post}/baseline" in sets
    # post 001's batched-against-solo set: seeds 0-29 in three batches of 10, made by two commands
    assert sets["mountaincar/seed-batch/batch10"]["batches"] == [list(range(a, a + 10)) for a in (0, 10, 20)]
    # post 003's compiled seeds 0-99 are the engine comparison's, the check baseline's (compiled since
    # issue 34) and, seeds 0-29, the ablations' base: counted once
    assert sets["engines/cartpole/compiled"]["copies"] == {
        "cartpole/ablations-compiled/base": list(range(30)),
        "checks/cartpole/baseline": list(range(30, 100)),
    }
    # the faithful post-001 set is the check baseline's 30 solo runs again, counted once
    assert sets["mountaincar/faithful"]["copies"] == {"checks/mountaincar/baseline": list(range(30))}
    assert gen.cost(sets["mountaincar/faithful"]) == 0 and not sets["checks/mountaincar/baseline"]["copies"]


def test_a_seed_is_a_copy_only_where_its_config_its_batch_and_every_episode_are_the_same(tmp_path, monkeypatch):
    """The manifest reads a seed's episodes only where an earlier seed shares its config and batch
    (``run_head``); one changed value in one episode makes it a run of its own."""
    gen = load_generator("manifest")
    first = RunSet(ROOT / "results" / "checks" / "mountaincar" / "baseline").runs()[:2]
    for name in ("same", "changed"):
        for run in first:
            run.extract(tmp_path / name / f"seed_{run.seed}")
    csv = tmp_path / "changed" / "seed_1" / "episodes.csv"
    header, *rows, last = csv.read_text().splitlines()
    fields = last.split(",")
    score = header.split(",").index("score")
    fields[score] = repr(float(fields[score]) + 1.0)
    csv.write_text("\n".join([header, *rows, ",".join(fields)]) + "\n")
    sets = {"a/first": first, **{f"{k}/{n}": RunSet(tmp_path / n).runs() for k, n in (("b", "same"), ("c", "changed"))}}
    monkeypatch.setattr(gen, "find_sets", lambda results: sets)
    copies = {e["set"]: e["copies"] for e in gen._read_manifest(tmp_path)}
    assert copies == {"a/first": {}, "b/same": {"a/first": [0, 1]}, "c/changed": {"a/first": [0]}}


def test_a_seeds_batch_comes_from_its_summary_or_else_its_command():
    gen = load_generator("manifest")
    recorded = {"seed": 3, "experiment": "pendulum", "provenance": {"seed_batch": [2, 3]}, "command": ""}
    assert gen.batch_of(recorded) == [2, 3]
    command = "keras-rl reproduce pendulum --seeds 0-9 --seed-batch 4 --workers 2"
    assert gen.batch_of({"seed": 5, "experiment": "pendulum", "command": command}) == [4, 5, 6, 7]
    assert gen.batch_of({"seed": 9, "experiment": "pendulum", "command": command}) == [8, 9]
    tutorial = {"seed": 5, "experiment": "cartpole", "framework": "torch", "command": command}
    assert gen.batch_of(tutorial) == [5]  # the tutorial's own code never batches
    assert gen.batch_of({"seed": 5, "experiment": "pendulum", "command": "keras-rl reproduce pendulum"}) == [5]


def test_no_picture_is_committed_inside_a_seed_folder():
    """Per-seed curve.png files were 146 MB of results/ that `keras-rl aggregate` redraws from
    episodes.csv: results/ commits the aggregate figures only (.gitignore keeps the rest out)."""
    tracked = subprocess.run(
        ["git", "ls-files", "results"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.splitlines()
    if not tracked:
        pytest.skip("not a git checkout")
    pictures = [p for p in tracked if re.search(r"/seed_\d+/", p) and p.lower().endswith((".png", ".gif", ".jpg"))]
    assert pictures == [], pictures[:5]


def test_the_forest_plot_and_its_tables_match_the_committed_runs():
    """Issue 35, item 4: every verdict drawn. The plotted numbers (``results/forest.json``) and
    both pages' blocks regenerate from the committed runs and compare results."""
    gen = load_generator("forest")
    rows = gen.rows()
    committed = json.loads((ROOT / "results" / "forest.json").read_text())
    assert committed == {"command": gen.COMMAND, "rows": rows}, (
        "results/forest.json is stale: python -m maintainers tables forest --write"
    )
    # the compiled engine's certification, read by the package, is generated from these rows
    from keras_rl.train.compiled_scope import CERTIFIED

    assert json.loads(gen.CERTIFIED.read_text()) == gen.certified(rows), (
        "keras_rl/train/certified.json is stale: python -m maintainers tables forest --write"
    )
    assert set(CERTIFIED) == {("pendulum", "keras"), ("cartpole", "keras"), ("mountaincar", "keras")}
    figure = (ROOT / "results" / "forest.png").read_bytes()
    assert figure == (ROOT / "docs" / "forest.png").read_bytes()  # the docs site's copy
    text = gen.table(rows)
    assert block((ROOT / "results" / "README.md").read_text(), gen.BEGIN, gen.END) == text
    assert block((ROOT / "docs" / "findings.md").read_text(), gen.BEGIN, gen.END) == text
    groups = {r["group"] for r in rows}
    assert {"Keras vs PyTorch", "Keras vs PyTorch, matched init", "compiled engine vs Gymnasium loop"} <= groups
    assert any(g.startswith("seed-batched") for g in groups) and any("ablation" in g for g in groups)
    for r in rows:
        if not r["pending"]:
            for key in ("success", "speed"):
                v = r[key]
                assert v["reading"] in ("equivalent within the margin", "different", "inconclusive")
                if v["estimate"] is not None:
                    assert v["low"] <= v["estimate"] <= v["high"]


def test_a_planned_reading_reads_its_seeds_only_and_waits_for_all_of_them(tmp_path, monkeypatch):
    """A comparison planned at N seeds (``first_seeds_only``: the tutorial fix's first and second
    looks) reads seeds 0 to N - 1 of both arms, whatever else they hold, and is pending until
    both hold every one of them: no reading of a part-landed arm."""
    from keras_rl.runs.run_set import RunSet

    gen = load_generator("forest")
    sources = {"a": ROOT / "results" / "cartpole" / "faithful-torch", "b": ROOT / "results" / "cartpole" / "faithful"}

    def put(name: str, seeds: range, under: str | None = None) -> None:
        for s in seeds:
            RunSet.seed_at(sources[name] / f"seed_{s}").extract(tmp_path / (under or name) / f"seed_{s}")

    put("a", range(0, 14))
    put("b", range(0, 8))
    monkeypatch.setattr(gen, "RESULTS", tmp_path)
    planned = gen.Comparison("g", "planned at 10", "a", "b", seeds_before_reading=10, first_seeds_only=True)
    early = gen.row(planned)
    assert early["pending"] and early["seeds"] == 8
    put("b", range(8, 12))  # now both hold 0-9, and more
    read = gen.row(planned)
    assert not read["pending"] and read["seeds"] == 10
    put("a", range(0, 10), under="a10")
    put("b", range(0, 10), under="b10")
    exactly = gen.row(gen.Comparison("g", "planned at 10", "a10", "b10", seeds_before_reading=10))
    assert {k: read[k] for k in ("success", "speed")} == {k: exactly[k] for k in ("success", "speed")}
    unplanned = gen.row(gen.Comparison("g", "planned at 10", "a", "b", seeds_before_reading=10))
    assert unplanned["seeds"] == 12  # without the plan, every seed both hold


def test_the_manifest_splits_the_regeneration_cost_by_how_the_runs_ran():
    gen = load_generator("manifest")

    def entry(framework, command, minutes, seeds=2, copies=None):
        return {
            "framework": framework,
            "engine": "compiled" if "--engine compiled" in command else "gymnasium",
            "commands": [command],
            "process_minutes": minutes,
            "seeds": list(range(seeds)),
            "copies": copies or {},
        }

    entries = [
        entry("torch", "keras-rl reproduce cartpole --framework torch", 60.0),
        entry("keras", "keras-rl reproduce cartpole --engine compiled --seeds 0-1", 30.0),
        # made by --engine auto: its command names no engine, its summaries record the compiled one
        {**entry("keras", "keras-rl reproduce cartpole --seeds 2-3", 12.0), "engine": "compiled"},
        entry("keras", "keras-rl reproduce cartpole --seeds 0-1", 90.0, copies={"other": [0]}),  # half counted
    ]
    assert gen.by_kind(entries) == {
        "PyTorch": 60.0,
        "Keras on the Gymnasium loop": 45.0,
        "Keras on the compiled engine": 42.0,
    }
    entries = [e for e in entries if e["commands"] != ["keras-rl reproduce cartpole --seeds 2-3"]]
    # 135 process-minutes counted once; on 2 cores 67.5 minutes, but never less than the longest job
    for e, longest in zip(entries, (30.0, 10.0, 45.0)):
        e["longest_job_minutes"] = longest
    line = gen.regeneration_line(entries)
    assert "costs 2.2 process-hours; in wall time at least: 2 cores 1.1 h; 16 cores 0.8 h;" in line
    assert "256 cores 0.8 h (the longest single job, 45 minutes, bounds it from below)" in line


def test_the_forest_marks_cut_intervals_and_says_no_estimate_under_one_heading_per_group(monkeypatch, tmp_path):
    """Issue 54 item 22: intervals past the axis ran off unmarked, rows without an estimate were
    blank, and no heading said which arm was first."""
    from keras_rl.report import plots

    gen = load_generator("forest")
    figures = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path: figures.append(fig))

    def reading(estimate, low, high, margin):
        return {"estimate": estimate, "low": low, "high": high, "margin": margin, "reading": "inconclusive"}

    wide = {
        "group": "Keras vs PyTorch",
        "label": "wide",
        "seeds": 30,
        "pending": False,
        "success": reading(0.0, -1.4, 0.2, [-0.15, 0.15]),
        "speed": reading(1.2, 0.8, 3.5, [0.9, 1.1]),
    }
    empty = {**wide, "label": "none", "speed": reading(None, None, None, [0.9, 1.1])}
    gen.draw([wide, empty], tmp_path / "f.png")
    success, speed = figures[0].axes
    markers = lambda ax: [(line.get_marker(), tuple(line.get_xdata())) for line in ax.get_lines()]  # noqa: E731
    assert ("<", (-1.0,)) in markers(success) and (">", gen.RATIO_AXIS[1:]) in markers(speed)
    assert [t.get_text() for t in speed.texts] == ["no estimate"]
    labels = [t.get_text() for t in success.get_yticklabels()]
    assert labels[0] == "Keras vs PyTorch: first = Keras, second = PyTorch" and len(labels) == 3


def test_the_forest_groups_its_rows_under_headings_that_say_which_arm_is_first():
    gen = load_generator("forest")
    assert gen._heading("Keras vs PyTorch") == "Keras vs PyTorch: first = Keras, second = PyTorch"
    assert gen._heading("Keras vs PyTorch, matched init") == (
        "Keras vs PyTorch (matched init): first = Keras, second = PyTorch"
    )
    assert gen._heading("seed-batched vs solo") == "seed-batched vs solo: first = seed-batched, second = solo"


def test_the_check_example_figure_is_what_its_command_draws(tmp_path):
    """Issue 54 item 4: docs/check-example.png (the sensitive tier's check.png from committed runs)
    is the bytes its command draws now, so the picture the docs show is the check's own."""
    gen = load_generator("check_figure")
    verdict = gen.draw(tmp_path / "check.png")
    assert verdict.startswith("consistent") and "80 fresh seeds against 200" in verdict
    assert (tmp_path / "check.png").read_bytes() == gen.FIGURE.read_bytes(), f"stale: {gen.COMMAND}"


def test_a_deviation_that_counts_code_versions_names_every_commit_its_arm_recorded():
    """†4 named two code versions of the vectorised arm; its seeds recorded three commits (issue 72 item 13)."""
    from maintainers.plans import DEVIATIONS

    words = {2: "two", 3: "three", 4: "four"}
    arm = RunSet(ROOT / "results" / "cartpole" / "vectorised-torch" / "seeds-0-199")
    commits = {r.summary_record()["provenance"]["commit"][:8] for r in arm.runs()}
    (deviation,) = [d for d in DEVIATIONS if d.plan == "results/cartpole/vectorised-torch/plan.md"]
    assert f"holds {words[len(commits)]} code versions" in deviation.text
    assert all(c in deviation.text for c in commits), (sorted(commits), deviation.text)
