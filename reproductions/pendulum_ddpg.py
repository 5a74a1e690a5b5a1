"""Post 000: DDPG on Pendulum-v1 (g=10), reproduced faithfully or fixed.

Same as ``keras-rl reproduce pendulum ...``:

    python reproductions/pendulum_ddpg.py --variant faithful --seeds 0-9 --workers 2
    python reproductions/pendulum_ddpg.py --variant fixed --seeds 13

Options: --variant faithful|fixed, --seeds LIST|RANGE, --episodes N (the post's 1000 by
default), --out DIR, --workers K, --set FIELD=VALUE. Exit code 0 only when the success
criterion (EMA > -300 within the budget) holds for the seeds (see --min-success-rate).
The quirk switches behind the variants are documented in reproductions/FIDELITY.md.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from keras_rl.cli import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main(["reproduce", "pendulum", *sys.argv[1:]]))
