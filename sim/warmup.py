"""The main job's kernel warm-ups: numba compiles once, before the stages that need it.

A Dask worker compiles what a later stage needs while the planner runs
(:func:`warm_apart`): numba caches each kernel on disk, so every other process
then loads it instead of compiling it again. Only time depends on it: a stage
compiles whatever is not cached yet.

A part runs its kernels on small inputs the first time (:func:`warm_kernels`).
It then writes the signatures numba compiled for it, the *manifest*, beside numba's
cache, stamped with the sources it was made from. The next time, while the sources
are the same, the part only asks numba for those signatures (a load from the cache:
about a second, where running the simulated machine's part takes 8-10 s of
finite elements and lobes even with every kernel cached). Signatures numba no longer
has (a cache emptied by hand) are compiled from the manifest as the run would have.
The manifest also lists the kernels' cache index files: while the sources are the
same and those files are there, no child is started at all (:func:`cached`; a cache
emptied by hand then means its index files are gone).
"""

from __future__ import annotations

import hashlib
import importlib
import logging
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np

from errpred.pipeline import build_predictor
from nc.atomic import atomic_write
from nc.path import cutter_locations
from orient.contacts import ball_contacts
from orient.dynamics import ModalSystem
from orient.pointwise import point_lobes, point_setup
from orient.scenario import PlanScenario
from orient.stability import sdm_margin, zoa_margin_batch
from orient.workpiece import WorkpieceModel

from .constants import JOB_WARM_BLOCKS, JOB_WARM_POINTS
from .verify import verify_program

__all__ = ["PARTS", "cached", "warm_kernels", "warm_apart", "manifest_path",
           "sources_stamp"]

#: The warm-up's parts, in the order a job needs them.
PARTS = ("margins", "predict", "simulate")
#: The packages whose kernels a manifest lists and whose sources stamp it.
_PACKAGES = ("nc", "errpred", "orient", "sim")

log = logging.getLogger(__name__)


def run_part(scn: PlanScenario, part: str) -> None:
    """Run one part's kernels on small inputs (what :func:`warm_kernels` does without a
    manifest). Parts: ``'margins'`` the planner's zero-order margins (which the main
    process's speed choice needs once a worker has its sample of gains) and the plan's
    time-periodic check (:func:`orient.stability.sdm_margin`), ``'predict'`` the error
    prediction's (``JOB_WARM_BLOCKS`` blocks of the CAM program), ``'simulate'`` the
    simulated machine's (``JOB_WARM_POINTS`` cutter locations from the first cut) and
    the point analyses' (lobes by both methods at two speeds)."""
    base = scn.base
    if part == "margins":
        # the one-thread kernel: the job's margins are Dask tasks, the workers the
        # parallelism (the threaded kernel, 2 s more to compile, is not used there)
        P = np.broadcast_to(np.diag([1e6, 1e6, 1e5]), (2, 3, 3)).copy()
        zoa_margin_batch(P, ModalSystem.tool(base.compliance), [9000.0, 10000.0],
                         base.tool.flutes, cap=scn.options.margin_target, parallel=False)
        # the plan's time-periodic check (its main process compiled these: 6 s and
        # the compiler's memory)
        sdm_margin(P[:1].repeat(8, axis=0), ModalSystem.tool(base.compliance), 10000.0,
                   base.tool.flutes)
    elif part == "predict":
        prog = base.read_program()
        build_predictor(base, prog).run(range(min(len(prog), JOB_WARM_BLOCKS)))
    elif part == "simulate":
        # one workpiece model at the first contact for both (its finite elements:
        # each call built its own, the simulation's over the stretch's levels, and
        # the task peaked at 1.17 GB; the kernels' types do not depend on it)
        cam = cutter_locations(base.read_program(), scn.machine())
        contacts = ball_contacts(cam, base.tool.radius_mm, base.stock.load_design())
        first = int(np.flatnonzero(contacts.touching)[0])
        wp = WorkpieceModel(scn.workpiece, contacts.point[first][None])
        setup = point_setup(scn, first, workpiece=wp, contacts=contacts)
        point_lobes(scn, setup, ("zoa", "sdm"), setup.spindle_rpm * np.array([0.9, 1.1]))
        verify_program(scn, points=(setup.index, setup.index + JOB_WARM_POINTS),
                       workpiece=wp)
    else:
        raise ValueError(f"parts: unknown part {part!r} (expected one of {PARTS})")


def sources_stamp() -> str:
    """A digest of the packages' sources (each ``.py`` file's path, size and
    modification time, as numba stamps its own cache) and of Python's and numba's
    versions: a manifest made from other sources is not used. The same in every
    working directory."""
    import numba

    h = hashlib.sha256(f"{sys.version}|{numba.__version__}".encode())
    for name in _PACKAGES:
        # each folder once, resolved: a namespace package's (``errpred``) path lists
        # the folder again where the working directory is the one holding it (and
        # the editable install's path hook), so a job started from another folder
        # than the last one ran the simulated machine's part again (9-15 s)
        roots = {Path(p).resolve() for p in importlib.import_module(name).__path__
                 if Path(p).is_dir()}
        for root in sorted(roots):
            for path in sorted(root.rglob("*.py")):
                st = path.stat()
                h.update(f"{path}|{st.st_size}|{st.st_mtime_ns}".encode())
    return h.hexdigest()


def manifest_path(part: str) -> Path:
    """Where the part's manifest lives: numba's cache folder (``NUMBA_CACHE_DIR``) if
    one is set, otherwise the ``__pycache__`` beside this module, where numba caches
    ``sim``'s own kernels."""
    import numba

    folder = numba.config.CACHE_DIR or str(Path(__file__).parent / "__pycache__")
    return Path(folder) / f"job-warm-{part}.manifest"


