"""`python -m sweep` (with tools/ on PYTHONPATH): what `hbench sweep` runs."""
import sys

from sweep.cli import main

if __name__ == "__main__":
    sys.exit(main())
