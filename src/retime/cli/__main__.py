"""``python -m retime.cli``: the same as the ``retime`` program."""
import sys

from .main import main

sys.exit(main())