def _index_files(entries: list[tuple[str, str, list]]) -> list[str] | None:
    """The numba cache index file (``.nbi``) of each kernel of a manifest's ``entries``,
    or None where numba does not say where one is (the check that uses them is then
    not made)."""
    out = []
    for module, attr, _sigs in entries:
        disp = getattr(sys.modules.get(module), attr, None)
        path = getattr(getattr(getattr(disp, "_cache", None), "_cache_file", None),
                       "_index_path", None)
        if not isinstance(path, str):
            return None
        out.append(path)
    return out


def _compiled_signatures() -> list[tuple[str, str, list]]:
    """``(module, name, signatures)`` of every kernel of the packages called from Python
    in this process (a kernel's callees come with it: numba links them into its code)."""
    from numba.core.registry import CPUDispatcher

    out = []
    for name, mod in list(sys.modules.items()):
        if name.split(".")[0] not in _PACKAGES or mod is None:
            continue
        for attr, obj in list(vars(mod).items()):
            if (isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == name
                    and obj.signatures):
                out.append((name, attr, list(obj.signatures)))
    return out


def _read_manifest(path: Path) -> tuple[str, list, list[str] | None]:
    """``(stamp, entries, index files)`` of a manifest (index files None in one of the
    former format, which has none); raises where there is none or it cannot be read."""
    with open(path, "rb") as fh:
        made, entries, *files = pickle.load(fh)
    return made, entries, (files[0] if files else None)


def _from_manifest(path: Path, stamp: str) -> bool:
    """Ask numba for the manifest's signatures; False where there is no manifest of
    these sources (or it cannot be read, or a signature no longer compiles: the part
    then runs)."""
    try:
        made, entries, _files = _read_manifest(path)
    except FileNotFoundError:
        return False
    except Exception as exc:                    # noqa: BLE001 -- only time depends on it
        log.warning("%s: unreadable warm-up manifest (%s); running the part", path, exc)
        return False
    if made != stamp:
        return False
    try:
        for module, attr, sigs in entries:
            disp = getattr(importlib.import_module(module), attr)
            for sig in sigs:
                disp.compile(sig)
    except Exception as exc:                    # noqa: BLE001
        log.warning("%s: %s; running the part", path, exc)
        return False
    return True


def cached(parts: tuple[str, ...], stamp: str | None = None) -> bool:
    """Whether every part's manifest is of these sources and lists numba cache index
    files that all exist: then the warm-up has nothing to do (each kernel is loaded
    from the cache where it is first called) and :func:`warm_apart` starts no child
    (a Python that imports the packages to find that out: 3-5 s of a core, and the
    worker waiting for it, in the job). False where unsure: the child then checks.
    Only the index files are looked at, not each signature in them: a cache whose
    data files were deleted by hand, its index kept, is compiled again by the stage
    that needs it (in a worker: time and the compiler's memory, not answers)."""
    stamp = stamp or sources_stamp()
    for part in parts:
        try:
            made, _entries, files = _read_manifest(manifest_path(part))
            if made != stamp or files is None or not all(os.path.isfile(f) for f in files):
                return False
        except Exception:                       # noqa: BLE001 -- only time depends on it
            return False
    return True


def warm_kernels(scn: PlanScenario, parts: tuple[str, ...]) -> None:
    """Have numba compile (and cache on disk for every process) the kernels of ``parts``
    (:data:`PARTS`): from the part's manifest where one of these sources exists,
    otherwise by running the part (:func:`run_part`) and writing its manifest. Only
    time depends on it."""
    unknown = [p for p in parts if p not in PARTS]
    if unknown:
        raise ValueError(f"parts: unknown part {unknown[0]!r} (expected one of {PARTS})")
    stamp = sources_stamp()
    for part in parts:
        path = manifest_path(part)
        if _from_manifest(path, stamp):
            if not cached((part,), stamp) and _index_files(_compiled_signatures()):
                _write_manifest(path, stamp)    # one without its index files: with them
            continue
        run_part(scn, part)
        _write_manifest(path, stamp)


def _write_manifest(path: Path, stamp: str) -> None:
    """Every kernel this process called so far, not only the part's (a later part's
    manifest holds an earlier one's too: cheap to load; complete on its own), with
    their cache index files."""
    entries = _compiled_signatures()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_write(path, "wb") as fh:
            pickle.dump((stamp, entries, _index_files(entries)), fh)
    except OSError as exc:      # a read-only cache: the part runs every time
        log.info("%s: warm-up manifest not written (%s)", path, exc)


def warm_apart(scn: PlanScenario, parts: tuple[str, ...]) -> int:
    """:func:`warm_kernels` in a child process (this interpreter, this process's
    ``sys.path``), waited for: numba's compiler keeps the memory it took (about 290 MB
    for the margins' and the prediction's kernels), so the process that compiles is one
    that ends, not a worker that goes on to plan, predict or verify. Returns the child's
    exit status (a failure only costs time: a later stage compiles what is missing;
    its last line of error output is logged). No child where the kernels are cached
    (:func:`cached`; an unknown part has no manifest, so the child reports it)."""
    if cached(parts):
        return 0
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    code = ("import pickle, sys; from sim.warmup import warm_kernels; "
            "warm_kernels(*pickle.load(sys.stdin.buffer))")
    done = subprocess.run([sys.executable, "-c", code], input=pickle.dumps((scn, parts)),
                          env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          check=False)
    if done.returncode:
        lines = done.stderr.decode(errors="replace").strip().splitlines()
        log.warning("warming up %s in a child process failed (exit %d): %s",
                    ", ".join(parts), done.returncode, lines[-1] if lines else "no output")
    return done.returncode
