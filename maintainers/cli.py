"""The maintainers' commands: what regenerates the checkout's committed figures, run from a
checkout as ``python -m maintainers ...`` (this folder is not part of the installed package).

- ``python -m maintainers calibrate rules|family|held-out|designs|sensitive|real|twins|torch|bisect-levels``:
  the check's calibration (``maintainers/calibrate/``), whose JSON ships as package data;
- ``python -m maintainers tables findings|ablations|compat|forest|check-figure|prose|runs``: the generated Markdown
  (``maintainers/tables/``), each spliced between its markers (``maintainers/markdown.py``);
- ``python -m maintainers manifest``: ``results/MANIFEST``, and ``--regenerate`` to rerun sets and compare;
- ``python -m maintainers audit``: rerun K drawn seeds of every set and compare (``results/AUDIT.md``);
- ``python -m maintainers sigterm-stress``: SIGTERM each engine at random times, resume, count aborts;
- ``python -m maintainers replay-references``: the replay tests' references for a host of another
  instruction set or vendor, made natively there or under an emulated CPU, and checked
  (``tests/replay_references/``).

Each reads the checkout's ``results/`` (``maintainers/checkout.py``). The arguments are declared
here and each module's ``run(args)`` is imported only when its command runs.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from pathlib import Path

from keras_rl.commands.flags import shared_flags
from maintainers.checkout import results_dir


def _what(inner, name: str, module: str, help: str, *flags: str) -> argparse.ArgumentParser:
    # argparse formats a help string with %: a bare "90%" in it would be read as a format
    p = inner.add_parser(name, help=help.replace("%", "%%"), description=help, parents=[shared_flags(name, *flags)])
    p.set_defaults(module=module)
    return p


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m maintainers", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_parser(parser.add_subparsers(dest="command", required=True))
    return parser


def add_parser(sub) -> None:
    """``calibrate``, ``tables`` and ``manifest``."""
    group = sub.add_parser("calibrate", help="measure the check's error rates and designs (maintainers/calibrate/)")
    inner = group.add_subparsers(dest="what", required=True, metavar="WHAT", help="what to measure")
    p = _what(
        inner,
        "rules",
        "maintainers.calibrate.rules",
        "each candidate rule's false-alarm rate and power on the committed baseline and mutant runs, "
        "and the rule the pre-registered criterion picks (keras_rl/check/calibration.json, "
        "results/checks/calibration.md)",
        "--write",
    )
    p.add_argument("experiments", nargs="*", help="posts to recalibrate (none: rerender calibration.md)")
    p.add_argument("--make", action="store_true", help="run the missing baseline and mutant sets first")
    p = _what(
        inner,
        "family",
        "maintainers.calibrate.family",
        "the three-post command's family-wise false-alarm rate, and its spread over simulated baselines "
        "(results/checks/family.json, calibration.md's block)",
        "--write",
    )
    p = _what(
        inner,
        "held-out",
        "maintainers.calibrate.held_out",
        "the chosen rules' power against the held-out mutants (results/checks/held_out.json)",
        "--write",
    )
    p.add_argument("--missing", action="store_true", help="print the commands for the missing held-out runs")
    p = _what(
        inner,
        "designs",
        "maintainers.calibrate.designs",
        "the sequential check's designs: looks, bounds, error rates and expected seeds "
        "(keras_rl/check/sequential.json, results/checks/sequential.md)",
        "--write",
    )
    p = _what(
        inner,
        "sensitive",
        "maintainers.calibrate.sensitive",
        "the sensitive tier's false alarms, power against a 10% move and against the held-out mutants, "
        "and post 001's statistic (keras_rl/check/sensitive.json, calibration.md's block)",
        "--write",
    )
    p = _what(
        inner,
        "torch",
        "maintainers.calibrate.torch",
        "check --framework torch: its rules' false alarms on real arithmetic changes and power against real changes "
        "of the algorithm, from committed runs (keras_rl/check/torch.json, calibration.md's block)",
        "--write",
    )
    p = _what(
        inner,
        "twins",
        "maintainers.calibrate.twins",
        "the twin check: post 000's n chosen on the tuning mutants, false alarms on real arithmetic changes and "
        "power against held-out mutants on twin seeds (keras_rl/check/twins.json, calibration.md's block)",
        "--write",
    )
    p = _what(
        inner,
        "real",
        "maintainers.calibrate.real",
        "the sensitive tier on real runs no baseline holds: false alarms and power over disjoint real checks, "
        "and post 000's fresh-seed count re-derived on held-back seeds (results/checks/real_checks.json, "
        "calibration.md's block)",
        "--write",
    )
    p = _what(
        inner,
        "bisect-levels",
        "maintainers.calibrate.bisect_levels",
        "the bisect's per-step levels against simulated unchanged checks (results/checks/bisect_levels.md)",
        "--write",
    )
    p.add_argument("--draws", type=int, default=None, help="unchanged checks per post (default 50,000)")

    group = sub.add_parser("tables", help="regenerate the committed Markdown tables from the committed runs")
    inner = group.add_subparsers(dest="what", required=True, metavar="WHAT", help="which tables")
    p = _what(
        inner,
        "findings",
        "maintainers.tables.findings",
        "the findings tables of results/README.md and the README's short table",
        "--write",
        "--changes",
    )
    p = _what(
        inner,
        "ablations",
        "maintainers.tables.ablations",
        "FIDELITY.md's measured-effect tables, one per post, and post 001's readings",
        "--write",
        "--changes",
    )
    p.add_argument("experiments", nargs="*", default=None, help="default: all three posts")
    p = _what(
        inner,
        "compat",
        "maintainers.tables.compat",
        "the version matrix's tables (results/compat/README.md, the README's short table) from the cell folders",
        "--write",
    )
    _what(
        inner,
        "forest",
        "maintainers.tables.forest",
        "every two-arm comparison's estimate, 90% interval, margin and reading, drawn (results/forest.png) "
        "and tabled (results/README.md, docs/findings.md)",
        "--write",
    )
    _what(
        inner,
        "check-figure",
        "maintainers.tables.check_figure",
        "what check.png shows at the sensitive tier: post 000's baseline against 80 real unchanged seeds "
        "(docs/check-example.png)",
        "--write",
    )
    _what(
        inner,
        "prose",
        "maintainers.prose",
        "every number the docs' prose takes from the data, written between its markers (without --write: "
        "what is stale, exit 1)",
        "--write",
    )
    p = _what(
        inner,
        "runs",
        "maintainers.tables.runs",
        "run-set folders tabulated against the first: the ledger's measured-effect column",
    )
    p.add_argument("folders", nargs="+", type=Path, help="run-set folders of seed_<n>/; the first is the baseline")

    p = sub.add_parser(
        "manifest",
        help="results/MANIFEST: every committed run set with its command; --regenerate reruns sets and compares",
        parents=[shared_flags("manifest", "--out", "--workers", "--write", "--address")],
    )
    p.set_defaults(module="maintainers.manifest")
    p.add_argument(
        "--regenerate",
        nargs="+",
        metavar="SET",
        help="rerun the sets matching these patterns (fnmatch) into --out and compare them with the committed ones",
    )

    p = sub.add_parser(
        "audit",
        help="rerun K randomly drawn seeds of every committed set and compare them with the committed episodes",
        parents=[shared_flags("audit", "--out", "--workers", "--write", "--address")],
    )
    p.set_defaults(module="maintainers.audit")
    p.add_argument("--per-set", type=int, default=1, metavar="K", help="seeds (batches) drawn from each set")
    p.add_argument("--draw-seed", type=int, default=52, help="the random seed that draws them (default 52)")
    p.add_argument("--sets", nargs="+", metavar="SET", help="only the sets matching these patterns (fnmatch)")
    p.add_argument(
        "--again",
        action="store_true",
        help="with --write: rerun every set, not only those the committed report lacks",
    )

    p = sub.add_parser(
        "sigterm-stress",
        help="SIGTERM each engine's short seed at random times, resume it, and count aborts (results/reliability)",
        parents=[shared_flags("sigterm-stress", "--out", "--write")],
    )
    p.set_defaults(module="maintainers.sigterm_stress")
    p.add_argument("--stops", type=int, default=100, help="SIGTERMs per engine (default 100)")
    p.add_argument(
        "--engines",
        nargs="+",
        default=["compiled", "gymnasium", "vectorised"],
        help="the engines to stop (default: compiled gymnasium vectorised)",
    )

    p = sub.add_parser(
        "replay-references",
        help="make the replay tests' references for another host (natively, or under an emulated CPU), or check them",
        parents=[shared_flags("replay-references", "--episodes", "--write")],
    )
    p.set_defaults(module="maintainers.replay_references")
    p.add_argument(
        "action",
        choices=("check", "make", "probe"),
        help="check: rerun the real host's references; make: the missing; probe: a case native and emulated",
    )
    p.add_argument(
        "--emulate",
        metavar="CPU",
        help="the CPU model qemu-x86_64 -cpu gives (EPYC-Rome); make without it: a set for this host, made here",
    )
    p.add_argument(
        "--reference-set",
        default="avx2",
        help="the reference set under tests/replay_references (default avx2; portable-torch: made under "
        "KERAS_RL_PORTABLE_TORCH=1, natively, for every host)",
    )
    p.add_argument(
        "--trace",
        action="store_true",
        help="check, probe: count the approximate instructions (rcp, rsqrt, x87 transcendentals) each rerun executes "
        "under the emulator, which QEMU computes exactly and silicon does not",
    )
    p.add_argument("--cases", nargs="+", metavar="ID", help="only these cases (default: every case)")
    p.add_argument("--env", nargs="+", action="extend", metavar="KEY=VALUE", help="probe: set on both runs")
    p.add_argument(
        "--native-env", nargs="+", action="extend", metavar="KEY=VALUE", help="probe: set on the native run only"
    )


def run(args: argparse.Namespace) -> int:
    results_dir()  # exit 2 outside a checkout, before anything is read
    return int(importlib.import_module(args.module).run(args))


def main(argv: Sequence[str] | None = None) -> int:
    """Parse, run, and turn the package's errors into exit codes as ``keras-rl`` does."""
    from keras_rl.cli import EXIT_CRITERION, EXIT_USAGE
    from keras_rl.commands.flags import resolve_defaults
    from keras_rl.errors import KerasRLError

    args = resolve_defaults(build_parser().parse_args(argv))
    try:
        return run(args)
    except KerasRLError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_CRITERION
