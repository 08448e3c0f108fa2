"""The main job's staging folder: filled beside the output folder, moved into it only
when the whole run has succeeded, and never left behind.

The folder (``.NAME-XXXXXXXX`` beside ``NAME``) holds a record of its owner (process
id, the process's start time, host). It is removed when the run ends in any way
Python sees: success, an error, SIGINT (Ctrl-C) or SIGTERM, which
:func:`terminate_as_interrupt` turns into an exception so that every ``finally``
runs. A run killed outright (SIGKILL, a power cut) cannot clean up: the next run
for the same output folder removes the staging folders whose owner is gone (its
process id not running, or running but started at another time: a reused id), and
keeps those of a live run, of another host, or without a record.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import socket
import sys
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

from .constants import SIGNAL_REDELIVER_S

__all__ = ["OWNER_RECORD", "Interrupted", "commit", "remove_stale", "staging_folder",
           "terminate_as_interrupt"]

#: The owner's record inside a staging folder (not moved into the output folder).
OWNER_RECORD = ".staging-owner.json"
_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(BaseException):
    """The job was sent SIGINT or SIGTERM (``signum``); a BaseException, as
    KeyboardInterrupt, so that no ``except Exception`` swallows it."""

    def __init__(self, signum: int) -> None:
        super().__init__(f"interrupted by {signal.Signals(signum).name}")
        self.signum = signum


def _start_time(pid: int) -> str | None:
    """The process's start time in clock ticks since boot (Linux ``/proc``), or None."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as fh:
            return fh.read().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return None


def _owner() -> dict:
    return {"pid": os.getpid(), "start": _start_time(os.getpid()),
            "host": socket.gethostname()}


def _owner_gone(record: dict) -> bool:
    """Whether the process of an owner's record is certainly not running any more."""
    if record.get("host") != socket.gethostname():
        return False                                # another machine's: cannot tell
    pid = int(record["pid"])
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:                          # running, another user's
        pass
    start = _start_time(pid)
    return start is not None and record.get("start") is not None and start != record["start"]


def remove_stale(out: Path) -> list[Path]:
    """Remove the staging folders of ``out`` (``.NAME-*`` beside it) whose owner is gone;
    returns them."""
    removed = []
    for d in sorted(out.parent.glob(f".{out.name}-*")):
        rec = d / OWNER_RECORD
        if not d.is_dir() or d.is_symlink() or not rec.is_file():
            continue
        try:
            record = json.loads(rec.read_text(encoding="utf-8"))
            gone = _owner_gone(record)
        except (OSError, ValueError, KeyError, TypeError):
            continue                                 # unreadable: not provably stale
        if gone:
            shutil.rmtree(d, ignore_errors=True)
            removed.append(d)
    return removed


@contextlib.contextmanager
def terminate_as_interrupt() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM raise :class:`Interrupted` (once: a second
    signal while the first unwinds is ignored, so the clean-up is not cut short); the
    previous handlers are back after it. Outside the main thread it does nothing.

    Python runs a signal's handler in whatever Python code the main thread runs next,
    and that may be a callback from C (numba's compiler calls back into Python while
    it compiles a kernel), where the exception cannot propagate: C ignores it
    (``sys.unraisablehook``). Such a lost :class:`Interrupted` is sent again,
    ``SIGNAL_REDELIVER_S`` later, when the callback has returned.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    fired = []

    def handler(signum, _frame):
        if fired:
            return
        fired.append(signum)
        raise Interrupted(signum)

    hook = sys.unraisablehook

    def lost(unraisable) -> None:
        exc = unraisable.exc_value
        if isinstance(exc, Interrupted) and fired:
            fired.clear()
            timer = threading.Timer(SIGNAL_REDELIVER_S, os.kill, (os.getpid(), exc.signum))
            timer.daemon = True
            timer.start()
            return
        hook(unraisable)

    before = {s: signal.signal(s, handler) for s in _SIGNALS}
    sys.unraisablehook = lost
    try:
        yield
    finally:
        sys.unraisablehook = hook
        for s, h in before.items():
            signal.signal(s, h)


@contextlib.contextmanager
def staging_folder(out: Path) -> Iterator[Path]:
    """A fresh staging folder beside ``out`` (stale ones removed first, an owner's record
    in it); removed when the block ends, whatever the way. Use it inside
    :func:`terminate_as_interrupt` so that SIGTERM ends the block too."""
    remove_stale(out)
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}-", dir=out.parent))
    try:
        (stage / OWNER_RECORD).write_text(json.dumps(_owner()), encoding="utf-8")
        yield stage
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def commit(stage: Path, out: Path) -> None:
    """Move the staging folder's files into ``out`` (made if missing), the owner's record
    excepted."""
    out.mkdir(exist_ok=True)
    for f in sorted(stage.iterdir()):
        if f.name != OWNER_RECORD:
            os.replace(f, out / f.name)
