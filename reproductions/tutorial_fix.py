"""The tutorial's community fix against the tutorial as published (post 003, issue 35 item 3;
planned in ``results/cartpole/tutorial-fix/plan.md`` before its runs).

    python reproductions/tutorial_fix.py results/engines/cartpole/compiled \
        results/cartpole/tutorial-fix/issue-3080 --labels published,issue-3080 \
        --write results/cartpole/tutorial-fix/report.md

Two arms of run folders (``seed_<n>/`` each), the same budget (600 episodes, no early stop).
The readings, each with its seeds and interval:

- success within the budget (each arm's rate with its 90% Wilson interval; the difference with
  the pre-registered TOST reading, ``keras_rl/report/equivalence.py``);
- episodes until the 100-episode mean first reaches 475, a seed that never does counting as
  budget + 1 (median ratio, TOST reading);
- what a reader of the tutorial on a CPU gets: its 50 episodes (``tutorial_num_episodes``),
  read from the first 50 rows of each run: per seed the mean duration of episodes 1-50 and the
  longest episode, as the median and quartiles over the seeds.

A seed counts only when it has finished (``summary.json`` status ``completed``, or stopped by a
non-finite loss: ``runs.reuse.OUTCOMES``); the report names how many each arm holds.

An arm may be several folders, comma-joined, where it grew in steps (the published PyTorch arm is
``results/cartpole/faithful-torch`` for seeds 0-29 and ``faithful-torch-seeds-30-199`` after): a
seed held twice is read from the first folder listed, and both must agree on its outcome
(``maintainers.certified.arm_where``, the arms of the Keras-against-PyTorch comparisons).
``--seeds`` reads both arms on those seeds only, and each arm must hold every one of them
finished; without it, an arm is every finished seed its folders hold. ``--first-look`` names the
seeds a planned earlier reading used (plan.md's addenda: a comparison read once at 30 seeds and
again at 100): the report then gives that reading too, from the same folders.

    python reproductions/tutorial_fix.py \
        results/cartpole/faithful-torch,results/cartpole/faithful-torch-seeds-30-199 \
        results/cartpole/tutorial-fix/pr-3384-torch --labels published,pr-3384 --seeds 0-99 \
        --first-look 0-29 --write results/cartpole/tutorial-fix/report-pr-3384-torch-100.md
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import NoReturn

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout's maintainers/

import numpy as np

from keras_rl.atomic import atomic_write_text
from keras_rl.commands.common import parse_seeds
from keras_rl.errors import ConfigError, RunFolderError
from keras_rl.posts.cartpole import tutorial_num_episodes
from keras_rl.report.equivalence import Arm, median_ratio_equivalence, success_rate_equivalence
from keras_rl.report.stats import wilson_interval
from keras_rl.runs.run_set import RunSet
from maintainers import plans
from maintainers.certified import arm_where
from maintainers.markdown import seed_span

CPU_EPISODES = tutorial_num_episodes(cuda_available=False)


def fail(message: str) -> NoReturn:
    """Bad input: say what, exit 2 (nothing is written)."""
    print(f"error: {message}", file=sys.stderr)
    raise SystemExit(2)


def arm(folders: list[Path], seeds: list[int] | None = None) -> dict:
    """One arm's finished seeds (only ``seeds``, each of which it must hold, when given):
    successes, episodes to threshold, and the first 50 episodes."""
    name = " + ".join(str(f) for f in folders)
    try:
        held = arm_where(tuple(str(f) for f in folders), Path("."))
    except RunFolderError as e:
        fail(str(e))
    if seeds is not None:
        missing = [x for x in seeds if x not in held]
        if missing:
            asked = f"the {len(seeds)} asked for ({seed_span(seeds)})"
            fail(f"{name} lacks finished seed(s) {seed_span(missing)} of {asked}")
        held = {x: held[x] for x in seeds}
    if not held:
        fail(f"{name} holds no finished seed")
    finished = [s for _, s in held.values()]
    budgets = {s["budget_episodes"] for s in finished}
    if len(budgets) != 1:
        fail(f"{name}'s seeds ran different budgets ({sorted(budgets)})")
    first = []
    for seed in sorted(held):
        folder, _ = held[seed]
        steps = [int(r["steps"]) for r in RunSet.seed_at(Path(folder) / f"seed_{seed}").rows()[:CPU_EPISODES]]
        first.append((float(np.mean(steps)), max(steps)))
    seeds = Arm.of(finished)
    return {
        "folder": name,
        "seeds": sorted(held),
        "n": len(finished),
        "successes": seeds.successes,
        "episodes": seeds.episodes(),
        "budget": budgets.pop(),
        "cpu_mean": np.array([m for m, _ in first]),
        "cpu_longest": np.array([x for _, x in first]),
    }


def quartiles(x: np.ndarray) -> str:
    q1, med, q3 = np.percentile(x, [25, 50, 75])
    return f"{med:.1f} ({q1:.1f}-{q3:.1f})"


def seed_text(seeds: list[int]) -> str:
    return f"{seeds[0]}-{seeds[-1]}" if seeds == list(range(seeds[0], seeds[-1] + 1)) else f"{len(seeds)} seeds"


def readings(a: dict, b: dict) -> list[str]:
    """The fix's arm ``b`` minus the published ``a``: the two pre-registered readings' sentences."""
    if a["budget"] != b["budget"]:
        fail(f"the arms ran different budgets ({a['budget']} and {b['budget']} episodes)")
    success = success_rate_equivalence(b["successes"], b["n"], a["successes"], a["n"])
    speed = median_ratio_equivalence(b["episodes"], a["episodes"], a["budget"])
    return [success.sentence(), speed.sentence()]


def report(a: dict, b: dict, labels: tuple[str, str], command: str, first_look: tuple[dict, dict] | None = None) -> str:
    said = readings(a, b)
    budget = a["budget"]
    lines = [
        f"# {labels[1]} against {labels[0]}: post 003 (CartPole-v1 DQN)",
        "",
        f"Generated by `{command}`; planned in `plan.md` beside this file before the runs.",
        "",
        f"| arm | folder | seeds | success within {budget} episodes (90% Wilson) | median episode to 475 "
        f"(never: {budget + 1}) | a CPU reader's {CPU_EPISODES} episodes: mean duration, median (IQR) "
        "| longest episode in them, median (IQR) |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, x in zip(labels, (a, b)):
        low, high = wilson_interval(x["successes"], x["n"], confidence=0.90)
        episodes = np.median([budget + 1 if v is None else v for v in x["episodes"]])
        lines.append(
            f"| {label} | `{x['folder']}` | {seed_text(x['seeds'])} ({x['n']}) | {x['successes']}/{x['n']} "
            f"({low:.2f}-{high:.2f}) | {episodes:g} | {quartiles(x['cpu_mean'])} | {quartiles(x['cpu_longest'])} |"
        )
    lines += [
        "",
        f"{labels[1]} minus {labels[0]}, judged on the margins set before the runs (2026-11-23):",
        "",
        *(f"- {x}" for x in said),
        "",
    ]
    if first_look is not None:
        earlier = seed_text(first_look[0]["seeds"])
        lines += [
            f"This is a second look, planned in `plan.md` before its runs. The first reading, on seeds {earlier} "
            "of the same arms, stays as it was:",
            "",
            *(f"- {x}" for x in readings(*first_look)),
            "",
        ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("published", help="the tutorial as published (the reference arm): folder[,folder...]")
    parser.add_argument("fix", help="the fix's arm: folder[,folder...]")
    parser.add_argument("--labels", default="published,fix", help="the two arms' names, comma-separated")
    parser.add_argument("--seeds", default=None, help="read both arms on these seeds only (each must hold them all)")
    parser.add_argument("--first-look", default=None, help="also give the planned earlier reading on these seeds")
    parser.add_argument("--write", type=Path, default=None, help="write the report here (else print it)")
    args = parser.parse_args(argv)
    labels = tuple(args.labels.split(","))
    if len(labels) != 2 or not all(labels):
        parser.error("--labels takes two names, comma-separated")
    arms = []
    for text in (args.published, args.fix):
        folders = [Path(x) for x in text.split(",")]
        for folder in folders:
            if not folder.is_dir():
                parser.error(f"{folder} is not a folder of run folders")
        arms.append(folders)
    seeds, first_seeds = (None if x is None else seeds_of(parser, x) for x in (args.seeds, args.first_look))
    if first_seeds is not None and seeds is not None and not set(first_seeds) < set(seeds):
        parser.error(f"--first-look {args.first_look} is not a smaller part of --seeds {args.seeds}")
    command = (
        f"python reproductions/tutorial_fix.py {args.published} {args.fix} --labels {args.labels}"
        + (f" --seeds {args.seeds}" if args.seeds else "")
        + (f" --first-look {args.first_look}" if args.first_look else "")
        + (f" --write {args.write}" if args.write else "")
    )
    first_look = None if first_seeds is None else (arm(arms[0], first_seeds), arm(arms[1], first_seeds))
    text = report(arm(arms[0], seeds), arm(arms[1], seeds), (labels[0], labels[1]), command, first_look)
    text = plans.disclosed(text, plans.report_path(args.write))  # a deviation of a plan it touches
    if args.write:
        atomic_write_text(args.write, text)
        print(f"wrote {args.write}")
    else:
        print(text)


def seeds_of(parser: argparse.ArgumentParser, text: str) -> list[int]:
    try:
        return parse_seeds(text)
    except ConfigError as e:
        parser.error(str(e))


if __name__ == "__main__":
    main()
