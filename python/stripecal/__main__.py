"""``python -m stripecal`` runs the command-line interface."""

from stripecal.cli import main

raise SystemExit(main())
