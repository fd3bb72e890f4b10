"""``python -m mjxskill.experiment``: the command of :mod:`mjxskill.cli.experiment`.

Run as a program, Ctrl-C is handled from the first import on (``mjxskill.cli.interrupt``)."""

if __name__ == "__main__":
    from mjxskill.cli.interrupt import run_command

    raise SystemExit(run_command("mjxskill.experiment", "mjxskill.cli.experiment"))

from mjxskill.cli.experiment import main  # noqa: E402, F401  (imported as a module: the command's entry point)
