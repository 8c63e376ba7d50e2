"""``python -m exo_ctrl`` runs the ``exo-ctrl`` command."""

from .cli import main

raise SystemExit(main())
