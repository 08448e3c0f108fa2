"""Timings of orient's planner (issue 4) on the bundled thin-wall scenario.

Targets: margin of one posture <= 1 ms; a 10,000-point path over a 15 x 15
lead/tilt grid <= 60 s on both cores; lobes over 200 spindle speeds by the
time-periodic method, time reported. Prints:

1. the margin of one posture at a thin-wall cutter location (tool modes plus
   the wall's modes at the contact): ``process_gain_batch`` on that one
   posture plus ``zoa_margin`` (and ``zoa_margin_batch`` on one posture, as
   the planner calls it), median over many repeats after warm-up; and the
   per-posture cost inside the batch path (gain over numba's threads, ZOA
   batch per cutter location, as :func:`orient.plan._margins` does) on a
   sample of the bundled path's cutter locations;
2. :func:`orient.plan.plan` on a path of about 10,000 cutting points: the
   thin-wall CAM program regenerated (``scripts/make_orient_scenarios.py``
   with a finer step along the passes) in a temporary folder; total wall
   time, the planner's stage times, candidate postures, postures per second,
   the cores; once with the thin wall's finite elements, once rigid (the
   ``[workpiece]`` table removed);
3. stability lobes over 200 spindle speeds at one thin-wall point
   (:func:`orient.pointwise.point_lobes`) by the zero-order method and by the
   time-periodic one (full discretization). The time-periodic lobes of the
   flexible wall take several seconds per speed, so by default only every
   ``200 / --sdm-speeds``-th speed of the grid is computed and the time for
   all 200 is extrapolated (labelled so); ``--sdm-speeds 200`` runs them all;
4. the peak resident memory of the process (``resource`` maxrss).

The machine may be shared: the load average at the start is printed. The
time-periodic margins spend their time in LAPACK's eigenvalues of the
monodromy matrix (scipy, OpenBLAS threads): on a loaded machine a multi-
threaded OpenBLAS can be several times slower than one thread; compare with
``OPENBLAS_NUM_THREADS=1``.

With ``--scenario PATH`` (issue 20: the planner's time per cutter location), only
:func:`orient.plan.plan` on that scenario, ``--plan-repeats`` times in this process
(the first run may compile numba's kernels; it is reported but left out of the
statistics when there are more runs): per run the wall and CPU seconds (this process,
all its threads), the load average before it and the stage times; then the min and
median over the runs, per touching cutter location.

Usage: python benchmarks/bench_plan.py [--points N] [--sdm-speeds N] [--repeats N]
       python benchmarks/bench_plan.py --scenario PATH [--plan-repeats N]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import re
import resource
import shutil
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "scripts"))

from nc.path import cutter_locations
from orient.contacts import ball_contacts
from orient.dynamics import ModalSystem
from orient.gain import process_gain_batch
from orient.geometry import inclination, posture_axis
from orient.cuts import local_cuts
from orient.plan import _reachable, candidate_grid, plan
from orient.pointwise import point_lobes, point_setup
from orient.scenario import bundled_scenario, load_plan_scenario
from orient.stability import zoa_frequency_grid, zoa_margin, zoa_margin_batch
from orient.stability.sdm import _steps
from orient.workpiece import WorkpieceModel

TARGET_ONE_MS = 1.0
TARGET_PATH_S = 60.0
TARGET_PATH_POINTS = 10_000


def _peak_mb() -> float:
    """Peak resident set size of this process [MB] (Linux: ru_maxrss in kB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _median_ms(fn, repeats: int, warmup: int = 20) -> tuple[float, float]:
    for _ in range(warmup):
        fn()
    ts = np.empty(repeats)
    for i in range(repeats):
        t = time.perf_counter()
        fn()
        ts[i] = time.perf_counter() - t
    return 1e3 * float(np.median(ts)), 1e3 * float(np.percentile(ts, 90))


# ---------------------------------------------------------------- 1. one posture
def one_posture(scn, setup, repeats: int) -> None:
    i = setup.index
    tool, coef = scn.base.tool, scn.base.coefficients
    u, n, f = setup.axis, setup.contacts.normal[i], setup.contacts.feed[i]
    system, rpm, z = setup.system, setup.spindle_rpm, tool.flutes
    dirs = system.directions_for_axes(u[None])
    P = process_gain_batch(tool, coef, u, n, f, setup.cut).P
    m1 = zoa_margin(P, system, rpm, z)
    m2 = float(zoa_margin_batch(P[None], system, rpm, z, mode_directions=dirs)[0])
    print(f"point {i}: contact {np.round(setup.contacts.point[i], 2).tolist()} mm, "
          f"CAM posture, {rpm:g} min^-1, {system.n_modes} modes "
          f"({int(np.sum(system.source == 'tool'))} tool, "
          f"{int(np.sum(system.source == 'workpiece'))} wall: "
          f"{', '.join(f'{x:.0f}' for x in system.natural_frequency_rad_s / 2 / math.pi)} Hz), "
          f"{zoa_frequency_grid(system).size} ZOA frequencies; margin {m1:.3f} "
          f"(batch {m2:.3f})")
    g_ms, g90 = _median_ms(lambda: process_gain_batch(tool, coef, u, n, f, setup.cut), repeats)
    z_ms, z90 = _median_ms(lambda: zoa_margin(P, system, rpm, z), repeats)
    b_ms, b90 = _median_ms(lambda: zoa_margin_batch(P[None], system, rpm, z,
                                                    mode_directions=dirs), repeats)

    def both():
        p = process_gain_batch(tool, coef, u, n, f, setup.cut).P
        return zoa_margin(p, system, rpm, z)

    t_ms, t90 = _median_ms(both, repeats)
    print(f"  process_gain_batch (1 posture)   : median {g_ms:.3f} ms (p90 {g90:.3f})")
    print(f"  zoa_margin                       : median {z_ms:.3f} ms (p90 {z90:.3f})")
    print(f"  zoa_margin_batch (1 posture)     : median {b_ms:.3f} ms (p90 {b90:.3f})")
    print(f"  gain + zoa_margin, one posture   : median {t_ms:.3f} ms (p90 {t90:.3f})  "
          f"target <= {TARGET_ONE_MS:g} ms: {'met' if t_ms <= TARGET_ONE_MS else 'NOT met'}"
          f"  [{repeats} repeats]")


def batch_split(scn, sample: int) -> None:
    """Per-posture cost of gain and ZOA inside the batch path (as plan._margins)."""
    base = scn.base
    machine = base.machine
    if isinstance(machine, str):
        from nc.kinematics import get_machine

        machine = get_machine(machine)
    cam = cutter_locations(base.read_program(), machine)
    R = base.tool.radius_mm
    contacts = ball_contacts(cam, R, base.stock.load_design())
    touching = np.flatnonzero(contacts.touching)
    idx = touching[np.linspace(0, len(touching) - 1, min(sample, len(touching))).astype(int)]
    lead, tilt = candidate_grid(scn.options)
    L, T = np.meshgrid(lead, tilt, indexing="ij")
    normal, feed = contacts.normal[idx], contacts.feed[idx]
    axes = posture_axis(normal[:, None, :], feed[:, None, :], L.ravel()[None], T.ravel()[None])
    axes = np.concatenate([axes, cam.axis[idx][:, None, :]], axis=1)
    incl = inclination(axes, normal[:, None, :])
    opt = scn.options
    ok = (incl >= opt.min_inclination_rad - 1e-9) & (incl <= opt.max_inclination_rad + 1e-9)
    ok &= _reachable(machine, contacts.centre[idx][:, None, :] - R * axes, axes)
    ok[:, -1] = True
    rpm = float(np.max(cam.spindle_rpm))
    cuts = local_cuts(scn, contacts, idx, cam, rpm)
    tool_sys = ModalSystem.tool(base.compliance)
    t0 = time.perf_counter()
    wp = WorkpieceModel(scn.workpiece, contacts.point[touching])
    t_fem = time.perf_counter() - t0
    pi, ps = np.nonzero(ok)
    cut_arr = np.empty(len(pi), dtype=object)
    cut_arr[:] = [cuts[i] for i in pi]
    args = (base.tool, base.coefficients, axes[pi, ps], normal[pi], feed[pi], cut_arr)
    process_gain_batch(*(a[:4] if isinstance(a, np.ndarray) else a for a in args),
                       parallel=True)
    t0 = time.perf_counter()
    gains = process_gain_batch(*args, parallel=True)
    t_gain = time.perf_counter() - t0
    P = np.zeros(ok.shape + (3, 3))
    P[pi, ps] = gains.P
    t_sys = t_zoa = 0.0
    modes = []
    for r in range(len(idx)):
        sel = np.flatnonzero(ok[r])
        t0 = time.perf_counter()
        system = wp.system_at(tool_sys, contacts.point[idx[r]])
        dirs = system.directions_for_axes(axes[r, sel])
        t1 = time.perf_counter()
        zoa_margin_batch(P[r, sel], system, rpm, base.tool.flutes, mode_directions=dirs)
        t2 = time.perf_counter()
        t_sys += t1 - t0
        t_zoa += t2 - t1
        modes.append(system.n_modes)
    n = len(pi)
    print(f"batch path on {len(idx)} cutter locations of the bundled path x {axes.shape[1]} "
          f"postures ({n} feasible: inclination, reach; {min(modes)}-{max(modes)} modes); "
          f"wall FEM ({len(wp.levels)} levels) {t_fem:.2f} s, not included:")
    print(f"  process gain (all cores)         : {1e6 * t_gain / n:7.1f} us/posture "
          f"({n / t_gain:,.0f} postures/s)")
    print(f"  ZOA margin batch (all cores)     : {1e6 * t_zoa / n:7.1f} us/posture "
          f"({n / t_zoa:,.0f} postures/s)")
    print(f"  system at the point + directions : {1e6 * t_sys / n:7.1f} us/posture "
          f"({1e3 * t_sys / len(idx):.2f} ms per cutter location)")
    tot = t_gain + t_zoa + t_sys
    print(f"  margin per posture in the batch  : {1e6 * tot / n:7.1f} us/posture "
          f"({n / tot:,.0f} postures/s)")
    print(f"  peak RSS so far {_peak_mb():.0f} MB")


# ---------------------------------------------------------------- 2. long path
def _strip_workpiece(src: str, dst: str) -> None:
    """Copy the scenario file ``src`` to ``dst`` without its [workpiece] tables (rigid)."""
    with open(src, encoding="utf-8") as fh:
        lines = fh.read().splitlines(keepends=True)
    out, skip = [], False
    for line in lines:
        m = re.match(r"\s*\[\[?\s*([A-Za-z0-9_.\-]+)\s*\]\]?", line)
        if m:
            skip = m.group(1).split(".")[0] == "workpiece"
        if not skip:
            out.append(line)
    with open(dst, "w", encoding="utf-8") as fh:
        fh.write("".join(out))


def make_long_path(tmp: str, points: int) -> tuple[str, str, dict]:
    """Thin-wall scenario copies with about ``points`` cutting points: (flexible, rigid)."""
    import make_orient_scenarios as M

    rib = M.THIN_WALL
    passes = len(rib.pass_heights())
    # cutting (touching) points have their contact on the wall: x in [0, length]
    per_pass = max(2, round(points / passes))
    rib = dataclasses.replace(rib, step=rib.length / (per_pass - 1))
    t0 = time.perf_counter()
    info = M.write_rib(os.path.join(tmp, "thin-wall"), rib, design_title="thin-wall design",
                       stock_title="thin-wall stock", source="thin-wall CAM default, "
                       f"{rib.step:.3f} mm steps")
    info["seconds"] = time.perf_counter() - t0
    info["step_mm"] = rib.step
    folder = os.path.join(tmp, "thin-wall")
    flex = os.path.join(folder, "scenario.toml")
    shutil.copyfile(bundled_scenario("thin-wall"), flex)
    rigid = os.path.join(folder, "scenario-rigid.toml")
    _strip_workpiece(flex, rigid)
    return flex, rigid, info


def run_plan(label: str, path: str) -> dict:
    scn = load_plan_scenario(path)
    t0 = time.perf_counter()
    res = plan(scn)
    wall = time.perf_counter() - t0
    st = res.stats
    sec = st["seconds"]
    t = st["touching"]
    evaluated = int(np.sum(res.grid_feasible)) + st["interference_dropped"] + t   # + CAM's
    print(f"{label}: {st['points']:,} points, {t:,} cutting, {st['postures']:,} candidate "
          f"postures ({evaluated:,} feasible and evaluated); workpiece "
          f"{scn.workpiece.kind}")
    print(f"  total {wall:.1f} s wall -> target <= {TARGET_PATH_S:g} s: "
          f"{'met' if wall <= TARGET_PATH_S else 'NOT met'}"
          f" (x{wall / TARGET_PATH_S:.2f} of the target)")
    print("  stages: " + ", ".join(f"{k} {v:.1f} s" for k, v in sec.items() if k != "total"))
    print(f"  margins stage: {evaluated / sec['margins']:,.0f} postures/s "
          f"({1e6 * sec['margins'] / evaluated:.1f} us/posture); whole plan "
          f"{evaluated / wall:,.0f} postures/s")
    if res.sdm_checks:
        print(f"  finish: {len(res.sdm_checks)} time-periodic checks (SDM vs ZOA margin: "
              + ", ".join(f"{c['sdm_margin']:.2f}/{c['zoa_margin']:.2f}"
                          for c in res.sdm_checks) + ")")
    if st.get("wall_first_frequencies_hz"):
        print("  wall first frequency per level: "
              + ", ".join(f"{f:.0f}" for f in st["wall_first_frequencies_hz"]) + " Hz")
    print(f"  interference: {st['interference_dropped']} postures dropped, "
          f"{st['planned_collisions']} planned collisions; peak RSS so far {_peak_mb():.0f} MB")
    return {"wall": wall, **sec}


def per_location(path: str, repeats: int) -> None:
    """``plan`` on one scenario ``repeats`` times: wall and CPU per touching location."""
    scn = load_plan_scenario(path)
    rows = []
    for k in range(repeats):
        load = os.getloadavg()[0]
        t0, c0 = time.perf_counter(), time.process_time()
        res = plan(scn)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        t = res.stats["touching"]
        sec = res.stats["seconds"]
        print(f"run {k + 1}: {wall:.1f} s wall, {cpu:.1f} s CPU, load {load:.1f} before; "
              f"{t} touching of {res.stats['points']} points; "
              + ", ".join(f"{a} {b:.1f}" for a, b in sec.items() if a != "total"))
        rows.append((wall / t * 1e3, cpu / t * 1e3))
    use = np.array(rows[1:] if len(rows) > 1 else rows)
    print(f"per touching location over {len(use)} run(s)"
          f"{' (the first left out)' if len(rows) > 1 else ''}: wall min "
          f"{use[:, 0].min():.1f} ms, median {np.median(use[:, 0]):.1f} ms; CPU min "
          f"{use[:, 1].min():.1f} ms, median {np.median(use[:, 1]):.1f} ms")


# ---------------------------------------------------------------- 3. lobes
def lobes(scn, setup, speeds: int, sdm_speeds: int, label: str) -> None:
    rpm = np.linspace(5000.0, 15000.0, speeds)
    t0 = time.perf_counter()
    (zl,), _ = point_lobes(scn, setup, methods=("zoa",), rpm=rpm)
    t_zoa = time.perf_counter() - t0
    print(f"{label}: ZOA lobes over {speeds} speeds: {t_zoa:.3f} s "
          f"({1e3 * t_zoa / speeds:.2f} ms/speed); min margin {zl.minimum[1]:.3f} "
          f"at {zl.minimum[0]:.0f} min^-1")
    k = max(1, min(sdm_speeds, speeds))
    sub = rpm[np.unique(np.linspace(0, speeds - 1, k).round().astype(int))]
    tau = 60.0 / (sub * scn.base.tool.flutes)
    steps = [_steps(None, 90, setup.system, float(x)) for x in tau]
    m = setup.system.n_modes
    t0 = time.perf_counter()
    (sl,), _ = point_lobes(scn, setup, methods=("sdm",), rpm=sub)
    t_sdm = time.perf_counter() - t0
    per = t_sdm / len(sub)
    whole = "" if len(sub) == speeds else (f" -> {speeds} speeds ~ {per * speeds:.0f} s "
                                           f"(extrapolated)")
    print(f"{label}: SDM lobes on {len(sub)} of the {speeds} speeds: {t_sdm:.1f} s "
          f"({per:.2f} s/speed){whole}; {min(steps)}-{max(steps)} steps per tooth period, "
          f"{m} modes -> monodromy {(min(steps) + 2) * m}-{(max(steps) + 2) * m} square; "
          f"min margin {np.min(sl.margin):.3f} (ZOA on the same speeds "
          f"{np.min(np.interp(sub, rpm, zl.margin)):.3f})")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=TARGET_PATH_POINTS,
                    help="cutting points of the long path")
    ap.add_argument("--repeats", type=int, default=1000, help="repeats of the one-posture runs")
    ap.add_argument("--sample", type=int, default=150,
                    help="cutter locations of the batch-path split")
    ap.add_argument("--speeds", type=int, default=200)
    ap.add_argument("--sdm-speeds", type=int, default=10,
                    help="speeds of the grid computed by the time-periodic method "
                         "(evenly spread; the rest extrapolated)")
    ap.add_argument("--skip-rigid", action="store_true")
    ap.add_argument("--scenario", help="only plan this scenario, --plan-repeats times")
    ap.add_argument("--plan-repeats", type=int, default=3)
    args = ap.parse_args(argv)
    import numba

    if args.scenario:
        print(f"{os.cpu_count()} CPUs, numba threads {numba.get_num_threads()}; load average "
              f"{', '.join(f'{x:.2f}' for x in os.getloadavg())}")
        per_location(args.scenario, args.plan_repeats)
        return 0

    t_start = time.perf_counter()
    blas = os.environ.get("OPENBLAS_NUM_THREADS", "unset (one per CPU)")
    print(f"{os.cpu_count()} CPUs, numba threads {numba.get_num_threads()}, "
          f"OPENBLAS_NUM_THREADS {blas}; load average at start "
          f"{', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    scn = load_plan_scenario(bundled_scenario("thin-wall"))
    t0 = time.perf_counter()
    setup = point_setup(scn)
    print(f"point setup (path, contacts, wall FEM at one level): "
          f"{time.perf_counter() - t0:.2f} s")

    print("\n== 1. margin of one posture")
    one_posture(scn, setup, args.repeats)
    batch_split(scn, args.sample)

    print(f"\n== 2. a path of ~{args.points:,} cutting points, "
          f"{scn.options.grid[0]} x {scn.options.grid[1]} lead/tilt grid")
    with tempfile.TemporaryDirectory(prefix="bench_plan_") as tmp:
        flex, rigid, info = make_long_path(tmp, args.points)
        print(f"CAM program regenerated with STEP {info['step_mm']:.4f} mm: "
              f"{info['points']:,} points in {info['passes']} passes, "
              f"{info['program_lines']:,} lines, {info['seconds']:.1f} s")
        run_plan("thin wall (FEM)", flex)
        if not args.skip_rigid:
            run_plan("rigid workpiece", rigid)

    print(f"\n== 3. lobes at point {setup.index} over {args.speeds} speeds "
          f"(5000-15000 min^-1)")
    lobes(scn, setup, args.speeds, args.sdm_speeds, "thin wall")
    with tempfile.TemporaryDirectory(prefix="bench_plan_") as tmp:
        src = bundled_scenario("thin-wall")
        for name in os.listdir(src.parent):
            shutil.copy(src.parent / name, tmp)
        path = os.path.join(tmp, "scenario-rigid.toml")
        _strip_workpiece(src, path)
        scn_r = load_plan_scenario(path)
        setup_r = point_setup(scn_r, setup.index)
        lobes(scn_r, setup_r, args.speeds, args.speeds, "rigid    ")

    print(f"\n== 4. peak resident memory {_peak_mb():.0f} MB; benchmark ran "
          f"{time.perf_counter() - t_start:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
