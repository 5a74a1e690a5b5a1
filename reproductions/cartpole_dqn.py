"""Post 003: the PyTorch DQN tutorial on CartPole-v1, in Keras or as the tutorial's own code.

Same as ``keras-rl reproduce cartpole ...``:

    python reproductions/cartpole_dqn.py --seeds 21
    python reproductions/cartpole_dqn.py --framework torch --seeds 0-9 --workers 2

Success: the 100-episode mean duration reaches 475 within 600 episodes. The torch side
needs the extra: pip install -e '.[torch]' (torch==2.13.0). See reproductions/FIDELITY.md.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from keras_rl.cli import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main(["reproduce", "cartpole", *sys.argv[1:]]))
