"""``python -m mjxskill.experiment``: the command of :mod:`mjxskill.cli.experiment`.

Ctrl-C is handled from the first import on (``mjxskill.cli.interrupt``)."""

from mjxskill.cli.interrupt import run_command

raise SystemExit(run_command("mjxskill.experiment", "mjxskill.cli.experiment"))
