"""`python -m eval run|paper|speed` (same as `mobman-eval`)."""

import sys

from eval.cli import main

sys.exit(main())
