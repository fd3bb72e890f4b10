"""``python -m mjxskill.explore``: the command of :mod:`mjxskill.cli.explore`."""

from mjxskill.cli.explore import main

if __name__ == "__main__":
    raise SystemExit(main())
