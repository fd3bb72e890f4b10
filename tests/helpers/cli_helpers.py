"""Running the commands in tests: in this process through their entry point (fast), or as a
real ``python -m`` subprocess (what a user runs), and the shape every bad input must have."""

import importlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HELPERS = Path(__file__).resolve().parent  # these modules: what a subprocess puts on sys.path to import them

# Tiny episodes and a cheap acquisition search: the commands' behaviour, not the physics or the GP.
QUICK_GP = ["n_raw=64", "n_restarts=2", "n_opt_steps=10", "fit_starts=1", "fit_steps=10"]
# The paper's protocol: the command's files and behaviour (the robust one: tests/cli/test_robust.py)
TINY = ["--budget", "6", "--batch-size", "3", "--init", "3", "--worlds", "1", "--episode-seconds", "0.2", "--quiet",
        "--protocol", "paper", *(arg for option in QUICK_GP for arg in ("--optimizer-option", option))]


def command(module, *args):
    return [sys.executable, "-m", f"mjxskill.{module}", *map(str, args)]


def subprocess_env(**extra) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])  # this checkout first
    env.update(extra)
    return env


def run_cli(module, *args, timeout=600, cwd=ROOT, **env):
    """``python -m mjxskill.<module> args`` in a subprocess: CompletedProcess (text)."""
    return subprocess.run(command(module, *args), cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env=subprocess_env(**env))


def kill_once_written(module, args, csv: Path, lines: int, timeout: float = 600) -> bool:
    """Starts ``python -m mjxskill.<module> args`` and kills it with SIGKILL once ``csv`` has
    ``lines`` lines; whether it was still running then (not ended on its own)."""
    proc = subprocess.Popen(command(module, *args), cwd=ROOT, env=subprocess_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not (csv.is_file() and len(csv.read_text().splitlines()) >= lines):
            assert proc.poll() is None, f"mjxskill.{module} ended before {csv} had {lines} lines"
            time.sleep(0.1)
        running = proc.poll() is None
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait()
    return running


def invoke(capsys, module, *args):
    """The command's entry point in this process (what ``python -m`` runs): (exit code, stderr)."""
    main = importlib.import_module(f"mjxskill.cli.{module}").main
    try:
        code = main([str(a) for a in args])
    except SystemExit as exit_:  # argparse's own errors
        code = exit_.code
    return code, capsys.readouterr().err


def error_line(code: int, stderr: str, prog: str, *fragments: str) -> str:
    """Asserts exit code 2 and exactly one ``prog: error:`` line (no traceback) holding every
    fragment; returns that line."""
    assert code == 2, stderr
    assert "Traceback" not in stderr, stderr
    errors = [line for line in stderr.splitlines() if ": error:" in line]
    assert len(errors) == 1 and errors[0].startswith(f"mjxskill.{prog}: error: "), stderr
    for fragment in fragments:
        assert fragment in errors[0], (fragment, errors[0])
    return errors[0]


def snapshot(folder: Path) -> dict:
    """Every file below ``folder`` (relative path -> bytes) but the writer's lock (which says
    who last wrote, mjxskill.runs.run_lock): to show that nothing was changed."""
    folder = Path(folder)
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != ".lock"}
