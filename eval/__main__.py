"""`python -m eval COMMAND`: the same as `mobman-eval COMMAND` (run, sweep, bench, paper, speed, picture, readme)."""

import sys

from eval.cli import main

sys.exit(main())
