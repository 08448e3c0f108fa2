"""The main job on the bundled default (issue 17: <= 60 s warm, <= 120 s fresh, <= 1 GB a process).

Runs ``python -m sim job`` (the README's main command after installation) in a
child process with an empty numba cache, as on a fresh machine, and prints:

* the wall time and the job's stages (``report.json``'s ``seconds``);
* the peak resident memory (RSS) of every process of the run: the job's main process
  and each process it starts (the local Dask cluster's worker processes; its
  scheduler and nannies run in the main process), found by sampling the process
  tree every ``--sample-s`` seconds (psutil), with the time of the peak since the
  start (the stages follow each other in the order printed, after the start-up);
  a peak shorter than the sampling period can be missed, so the largest peak of
  any process is also read exactly from the kernel (``ru_maxrss`` of the waited-for
  children);
* the checks.

With ``--warm`` the cache of the first run is kept and the job runs a second time
(the kernels compiled). Machine load changes the times: the load average at the
start is printed; repeat with ``--repeats`` for the spread.

``--scenario`` runs another scenario (a file or a bundled name, e.g. ``mold-core``).

Usage: python benchmarks/bench_job.py [--scenario S] [--warm] [--repeats N] [--sample-s S]
[--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil

#: Seconds between two samples of the process tree's memory (default) [s].
SAMPLE_S = 0.2


def _label(p: psutil.Process, root_pid: int) -> str | None:
    """A readable name for a process of the job's tree (None: not known yet)."""
    if p.pid == root_pid:
        return "main"
    try:
        cmd = " ".join(p.cmdline())
    except (psutil.NoSuchProcess, psutil.AccessDenied):
        return None
    if "resource_tracker" in cmd:
        return "resource tracker"
    if "spawn_main" in cmd or "forkserver" in cmd:
        return "worker"                 # the local Dask cluster's worker processes
    return cmd[:60] or None


def _run(out: Path, cache: Path, sample_s: float, scenario: str | None = None
         ) -> tuple[float, dict[int, dict]]:
    """Run the job; wall time [s] and per process ``pid -> {label, peak RSS [bytes],
    time of the peak [s since the start]}``."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "sim", "job", *([scenario] if scenario
                                                                     else []), "--out", str(out)],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True)
    root = psutil.Process(proc.pid)
    peaks: dict[int, dict] = {}
    while proc.poll() is None:
        try:
            tree = [root, *root.children(recursive=True)]
        except psutil.NoSuchProcess:
            break
        now = time.perf_counter() - t0
        for p in tree:
            try:
                rss = p.memory_info().rss
            except (psutil.NoSuchProcess, psutil.AccessDenied):
                continue
            entry = peaks.setdefault(p.pid, {"label": None, "rss": 0, "at_s": 0.0})
            if entry["label"] is None:
                entry["label"] = _label(p, proc.pid)
            if rss > entry["rss"]:
                entry.update(rss=rss, at_s=now)
        time.sleep(sample_s)
    err = proc.stderr.read()
    proc.wait()
    wall = time.perf_counter() - t0
    if proc.returncode not in (0, 1):       # 1: a check failed, the report is written
        sys.exit(f"the job ended with status {proc.returncode}:\n{err[-2000:]}")
    return wall, peaks


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", help="a scenario file or a bundled scenario's name "
                                       "(default: the bundled default)")
    ap.add_argument("--warm", action="store_true", help="also runs with the kernels cached")
    ap.add_argument("--repeats", type=int, default=1, help="warm runs (with --warm)")
    ap.add_argument("--sample-s", type=float, default=SAMPLE_S,
                    help=f"memory sampling period [s] (default {SAMPLE_S})")
    ap.add_argument("--keep", metavar="DIR", help="keep the runs' output folders here")
    args = ap.parse_args(argv)
    print(f"{os.cpu_count()} CPUs, load average at start "
          + " ".join(f"{x:.2f}" for x in os.getloadavg()))
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "numba-cache"
        runs = [("fresh numba cache", Path(tmp) / "fresh")]
        if args.warm:
            runs += [(f"kernels compiled (run {i + 1})", Path(tmp) / f"warm{i + 1}")
                     for i in range(max(1, args.repeats))]
        for name, out in runs:
            wall, peaks = _run(out, cache, args.sample_s, args.scenario)
            rep = json.loads((out / "report.json").read_text())
            sec = rep["seconds"]
            stages = ", ".join(f"{k} {v:.1f} s" for k, v in sec.items() if k != "total")
            print(f"{name}: {wall:.1f} s wall (job {sec['total']:.1f} s: {stages}; "
                  f"start-up and report {wall - sec['total']:.1f} s)")
            rows = sorted(peaks.values(), key=lambda e: (e["label"] != "main", -e["rss"]))
            print("  peak RSS per process: " + ", ".join(
                f"{e['label'] or 'process'} {e['rss'] / 2**20:.0f} MB (at {e['at_s']:.0f} s)"
                for e in rows))
            print("  checks: " + ", ".join(f"{k} {'yes' if v else 'NO'}"
                                           for k, v in rep["checks"].items()))
            if args.keep:
                dest = Path(args.keep) / out.name
                shutil.rmtree(dest, ignore_errors=True)
                shutil.copytree(out, dest)
        big_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        print(f"largest process of all runs (the kernel's ru_maxrss, exact): {big_mb:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
