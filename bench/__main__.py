"""``python -m bench``: the benchmark's command line (see :mod:`bench.cli`)."""

import sys

from bench.cli import main

sys.exit(main(command="python -m bench", prog="python -m bench"))
