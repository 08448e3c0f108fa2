"""The main job's staging folder (sim.staging): SIGTERM and SIGINT during
``python -m sim job --out DIR`` leave nothing behind, and a staging folder of a run
killed outright is removed by the next run only when its owner is certainly gone."""

from __future__ import annotations

import ctypes
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sim.staging import (OWNER_RECORD, Interrupted, commit, remove_stale, staging_folder,
                         terminate_as_interrupt)

ROOT = Path(__file__).resolve().parents[2]


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def _stage(parent: Path, name: str, record: dict | None) -> Path:
    d = parent / name
    d.mkdir()
    (d / "report.json").write_text("{}")
    if record is not None:
        (d / OWNER_RECORD).write_text(json.dumps(record))
    return d


def _my_start() -> str:
    with open(f"/proc/{os.getpid()}/stat") as fh:
        return fh.read().rsplit(")", 1)[1].split()[19]


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_only_stale_staging_folders_are_removed(tmp_path):
    host = socket.gethostname()
    dead = _dead_pid()
    stale = _stage(tmp_path, ".job-dead", {"pid": dead, "start": None, "host": host})
    reused = _stage(tmp_path, ".job-reused", {"pid": os.getpid(), "start": "1", "host": host})
    live = _stage(tmp_path, ".job-live", {"pid": os.getpid(), "start": _my_start(),
                                          "host": host})
    other_host = _stage(tmp_path, ".job-away", {"pid": dead, "start": None,
                                                "host": host + "-elsewhere"})
    unrecorded = _stage(tmp_path, ".job-old", None)
    garbled = _stage(tmp_path, ".job-garbled", None)
    (garbled / OWNER_RECORD).write_text("{not json")
    other_job = _stage(tmp_path, ".plan-dead", {"pid": dead, "start": None, "host": host})
    removed = remove_stale(tmp_path / "job")
    assert sorted(removed) == sorted([stale, reused])
    assert not stale.exists() and not reused.exists()
    for kept in (live, other_host, unrecorded, garbled, other_job):
        assert (kept / "report.json").exists()


def test_staging_folder_is_removed_and_its_record_not_committed(tmp_path):
    out = tmp_path / "job"
    with staging_folder(out) as stage:
        assert stage.parent == tmp_path and stage.name.startswith(".job-")
        rec = json.loads((stage / OWNER_RECORD).read_text())
        assert rec["pid"] == os.getpid()
        (stage / "job.nc").write_text("%\n%\n")
        commit(stage, out)
    assert not stage.exists()
    assert sorted(p.name for p in out.iterdir()) == ["job.nc"]
    with pytest.raises(RuntimeError), staging_folder(out) as stage:
        raise RuntimeError("the job failed")
    assert not stage.exists()


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_signal_during_the_job_leaves_nothing_and_stale_folders_go(tmp_path, signum):
    """A stale staging folder (its owner killed) is removed when the next run starts; that
    run, sent the signal once its own staging folder exists, removes its own too and
    ends with one line and exit status 128 + the signal."""
    out = tmp_path / "job"
    stale = _stage(tmp_path, ".job-killed", {"pid": _dead_pid(), "start": None,
                                             "host": socket.gethostname()})
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    proc = subprocess.Popen([sys.executable, "-m", "sim", "job", "--out", str(out),
                             "--no-dask"], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        t0 = time.monotonic()
        mine: list[Path] = []
        while not mine:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() - t0 < 120, "the job made no staging folder in 120 s"
            mine = [d for d in tmp_path.glob(".job-*")
                    if d != stale and (d / OWNER_RECORD).is_file()]
            time.sleep(0.05)
        assert json.loads((mine[0] / OWNER_RECORD).read_text())["pid"] == proc.pid
        assert not stale.exists()
        time.sleep(0.5)                                   # the job is under way
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 128 + signum, err[-2000:]
    assert err.strip().splitlines()[-1].startswith("error: ")
    assert f"interrupted by {signal.Signals(signum).name}" in err
    assert list(tmp_path.glob(".job-*")) == []
    assert not out.exists()


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_whose_exception_a_callback_from_c_swallowed_is_delivered_again(signum):
    """The handler runs in a callback from C (as numba's compiler calls back into Python
    while a fresh job compiles its kernels), where its exception cannot propagate: C
    ignores it. The signal is sent again, so the block still ends in Interrupted; the
    previous handlers and unraisable hook are back after it."""
    calls = []

    def in_callback():
        calls.append(1)
        signal.raise_signal(signum)   # handled here, inside the callback

    callback = ctypes.CFUNCTYPE(None)(in_callback)
    hook = sys.unraisablehook
    before = signal.getsignal(signum)
    t0 = time.monotonic()
    with pytest.raises(Interrupted) as caught:
        with terminate_as_interrupt():
            callback()                # C calls it; the exception raised in it is lost
            assert calls == [1]
            while time.monotonic() - t0 < 10.0:
                time.sleep(0.01)      # the signal again, now in Python code
    assert caught.value.signum == signum
    assert time.monotonic() - t0 < 5.0
    assert sys.unraisablehook is hook and signal.getsignal(signum) is before
