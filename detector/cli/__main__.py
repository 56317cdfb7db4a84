"""``python -m detector.cli``: the ``poles`` command without its entry point."""
import sys

from detector.cli import main

sys.exit(main())
