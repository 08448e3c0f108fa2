"""The main job's command line, ``python -m sim job [SCENARIO]`` (:mod:`sim.cli` adds
these arguments and calls :func:`run`).

Without a scenario the bundled default (orient's thin wall) runs; ``mold-core`` names the
second bundled scenario (a free-form mold core). Everything is
written into one folder (default ``./NAME-job``): the final program
``NAME.nc``, the planned one before correction ``NAME-planned.nc``,
``report.html`` (self-contained) and ``report.json``. The folder is filled
from a staging folder beside it only when the whole run has succeeded, so a
failed run leaves nothing behind; SIGINT and SIGTERM end the run with one line,
exit status 128 + the signal's number and the staging folder removed, and a run
killed outright (SIGKILL) has its staging folder removed by the next run
(:mod:`sim.staging`). Bad input ends in one line naming the file
and the key, exit status 2. A run whose checks do not all hold writes its report
and its programs renamed ``NAME.NOT-FOR-CUTTING.nc`` (with a comment at their top
saying which checks failed) and ends with one line and exit status 1; so does a
plan with points that have no feasible posture (unless ``--allow-fallback``) and a
rapid move into material or a cut deeper than the flutes, which write nothing.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from nc.atomic import atomic_write
from nc.command import Refused

from .constants import JOB_BLAS_THREADS
from .staging import Interrupted, commit, staging_folder, terminate_as_interrupt

__all__ = ["NOT_FOR_CUTTING_SUFFIX", "add_job_arguments", "run"]


def add_job_arguments(a: argparse.ArgumentParser) -> None:
    """The options of ``python -m sim job``."""
    a.add_argument("scenario", nargs="?", help="planning scenario TOML, or the name of a "
                                               "bundled one (thin-wall, mold-core; default: "
                                               "the thin wall)")
    a.add_argument("--out", metavar="DIR", help="folder for the program and the report "
                                                "(default: ./NAME-job)")
    a.add_argument("--allow-fallback", action="store_true",
                   help="where no posture is feasible keep the CAM posture (flagged) instead "
                        "of ending the job with status 1")
    g = a.add_mutually_exclusive_group()
    g.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the parallel stages on an existing Dask scheduler")
    g.add_argument("--dask", type=int, metavar="N", default=None,
                   help="local Dask cluster of N workers (default: one per core)")
    g.add_argument("--no-dask", action="store_true", help="everything in this process")


def _progress(con):
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )

    # off a terminal rich would draw its bars once, at the end: the stage log says it there
    return Progress(TextColumn("{task.description:<26}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), console=con, transient=False,
                    disable=not con.is_terminal)


class _StageLog:
    """Where stderr is not a terminal (a log file, a CI job) rich draws no bar until the
    end: one line per stage instead, at every tenth of it and when it is done, with the
    run's elapsed time, so a long run's log says where it is. Not when a stage starts:
    bad input found as a stage starts stays the one line that says so."""

    def __init__(self, con, t0: float) -> None:
        self.on = not con.is_terminal
        self.t0 = t0
        self.last: dict[str, int] = {}

    def __call__(self, name: str, done: int, total: int) -> None:
        if not self.on or done <= 0:
            return
        tenth = 10 if total <= 0 or done >= total else (10 * done) // total
        if self.last.get(name, 0) >= tenth:
            return
        self.last[name] = tenth
        print(f"[{time.perf_counter() - self.t0:7.1f} s] {name}: {done}/{total}",
              file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    """Run the job for parsed arguments (see :func:`add_job_arguments`)."""
    from rich.console import Console

    from errpred.cluster import dask_client
    from orient.scenario import load_plan_scenario

    from threadpoolctl import threadpool_limits

    from .job import run_job
    from .job_report import write_job_report

    scn = load_plan_scenario(_scenario_path(args.scenario))
    out = Path(args.out if args.out else f"{scn.name}-job").resolve()
    if not out.parent.is_dir():
        raise FileNotFoundError(f"{out}: directory {out.parent} does not exist")
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"{out}: exists and is not a directory")
    workers = 0 if args.no_dask else (args.dask if args.dask is not None
                                      else max(1, len(os.sched_getaffinity(0))))
    con = Console(file=sys.stderr, width=None if sys.stderr.isatty() else 110)
    t0 = time.perf_counter()
    try:
        with terminate_as_interrupt(), staging_folder(out) as stage:
            # this process's BLAS on one thread, as Dask's workers (JOB_BLAS_THREADS: beside
            # a local cluster's workers its spinning threads made LAPACK 100 times slower;
            # and OpenBLAS's results depend on its thread count: one process and a cluster
            # alike)
            with _progress(con) as bar, dask_client(args.scheduler, workers) as client, \
                    threadpool_limits(limits=JOB_BLAS_THREADS, user_api="blas"):
                tasks: dict[str, int] = {}

                log = _StageLog(con, t0)

                def progress(name: str, done: int, total: int) -> None:
                    if name not in tasks:
                        tasks[name] = bar.add_task(name, total=total)
                    bar.update(tasks[name], completed=done, total=total)
                    log(name, done, total)

                res = run_job(scn, stage, client=client, progress=progress,
                              allow_fallback=True if getattr(args, "allow_fallback", False)
                              else None)
                rep = write_job_report(res, stage)
                failed = [k for k, v in rep["checks"].items() if not v]
                if failed:
                    _not_for_cutting(stage, (res.final_path, res.planned_path), failed)
            commit(stage, out)
    except Interrupted as exc:
        print(f"error: {scn.name}: {exc}; nothing written to {out}", file=sys.stderr)
        return 128 + exc.signum
    sim = rep["simulation"]
    p = rep["plan"]
    print(f"{scn.name}: planned {p['cutting_points']} cutting points at {p['spindle_rpm']:.0f} "
          f"rev/min; margin min {p['cam_margin_min']} -> {p['margin_min']}")
    print(f"predicted error RMS {rep['correction']['predicted_rms_um'][0]} -> "
          f"{rep['correction']['predicted_rms_um'][rep['correction']['best_pass']]} um; "
          f"simulated {sim['planned']['surface_rms_um']} -> "
          f"{sim['corrected']['surface_rms_um']} um (ratio {sim['surface_rms_ratio']})")
    print("checks: " + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in rep["checks"].items()))
    if failed:
        raise Refused(f"{scn.name}: check(s) failed: {', '.join(failed)}; the programs are "
                      f"written as {out}/*{NOT_FOR_CUTTING_SUFFIX} and must not be cut (see "
                      f"{out / 'report.html'})")
    print(f"wrote {out / res.final_path.name}, {out / 'report.html'}, {out / 'report.json'} "
          f"in {time.perf_counter() - t0:.0f} s")
    return 0


def _scenario_path(arg: str | None) -> Path:
    """The scenario file: ``arg``, or the bundled scenario of that name when no such file
    exists (``orient.scenario.BUNDLED``), or the bundled default without one."""
    from orient.scenario import BUNDLED, bundled_scenario

    if not arg:
        return bundled_scenario()
    if arg in BUNDLED and not Path(arg).exists():
        return BUNDLED[arg]
    return Path(arg)


#: What a program of a job whose checks failed is renamed to end with.
NOT_FOR_CUTTING_SUFFIX = ".NOT-FOR-CUTTING.nc"


def _not_for_cutting(folder: Path, programs, failed: list[str]) -> None:
    """Rename the job's programs to ``NAME.NOT-FOR-CUTTING.nc`` and put a comment saying
    so (and which checks failed) at their top (after a leading ``%``)."""
    note = f"(NOT FOR CUTTING: the job's checks failed: {', '.join(failed)})"
    for path in programs:
        path = Path(path)
        lines = path.read_text().splitlines()
        at = 1 if lines and lines[0].strip() == "%" else 0
        lines.insert(at, note)
        target = path.with_name(path.stem + NOT_FOR_CUTTING_SUFFIX)
        with atomic_write(target) as fh:
            fh.write("\n".join(lines) + "\n")
        path.unlink()

