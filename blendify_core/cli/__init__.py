"""The ``blendify`` command line and the built-in demo."""

from blendify_core.cli.main import main

__all__ = ["main"]
