"""Files attached to a scene for a backend that understands their format (a ``.blend`` for Cycles).

An attachment is part of the picture: the backend that handles its format renders its unparsed content
beside the IR (see ``scene.attach_blend``); scene files and fingerprints include it. Backends that do not
handle the format render the IR only (what the attach step could parse into it): the attachment's
``approximations`` (what the parse could not carry) are listed in their ``result.meta["approximations"]``
(:meth:`Attachment.ir_limits`), and a crosscheck of a backend that reads the file against one that renders
the IR parse reports the pair as limited by the IR.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import PurePath

__all__ = ["IR_LIMIT_PREFIX", "Attachment"]

#: the start of every approximation line that comes from an attachment's IR parse
IR_LIMIT_PREFIX = "IR parse of "


@dataclass(frozen=True)
class Attachment:
    """A file of ``format`` (its suffix without the dot, e.g. ``"blend"``) at an absolute ``path``;
    ``approximations``: what parsing it into the IR could not carry (one line each; not part of equality)."""

    format: str
    path: str
    approximations: tuple[str, ...] = field(default=(), compare=False)

    def ir_limits(self) -> list[str]:
        """The approximations as ``result.meta["approximations"]`` lines of a backend rendering the IR parse."""
        name = PurePath(self.path).name
        return [f"{IR_LIMIT_PREFIX}{name}: {note}" for note in self.approximations]
