"""Ctrl-C works at any moment. SIGINT sent to real processes: small scripts
over ``mjxskill.cli.interrupt`` for the two ways an interrupt got lost (swallowed by a
garbage-collector callback, held up by a step that does not return), with Python's own handling
as the reference, and ``python -m mjxskill.train`` during start-up, compilation and the loop:
exit code 130, the "interrupted" message, no traceback, no evaluation lost."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cli_helpers import ROOT, TINY, command, subprocess_env
from mjxskill.cli.interrupt import EXIT_INTERRUPTED
from mjxskill.runs.run_dir import EVALUATIONS, Run

GC_SCRIPT = """
import gc, os, signal, sys, time
from mjxskill.cli import interrupt
collections = []
def callback(phase, info):  # like jax's _xla_gc_callback; the 5th collection is where Ctrl-C lands
    collections.append(phase)
    if len(collections) == 10:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.01)
gc.callbacks.append(callback)
if sys.argv[1] == "install":
    interrupt.install("gc-test")
else:  # Python's own handler, even when started with SIGINT ignored (a shell's background job)
    signal.signal(signal.SIGINT, signal.default_int_handler)
print("ready", flush=True)
try:
    while True:
        gc.collect()
        time.sleep(0.01)
except KeyboardInterrupt:
    interrupt.acknowledge()
    print("caught", flush=True)
    sys.exit(130)
"""

NOEXCEPT_SCRIPT = """
import os, signal, sys, time
from mjxskill.cli import interrupt
if sys.argv[1] == "install":
    interrupt.install("noexcept-test")
else:  # Python's own handler
    signal.signal(signal.SIGINT, signal.default_int_handler)
import numpy.lib.format
from scipy.stats import qmc
read_array = numpy.lib.format.read_array
def reading(*args, **kwargs):  # Ctrl-C lands while scipy's Sobol set-up (a Cython noexcept
    os.kill(os.getpid(), signal.SIGINT)  # function) loads its direction numbers
    time.sleep(0.01)
    return read_array(*args, **kwargs)
numpy.lib.format.read_array = reading
print("ready", flush=True)
try:
    qmc.Sobol(d=2, seed=0).random(4)
    time.sleep(3)
    print("not interrupted", flush=True)
except KeyboardInterrupt:
    interrupt.acknowledge()
    print("caught", flush=True)
    sys.exit(130)
"""

HALF_BUILT_SCRIPT = """
import io, os, signal, sys, time, zipfile
from mjxskill.cli import interrupt
if sys.argv[1] == "install":
    interrupt.install("half-built-test")
else:  # Python's own handler
    signal.signal(signal.SIGINT, signal.default_int_handler)
print("ready", flush=True)
try:
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(3)
except KeyboardInterrupt:
    interrupt.acknowledge()
    # What a Ctrl-C inside ZipFile.__init__ (np.load, np.savez) leaves: a ZipFile whose
    # finalizer fails on attributes __init__ never set.
    half = zipfile.ZipFile.__new__(zipfile.ZipFile)
    half.fp = io.BytesIO()  # the file is open, _writing not yet set
    del half
    print("caught", flush=True)
    sys.exit(130)
"""

IN_HOOK_SCRIPT = """
import os, signal, sys, time
from mjxskill.cli import interrupt
def slow_hook(unraisable):  # the hook printing a finalizer's error when Ctrl-C lands
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.5)
sys.unraisablehook = slow_hook
if sys.argv[1] == "install":
    interrupt.install("in-hook-test")  # slow_hook is the hook it passes other errors on to
else:  # Python's own handler
    signal.signal(signal.SIGINT, signal.default_int_handler)
class Failing:
    def __del__(self):
        raise ValueError("a finalizer's own error")
print("ready", flush=True)
try:
    Failing()
    time.sleep(3)
    print("not interrupted", flush=True)
except KeyboardInterrupt:
    interrupt.acknowledge()
    print("caught", flush=True)
    sys.exit(130)
