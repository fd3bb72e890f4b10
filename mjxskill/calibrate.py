"""``python -m mjxskill.calibrate``: the command of :mod:`mjxskill.cli.calibrate`.

Run as a program, Ctrl-C is handled from the first import on (``mjxskill.cli.interrupt``)."""

if __name__ == "__main__":
    from mjxskill.cli.interrupt import run_command

    raise SystemExit(run_command("mjxskill.calibrate", "mjxskill.cli.calibrate"))

from mjxskill.cli.calibrate import main  # noqa: E402, F401  (imported as a module: the command's entry point)
