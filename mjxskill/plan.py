"""``python -m mjxskill.plan``: the command of :mod:`mjxskill.cli.plan`."""

from mjxskill.cli.plan import main

if __name__ == "__main__":
    raise SystemExit(main())
