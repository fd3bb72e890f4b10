"""``python -m mjxskill.explore``: the command of :mod:`mjxskill.cli.explore`."""

from mjxskill.cli.explore import main

raise SystemExit(main())
