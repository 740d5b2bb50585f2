"""``scene.show()``: look at a scene before rendering.

With a display (and outside a notebook) pyrender's interactive Viewer opens on the scene as the ``pyrender``
backend translates it; in a notebook, or with no display, the self-contained HTML view
(:mod:`blendify_core.export.html`, three.js, offline) is shown inline in the notebook or written to a file.
"""

from __future__ import annotations

import html
import importlib
import logging
import os
import sys
import tempfile
import webbrowser
from pathlib import Path
from typing import Any

from blendify_core.errors import BackendUnavailableError, InvalidSceneError
from blendify_core.evaluate.progress import _in_notebook
from blendify_core.export.html import html_document
from blendify_core.io.output import atomic_write
from blendify_core.ir.validate import as_choice, strict_arguments
from blendify_core.registry import get_backend_class

__all__ = ["HTMLView", "show"]

logger = logging.getLogger(__name__)
VIEWERS = ("auto", "pyrender", "html")


def in_notebook() -> bool:
    """True inside a Jupyter kernel (the same test as the progress bars')."""
    return _in_notebook()


def has_display() -> bool:
    """Whether a window can be opened: always on macOS and Windows, with DISPLAY or WAYLAND_DISPLAY elsewhere."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class HTMLView:
    """The HTML view of a scene: displayed inline by Jupyter (an iframe holding the page), ``path`` is the
    file it was written to (None when only shown in a notebook); ``save(path)`` writes it again."""

    def __init__(self, page: str, width: int, height: int, path: Path | None = None) -> None:
        self.html = page
        self.width, self.height = width, height
        self.path = path

    def save(self, path: str | os.PathLike[str]) -> Path:
        p = Path(os.fspath(path)).expanduser()
        self.path = atomic_write(p, lambda tmp: Path(tmp).write_text(self.html, encoding="utf-8"))
        return self.path

    def _repr_html_(self) -> str:
        doc = html.escape(self.html, quote=True)
        return (
            f'<iframe srcdoc="{doc}" style="display: block; width: 100%; max-width: {self.width}px; aspect-ratio: '
            f'{self.width} / {self.height}; border: 0;" title="blendify scene"></iframe>'
        )

    def __repr__(self) -> str:
        where = f" at {str(self.path)!r}" if self.path else ""
        return f"HTMLView({self.width}x{self.height}{where})"


@strict_arguments
def show(
    scene: Any,
    viewer: str = "auto",
    path: str | os.PathLike[str] | None = None,
    open_browser: bool | None = None,
    **kwargs: Any,
) -> Any:
    """Look at ``scene`` before rendering.

    ``viewer``: ``"pyrender"`` (pyrender's interactive Viewer: needs a display and the ``pyrender`` backend;
    blocks until its window closes unless ``run_in_thread=True``), ``"html"`` (the offline three.js page) or
    ``"auto"`` (the default: pyrender when a display exists outside a notebook, otherwise HTML; a pyrender
    viewer that cannot open falls back to HTML with the reason logged).

    The HTML view is displayed inline in a notebook; elsewhere it is written to ``path`` (default: a file
    in the temporary folder, named by the scene's fingerprint) and, when a display exists
    (``open_browser=None``) or ``open_browser=True``, opened in the web browser. ``kwargs`` go to the viewer
    (``pyrender.Viewer`` keywords, or ``title`` / ``show_helpers`` for HTML). Returns the pyrender Viewer or
    an :class:`HTMLView`.
    """
    viewer = as_choice("viewer", viewer, VIEWERS)
    notebook = in_notebook()
    if viewer == "auto":
        viewer = "pyrender" if has_display() and not notebook and scene.camera is not None else "html"
        if viewer == "pyrender":
            try:
                return get_backend_class("pyrender").show_scene(scene, **kwargs)
            except BackendUnavailableError as exc:
                logger.warning("scene.show(): %s; showing the HTML view instead", exc)
                viewer, kwargs = "html", {}
    elif viewer == "pyrender":
        return get_backend_class("pyrender").show_scene(scene, **kwargs)
    page = html_document(scene, **kwargs)
    cam = scene.camera
    size = (int(cam.width), int(cam.height)) if cam is not None else (960, 720)
    view = HTMLView(page, *size)
    if open_browser is not None and not isinstance(open_browser, bool):
        raise InvalidSceneError(f"open_browser: expected True, False or None, got {open_browser!r}")
    if notebook:
        display = importlib.import_module("IPython.display").display
        if path is not None:
            view.save(path)
        display(view)
        return view
    if path is None:
        path = Path(tempfile.gettempdir()) / f"blendify_view_{scene.fingerprint()[:12]}.html"
    written = view.save(path)
    if open_browser or (open_browser is None and has_display()):
        webbrowser.open(written.resolve().as_uri())
    else:
        logger.warning("scene.show(): no display; the scene view is in %s (open it in a web browser)", written)
    return view
