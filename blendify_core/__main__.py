"""``python -m blendify_core`` runs the ``blendify`` command."""

from .cli import main

raise SystemExit(main())
