"""``python -m mjxskill.plan``: the command of :mod:`mjxskill.cli.plan`.

Run as a program, Ctrl-C is handled from the first import on (``mjxskill.cli.interrupt``)."""

if __name__ == "__main__":
    from mjxskill.cli.interrupt import run_command

    raise SystemExit(run_command("mjxskill.plan", "mjxskill.cli.plan"))

from mjxskill.cli.plan import main  # noqa: E402, F401  (imported as a module: the command's entry point)
