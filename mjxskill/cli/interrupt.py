"""Ctrl-C at any moment of a command: start-up, imports, compilation and the loop included.

Python turns SIGINT into a ``KeyboardInterrupt`` wherever the main thread happens to be. Two
places lost it: raised inside a garbage-collector callback (JAX installs one,
``_xla_gc_callback``) or a finalizer, it is printed as "Exception ignored in ..." and dropped,
and the run went on to its end; and while the main thread sits in a long C call (an XLA
compile, a batch on the device) it is only raised when that call returns. So, for the process
of a ``python -m mjxskill.<command>`` (``run_command``; never on import):

* the first Ctrl-C raises ``KeyboardInterrupt`` as usual; the command handles it where it
  knows what is on disk and calls ``acknowledge()``;
* one that would be raised inside a gc callback or inside the hooks below (seen from the
  handler's frame) or that a finalizer swallowed (seen by ``sys.unraisablehook``, silenced
  for it) is raised again in the main thread a moment later by the watchdog
  (``_thread.interrupt_main``), until it lands. An
  extension function that cannot raise (Cython's ``noexcept``, e.g. scipy's Sobol set-up) first
  prints the traceback through ``sys.excepthook`` and then hands the exception to the
  unraisable hook: after a Ctrl-C that print is silenced too, as are the finalizers that fail
  on objects the interrupt left half-built;
* Python runs its handler only when the main thread next runs Python code, so a watchdog
  thread hears the signal itself (``signal.set_wakeup_fd``: the C-level handler writes to a
  pipe at once). If nothing acknowledged the interrupt after ``GRACE_SECONDS`` (the main
  thread is stuck in C), it prints the command's message and ends the process with
  ``EXIT_INTERRUPTED``; a second Ctrl-C does that at once.

Nothing is lost by ending there: every finished batch is on disk (appended and fsynced), every
other file is replaced in one step, and a line cut short is set aside on resume
(``mjxskill.runs.resume``). After an interrupt the process also ends with ``os._exit``
rather than the interpreter's shutdown, which could crash in XLA's threads (exit 139) when the
interrupt came during a compile.
"""

from __future__ import annotations

import _thread
import gc
import importlib
import os
import select
import signal
import sys
import threading
import time
from typing import Any

EXIT_INTERRUPTED = 130  # 128 + SIGINT, what shells report for a Ctrl-C
GRACE_SECONDS = 5.0

_state: dict[str, Any] = {"prog": "mjxskill", "acknowledged": False, "redeliver": False, "redelivered": 0,
          "message": "interrupted", "previous_hook": None, "previous_excepthook": None, "request_fd": None,
          "pressed": False}


def run_command(prog: str, module: str) -> int:
    """Runs ``module.main()`` (a command) with Ctrl-C handled from the first import on."""
    install(prog)
    try:
        code = importlib.import_module(module).main()
    except Exception:
        if not _state["pressed"]:
            raise  # a bug: keep its traceback
        # A KeyboardInterrupt that an extension turned into another error on its way up
        # (numpy's import reports one as "Importing the numpy C-extensions failed").
        code = _interrupted()
    except KeyboardInterrupt:  # before the command had anything to say (imports, parsing)
        code = _interrupted()
    if code == EXIT_INTERRUPTED:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def _interrupted() -> int:
    acknowledge()
    print(f"\n{_state['prog']}: {_state['message']}", file=sys.stderr)
    return EXIT_INTERRUPTED


def install(prog: str) -> None:
    """Handles SIGINT as described in the module docstring (main thread only)."""
    _state["prog"] = prog
    signal.signal(signal.SIGINT, _on_sigint)
    if _state["previous_hook"] is None:
        _state["previous_hook"] = sys.unraisablehook
        sys.unraisablehook = _on_unraisable
        _state["previous_excepthook"] = sys.excepthook
        sys.excepthook = _on_excepthook
        signals, write = os.pipe()
        os.set_blocking(write, False)
        signal.set_wakeup_fd(write, warn_on_full_buffer=False)
        requests, _state["request_fd"] = os.pipe()
        os.set_blocking(_state["request_fd"], False)
        threading.Thread(target=_watchdog, args=(signals, requests), name="mjxskill-interrupt", daemon=True).start()


def set_message(message: str) -> None:
    """What an interrupt from now on leaves behind, e.g. where the finished batches are."""
    _state["message"] = message


def message() -> str:
    return _state["message"]


def acknowledge() -> None:
    """The KeyboardInterrupt reached the command: no redelivery, no forced exit."""
    _state["acknowledged"] = True


