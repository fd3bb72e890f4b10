"""``python -m mjxskill.select``: the command of :mod:`mjxskill.cli.select`."""

from mjxskill.cli.select import main

if __name__ == "__main__":
    raise SystemExit(main())
