import sys

from keras_rl.cli import main

sys.exit(main())
