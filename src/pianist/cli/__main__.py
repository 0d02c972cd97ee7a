"""``python -m pianist.cli``."""

from pianist.cli import main

raise SystemExit(main())
