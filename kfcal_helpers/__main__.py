"""``python -m kfcal_helpers``: the signal handlers, streams and matplotlib's directory are set up
first (:func:`kfcal_helpers.process.prepare`), before the command line's imports."""

import sys

from .process import prepare

prepare()

from .cli import main  # noqa: E402 - after the handlers, on purpose

sys.exit(main())
