"""``python bench/run.py``: the benchmark's command line (see :mod:`bench.cli`)."""

import sys
from pathlib import Path

if __name__ == "__main__":
    # As a file, this folder heads sys.path; the repo root (home of the package) takes its place.
    sys.path[0] = str(Path(__file__).resolve().parents[1])
    from bench.cli import main

    sys.exit(main())
