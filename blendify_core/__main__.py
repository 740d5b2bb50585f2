"""``python -m blendify_core`` runs the ``blendify`` command."""

from blendify_core.cli.main import main

raise SystemExit(main())
