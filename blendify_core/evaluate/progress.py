"""Progress bars for evaluations that run many renders (``bf.crosscheck``, ``estimate_reference``).

``progress=None`` (the default of those functions) shows a tqdm bar only where someone can see it: when
standard error is a terminal or the code runs in a Jupyter kernel; ``True`` always shows one, ``False``
never. tqdm's own switch ``TQDM_DISABLE=1`` (environment) turns every bar off, and without tqdm installed
there is no bar (never an error). The bar writes to standard error, never to standard output.
"""

from __future__ import annotations

import sys
from typing import Any

from blendify_core.ir.validate import as_bool

__all__ = ["progress_bar", "wants_progress"]


def _in_notebook() -> bool:
    """True inside a Jupyter kernel (IPython's kernel app is running), without importing IPython."""
    ipython = sys.modules.get("IPython")
    if ipython is None:
        return False
    try:
        shell = ipython.get_ipython()
    except Exception:  # noqa: BLE001 - an unusual IPython: no notebook
        return False
    return shell is not None and "IPKernelApp" in getattr(shell, "config", {})


def wants_progress(progress: bool | None) -> bool:
    """Whether to show a bar for ``progress`` (None: a terminal on standard error or a notebook)."""
    if progress is not None:
        return as_bool("progress", progress)
    stream = sys.stderr
    try:
        tty = bool(stream is not None and stream.isatty())
    except (AttributeError, ValueError):  # a replaced or closed stream
        tty = False
    return tty or _in_notebook()


class _NoBar:
    """What the evaluations call when no bar is shown."""

    def update(self, n: int = 1) -> None:
        pass

    def set_postfix_str(self, s: str = "", refresh: bool = True) -> None:
        pass

    def close(self) -> None:
        pass


def progress_bar(total: int, desc: str, progress: bool | None, unit: str = "render") -> Any:
    """A tqdm bar of ``total`` steps (``tqdm.auto``: a widget in notebooks), or a silent stand-in."""
    if not wants_progress(progress):
        return _NoBar()
    try:
        from tqdm.auto import tqdm
    except ImportError:  # tqdm is optional here: no bar
        return _NoBar()
    return tqdm(total=total, desc=desc, unit=unit, dynamic_ncols=True, file=sys.stderr)
