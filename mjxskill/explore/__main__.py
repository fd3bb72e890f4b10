"""``python -m mjxskill.explore``: the command of :mod:`mjxskill.cli.explore`.

Ctrl-C is handled from the first import on (``mjxskill.cli.interrupt``): the server stops, the
rollouts it built are closed and the process ends with exit code 130 without the interpreter's
shutdown, which aborts ("PyGILState_Check") when a rollout thread is inside MuJoCo or XLA."""

from mjxskill.cli.interrupt import run_command

raise SystemExit(run_command("mjxskill.explore", "mjxskill.cli.explore"))