def stopped(prog: str, save=None) -> int:
    """A command's answer to the KeyboardInterrupt it caught: acknowledge it, ``save()`` what
    shows the finished work (figures, a report; a failure there must not hide the message),
    print the message and return ``EXIT_INTERRUPTED``."""
    acknowledge()
    if save is not None:
        try:
            save()
        except Exception:  # noqa: BLE001  (a plotting problem must not hide where the work is)
            pass
    print(f"\n{prog}: {message()}", file=sys.stderr)
    return EXIT_INTERRUPTED


def _on_sigint(signum, frame) -> None:
    _state["pressed"] = True
    if _would_be_swallowed(frame):  # it would be printed and dropped there: raise it again after
        _request_redelivery()
        return
    _state["redeliver"] = False
    raise KeyboardInterrupt  # a second Ctrl-C is the watchdog's: it ends the process


def _on_unraisable(unraisable) -> None:
    if issubclass(unraisable.exc_type, KeyboardInterrupt) and not _state["acknowledged"]:
        _request_redelivery()  # raised where Python cannot propagate it (a finalizer, a callback)
        return
    if _state["pressed"]:
        # A finalizer failing on an object the Ctrl-C left half-built (a ZipFile interrupted in
        # its __init__ fails in __del__ on an attribute it never set): noise on the way out.
        return
    _state["previous_hook"](unraisable)


def _on_excepthook(exc_type, value, traceback) -> None:
    if issubclass(exc_type, KeyboardInterrupt) and _state["pressed"]:
        return  # an extension printing the Ctrl-C it cannot raise; _on_unraisable hears it next
    _state["previous_excepthook"](exc_type, value, traceback)


def _would_be_swallowed(frame) -> bool:
    """Whether ``frame`` runs inside a gc callback or inside our own hooks (and whatever hook
    they call): Python prints an exception raised there ("Exception ignored in
    sys.unraisablehook") and goes on. A redelivered interrupt can land in ``_on_unraisable``
    itself, which had just asked for it (CI lost one so)."""
    codes = {getattr(getattr(cb, "__func__", cb), "__code__", None) for cb in gc.callbacks}
    codes |= {_on_unraisable.__code__, _on_excepthook.__code__}
    while frame is not None:
        if frame.f_code in codes:
            return True
        frame = frame.f_back
    return False


def _request_redelivery() -> None:
    # Not from here: we are inside the callback that would swallow it again. The watchdog raises
    # it in the main thread a moment later, and again until it lands.
    _state["redeliver"] = True
    try:
        os.write(_state["request_fd"], b"r")
    except (OSError, KeyError):  # the pipe is full: a request is pending anyway
        pass


def _watchdog(signals: int, requests: int) -> None:
    """Hears every SIGINT at once, whatever the main thread is doing, and raises swallowed ones
    again."""
    deadline: float | None  # when the grace period of the first Ctrl-C ends
    received, deadline = 0, None
    while True:
        waiting = not _state["acknowledged"] and deadline is not None
        # waiting: a deadline is set
        timeout = 0.05 if _state["redeliver"] else max(0.0, deadline - time.monotonic()) if waiting else None  # type: ignore[operator]
        readable, _, _ = select.select([signals, requests], [], [], timeout)
        if signals in readable:
            received += sum(1 for b in os.read(signals, 64) if b == signal.SIGINT)
            presses = received - _state["redelivered"]
            if presses >= 2:
                _exit_now("interrupted again")
            if presses >= 1 and deadline is None:
                deadline = time.monotonic() + GRACE_SECONDS
        if requests in readable:
            os.read(requests, 64)
        if _state["redeliver"] and not _state["acknowledged"]:
            _state["redelivered"] += 1  # before interrupt_main writes to the wakeup pipe
            _thread.interrupt_main(signal.SIGINT)
        # waiting: a deadline is set
        if waiting and not _state["acknowledged"] and time.monotonic() >= deadline:  # type: ignore[operator]
            _exit_now(f"the running step did not stop within {GRACE_SECONDS:g} s, so the process ends here")


def _exit_now(why: str) -> None:
    try:
        sys.stdout.flush()
        print(f"\n{_state['prog']}: {_state['message']} ({why})", file=sys.stderr, flush=True)
    finally:
        os._exit(EXIT_INTERRUPTED)


__all__ = ["EXIT_INTERRUPTED", "GRACE_SECONDS", "acknowledge", "install", "message", "run_command", "set_message"]