"""

STUCK_SCRIPT = """
import ctypes, signal, sys
from mjxskill.cli import interrupt
interrupt.GRACE_SECONDS = float(sys.argv[1])
interrupt.install("stuck-test")
interrupt.set_message("interrupted: the test's own message")
# The main thread stuck in a C call that does not return on a signal (like an XLA compile): it
# never runs Python's handler; only the watchdog thread hears the signal.
signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
print("ready", flush=True)
ctypes.CDLL(None).pause()  # the test signals 0.3 s after "ready": by then the main thread is in here
"""


def start(script, *args):
    proc = subprocess.Popen([sys.executable, "-c", script, *args], cwd=ROOT, env=subprocess_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert first_line(proc.stdout) == "ready"
    return proc


def first_line(pipe) -> str:
    """The first line, read a byte at a time: ``readline`` fills the text buffer with whatever is
    already in the pipe ("caught" too, from a fast script), and ``communicate`` reads the
    file descriptor directly, so the rest would be lost (CI saw an empty stdout)."""
    line = b""
    while not line.endswith(b"\n"):
        byte = os.read(pipe.fileno(), 1)
        if not byte:
            break
        line += byte
    return line.decode().strip()


def assert_caught_quietly(script):
    """With ``interrupt.install``, the script's own handler caught the interrupt (exit 130,
    "caught") and nothing was printed on the way."""
    proc = start(script, "install")
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and out.strip() == "caught", (out, err)
    assert "Exception ignored" not in err and "Traceback" not in err, err


def test_an_interrupt_swallowed_by_a_gc_callback_is_raised_again():
    reference = start(GC_SCRIPT, "python")  # Python's own handling: the interrupt is lost
    with pytest.raises(subprocess.TimeoutExpired):  # still running: the interrupt was lost
        reference.wait(timeout=3)
    reference.kill()
    _, err = reference.communicate()
    assert "Exception ignored" in err and "KeyboardInterrupt" in err

    assert_caught_quietly(GC_SCRIPT)


def test_an_interrupt_an_extension_prints_and_drops_is_raised_again_without_a_traceback():
    reference = start(NOEXCEPT_SCRIPT, "python")  # Python's own handling: printed, then lost
    out, err = reference.communicate(timeout=60)
    assert out.strip() == "not interrupted" and "Traceback" in err and "KeyboardInterrupt" in err, (out, err)

    assert_caught_quietly(NOEXCEPT_SCRIPT)


def test_finalizers_of_objects_an_interrupt_left_half_built_stay_quiet():
    reference = start(HALF_BUILT_SCRIPT, "python")  # Python's own handling prints them
    out, err = reference.communicate(timeout=60)
    assert out.strip() == "caught" and "Exception ignored" in err and "AttributeError" in err, (out, err)

    assert_caught_quietly(HALF_BUILT_SCRIPT)


def test_an_interrupt_landing_inside_the_unraisable_hook_is_raised_again():
    reference = start(IN_HOOK_SCRIPT, "python")  # Python's own handling: printed, then lost
    out, err = reference.communicate(timeout=60)
    assert out.strip() == "not interrupted" and "Exception ignored in sys.unraisablehook" in err, (out, err)

    assert_caught_quietly(IN_HOOK_SCRIPT)


def test_an_interrupt_nothing_handles_ends_the_process_after_the_grace_period():
    proc = start(STUCK_SCRIPT, "1")
    time.sleep(0.3)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == EXIT_INTERRUPTED
    assert err.strip() == ("stuck-test: interrupted: the test's own message (the running step did not stop "
                           "within 1 s, so the process ends here)")


def test_a_second_interrupt_ends_the_process_at_once():
    proc = start(STUCK_SCRIPT, "600")
    time.sleep(0.3)
    proc.send_signal(signal.SIGINT)
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)  # long before the 600 s grace period
    assert proc.returncode == EXIT_INTERRUPTED
    assert err.strip() == "stuck-test: interrupted: the test's own message (interrupted again)"


def interrupt_train(out, moment, timeout=600, **env):
    """Starts ``train push`` into ``out``, sends SIGINT once ``moment(pid, stdout so far)``,
    returns (exit code, stderr, evaluations.csv as it was just before the signal)."""
    log = out.parent / f"{out.name}.stdout"
    with open(log, "w") as stdout:
        proc = subprocess.Popen(command("train", "push", *TINY, "--budget", "60", "--out", out), cwd=ROOT,
                                env=subprocess_env(**env), stdout=stdout, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + timeout
        while not moment(proc.pid, log.read_text()) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert proc.poll() is None, "train ended before the moment to interrupt it"
        before = (out / EVALUATIONS).read_text() if (out / EVALUATIONS).is_file() else ""
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    return proc.returncode, err, before


def importing(pid, stdout):
    """numpy is being loaded (the command module's imports, after the handler is installed) and
    nothing is planned yet."""
    try:
        maps = Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False
    return "_multiarray_umath" in maps and "task:" not in stdout


def after(condition, seconds):
    seen = []

    def check(pid, stdout):
        if not seen and condition(pid, stdout):
            seen.append(time.monotonic())
        return bool(seen) and time.monotonic() - seen[0] >= seconds

    return check


@pytest.mark.parametrize("moment", ["import", "compilation", "loop"])
def test_train_stops_on_ctrl_c_at_any_moment(tmp_path, moment):
    out = tmp_path / "run"
    when = {"import": importing,
            "compilation": after(lambda pid, text: "run directory:" in text, 1.0),
            "loop": lambda pid, text: (out / EVALUATIONS).is_file() and len((out / EVALUATIONS).read_text().splitlines()) >= 4}
    # compilation: a fresh cache, so that it really compiles; otherwise the shared one (the
    # program of these settings is cached by the other train tests)
    env = {"MJXSKILL_CACHE_DIR": str(tmp_path / "cache")} if moment == "compilation" else {}
    code, stderr, before = interrupt_train(out, when[moment], **env)
    assert code == EXIT_INTERRUPTED, stderr
    assert "Traceback" not in stderr and "Exception ignored" not in stderr, stderr
    last = [line for line in stderr.splitlines() if line.strip()][-1]
    if moment == "import":
        assert last == "mjxskill.train: interrupted" and not out.exists(), stderr
        return
    assert last == f"mjxskill.train: interrupted: every finished batch is in {out}; continue with python -m mjxskill.train push --resume {out}"
    after_ = (out / EVALUATIONS).read_text()
    assert after_.startswith(before)  # nothing lost: every row on disk before is still there
    if moment == "loop":
        assert len(before.splitlines()) >= 4 and len(Run(out).evaluations()) >= 3
