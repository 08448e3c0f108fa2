"""The main job on the bundled default (issue 6: under 5 minutes on 2 cores).

Runs ``python -m orient plan`` (the README's main command after installation) in a
child process with an empty numba cache, as on a fresh machine, and prints its wall
time, the job's stages (``report.json``'s ``seconds``), the peak memory of its
largest process and the checks. With ``--warm`` the cache of a first run is kept
and the job runs a second time (the kernels compiled).

Usage: python benchmarks/bench_job.py [--warm]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _run(out: Path, cache: Path) -> float:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "orient", "plan", "--out", str(out)], env=env,
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--warm", action="store_true", help="also a second run, kernels cached")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "numba-cache"
        runs = [("fresh numba cache", Path(tmp) / "cold")]
        if args.warm:
            runs.append(("kernels compiled", Path(tmp) / "warm"))
        for name, out in runs:
            wall = _run(out, cache)
            rep = json.loads((out / "report.json").read_text())
            sec = rep["seconds"]
            stages = ", ".join(f"{k} {v:.0f} s" for k, v in sec.items() if k != "total")
            print(f"{name}: {wall:.0f} s wall (job {sec['total']:.0f} s: {stages})")
            print("  checks: " + ", ".join(f"{k} {'yes' if v else 'NO'}"
                                           for k, v in rep["checks"].items()))
        peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        print(f"peak memory of the largest process: {peak_mb:.0f} MB; {os.cpu_count()} CPUs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
