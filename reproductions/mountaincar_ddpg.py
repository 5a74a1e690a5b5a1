"""Post 001: DDPG on MountainCarContinuous-v0, translated from Keras 2 / TF1 graph code.

Same as ``keras-rl reproduce mountaincar ...``:

    python reproductions/mountaincar_ddpg.py --seeds 31                        # faithful, literal gradient
    python reproductions/mountaincar_ddpg.py --variant faithful-intended --seeds 0-9 --workers 2
    python reproductions/mountaincar_ddpg.py --variant fixed --seeds 31   # then: keras-rl evaluate ... --episodes 100

See reproductions/FIDELITY.md (P001-*) for every switch and how the Keras 2 semantics were settled.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from keras_rl.cli import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main(["reproduce", "mountaincar", *sys.argv[1:]]))
