import sys

from maintainers.cli import main

sys.exit(main())
