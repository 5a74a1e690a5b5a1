"""``keras-rl``: reproduce a post over seeds, compare frameworks, or evaluate a saved run.

keras-rl reproduce pendulum --variant faithful --seeds 0-9 --workers 2 --out runs/pendulum
keras-rl compare pendulum --seeds 0-9 --workers 2 --runs runs --out runs/compare
keras-rl sweep pendulum --grid tau=0.001,0.005 --seeds 0-3 --workers 2 --out runs/s
keras-rl evaluate runs/pendulum/seed_0 --episodes 5 --gif pendulum.gif
keras-rl aggregate results/pendulum/faithful
keras-rl pack runs/pendulum/faithful       # a finished set's seed folders into one runs.parquet
keras-rl check pendulum cartpole mountaincar --tier smoke
keras-rl list
(the maintainers' tools, from a checkout: python -m maintainers calibrate|tables|manifest)
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from keras_rl import __version__
from keras_rl.commands import aggregate, bisect, check, compare, evaluate, pack, reproduce, sweep
from keras_rl.commands.check import check_results
from keras_rl.commands.common import EXIT_CRITERION, EXIT_NO_VERDICT, EXIT_OK, EXIT_USAGE, MAX_SEEDS, parse_seeds
from keras_rl.commands.compare import compare_result
from keras_rl.commands.flags import resolve_defaults
from keras_rl.errors import KerasRLError, as_flags

__all__ = [
    "COMMANDS",
    "EXIT_CRITERION",
    "EXIT_NO_VERDICT",
    "EXIT_OK",
    "EXIT_USAGE",
    "MAX_SEEDS",
    "build_parser",
    "check_results",
    "compare_result",
    "main",
    "parse_args",
    "parse_seeds",
]

COMMANDS = {
    "bisect": bisect.bisect,
    "check": check.check,
    "reproduce": reproduce.reproduce,
    "evaluate": evaluate.evaluate,
    "compare": compare.compare,
    "sweep": sweep.sweep,
    "aggregate": aggregate.aggregate,
    "pack": pack.pack,
    "list": aggregate.list_experiments,
}
"""Each command's function; its arguments come from its module's ``add_parser``."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="keras-rl", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--version", action="version", version=f"keras-rl {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for module in (reproduce, evaluate, compare, sweep, aggregate, pack, check, bisect):
        module.add_parser(sub)
    aggregate.add_list_parser(sub)
    return parser


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The command line parsed, each shared flag left at None set to its command's default."""
    return resolve_defaults(build_parser().parse_args(argv))


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        with as_flags():  # the library's messages name flags, not parameters
            return COMMANDS[args.command](args)
    except KerasRLError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:  # a full disk or a vanished folder mid-run: say so, no traceback
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_CRITERION


if __name__ == "__main__":
    sys.exit(main())
