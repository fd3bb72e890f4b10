"""``python -m mjxskill.evaluate``: the command of :mod:`mjxskill.cli.evaluate`."""

from mjxskill.cli.evaluate import main

if __name__ == "__main__":
    raise SystemExit(main())
