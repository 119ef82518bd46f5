"""Progress bars for long Monte Carlo loops, quiet under tests and CI.

A bar is shown only when the environment variables ``CI`` and ``KFCAL_QUIET``
are both unset (the test suite sets ``KFCAL_QUIET=1`` in its ``conftest.py``,
so notebooks run under nbval print nothing variable).
"""

from __future__ import annotations

import os

from functools import partial

from .process import OPEN_BARS
from .validation import MAX_COUNT, checked, optional, require_bool, require_int, require_iterable, require_text

_count = partial(require_int, minimum=0, maximum=MAX_COUNT)

__all__ = ["progress_enabled", "progress", "progress_bar"]


def progress_enabled() -> bool:
    """True unless ``CI`` or ``KFCAL_QUIET`` is set to a non-empty value."""
    return not (os.environ.get("CI") or os.environ.get("KFCAL_QUIET"))


@checked(iterable=require_iterable, total=optional(_count), desc=optional(require_text), enabled=optional(require_bool))
def progress(iterable, total: int | None = None, desc: str | None = None, enabled: bool | None = None):
    """Wrap ``iterable`` in a tqdm bar (notebook widget or terminal) when enabled.

    ``enabled=None`` means :func:`progress_enabled`.
    """
    if enabled is None:
        enabled = progress_enabled()
    if not enabled:
        return iterable
    from tqdm.auto import tqdm

    return _shown(tqdm(iterable, total=total, desc=desc, leave=False))


def _shown(bar):
    """Register ``bar`` as on the screen (the command line's signal handler then starts its line on
    a new line); closed bars are forgotten."""
    OPEN_BARS[:] = [b for b in OPEN_BARS if not getattr(b, "disable", True)]
    OPEN_BARS.append(bar)
    return bar


class _NoBar:
    """The interface of a tqdm bar that shows nothing."""

    def update(self, n=1):
        pass

    def close(self):
        pass


@checked(total=_count, desc=optional(require_text), enabled=optional(require_bool))
def progress_bar(total: int, desc: str | None = None, enabled: bool | None = None):
    """A tqdm bar over ``total`` items that the caller moves with ``update(n)`` and ends with
    ``close()``, or an object with the same two methods that shows nothing when not enabled
    (``enabled=None`` means :func:`progress_enabled`).  The bar redraws at most every 0.5 s."""
    if enabled is None:
        enabled = progress_enabled()
    if not enabled:
        return _NoBar()
    from tqdm.auto import tqdm

    return _shown(tqdm(total=total, desc=desc, leave=False, mininterval=0.5))
