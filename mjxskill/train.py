"""``python -m mjxskill.train``: the command of :mod:`mjxskill.cli.train`."""

from mjxskill.cli.train import main

if __name__ == "__main__":
    raise SystemExit(main())
