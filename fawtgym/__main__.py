"""``python -m fawtgym``: the same as the ``fawtgym`` command."""

from fawtgym.cli import main

raise SystemExit(main())
