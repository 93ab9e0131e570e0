"""Library warnings (NumPy, rasterio, ...) as one line each in navgate's words, prefixed
``navgate CMD: warning:`` (:func:`warning_handler`); deprecations are hidden from users.
"""

from __future__ import annotations

import contextlib
import logging
import warnings
from collections.abc import Iterator
from typing import Any

import click

#: (category name or message fragment, navgate's words); first match wins
_WARNING_WORDS = (
    ("NotGeoreferencedWarning", "the DEM file has no georeferencing; its coordinates are "
                                "not usable"),
    ("invalid value encountered", "a computation produced NaN (invalid value)"),
    ("divide by zero", "a computation divided by zero"),
    ("overflow encountered", "a computation overflowed"),
    ("Mean of empty slice", "a mean over no samples (result is NaN)"),
)


def warning_line(prefix: str, message: Any, category: type | None = None) -> str:
    """One line in navgate's words for a library warning."""
    text = " ".join(str(message).split())
    cat = category.__name__ if category is not None else ""
    for key, words in _WARNING_WORDS:
        if key == cat or key in text:
            return f"{prefix}: warning: {words} ({text[:160]})" if key != cat else \
                f"{prefix}: warning: {words}"
    return f"{prefix}: warning: {text[:240]}"


class _OneLineHandler(logging.Handler):
    def __init__(self, prefix: str):
        super().__init__(logging.WARNING)
        self.prefix = prefix

    def emit(self, record):  # pragma: no cover - exercised through library logging
        with contextlib.suppress(Exception):
            click.echo(warning_line(self.prefix, record.getMessage()), err=True)


@contextlib.contextmanager
def warning_handler(prefix: str) -> Iterator[None]:
    """Within the block, Python warnings and library log records (WARNING and above) are
    printed as one line each in navgate's words, each distinct line once."""
    seen: set[str] = set()

    def show(message, category, filename, lineno, file=None, line=None):
        text = warning_line(prefix, message, category)
        if text not in seen:
            seen.add(text)
            click.echo(text, err=True)

    root = logging.getLogger()
    handler = _OneLineHandler(prefix)
    level = root.level
    with warnings.catch_warnings():
        # library API deprecations are for navgate's developers, not its users
        for category in (DeprecationWarning, PendingDeprecationWarning, FutureWarning):
            warnings.simplefilter("ignore", category)
        # Amaranth's notice that a component object was garbage-collected without being
        # elaborated says nothing to a user (it comes from whatever object the collector
        # happens to reach, even one made by an earlier call in the same process)
        warnings.filterwarnings("ignore", message=r".*created but never used")
        warnings.showwarning = show
        root.addHandler(handler)
        if level == logging.NOTSET or level > logging.WARNING:
            root.setLevel(logging.WARNING)
        try:
            yield
        finally:
            root.removeHandler(handler)
            root.setLevel(level)
