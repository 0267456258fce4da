"""``python -m kapsel`` is the ``kapsel-py`` command."""
import sys

from .cli import main

sys.exit(main())
