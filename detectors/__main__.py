"""``python -m detectors fetch [NAME]`` / ``python -m detectors detect IMAGE...``."""

import sys

from detectors.cli import main

if __name__ == "__main__":
    sys.exit(main())
