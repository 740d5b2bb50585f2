"""Files attached to a scene for a backend that understands their format (a ``.blend`` for Cycles).

An attachment is part of the picture: the backend that handles its format renders its unparsed content
beside the IR (see ``scene.attach_blend``); scene files and fingerprints include it. Backends that do not
handle the format render the IR only (what the attach step could parse into it).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Attachment"]


@dataclass(frozen=True)
class Attachment:
    """A file of ``format`` (its suffix without the dot, e.g. ``"blend"``) at an absolute ``path``."""

    format: str
    path: str
