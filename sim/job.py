"""The main job: a CAM program in; a planned, corrected, verified 5-axis program out.

One run, the four packages in order (``docs/architecture.md``, "Data flow"):

1. read the CAM program and the part (the planning scenario);
2. plan lead/tilt per cutter location (:func:`orient.plan.plan`): stability
   margin above 1 where it can be had, interference and axis limits;
3. predict the machining error along the planned 5-axis path (errpred, the
   tilted tool, the workpiece's compliance at each cutting point: a thin wall's
   modes, or none for a rigid part) and correct
   the path, iterated (:func:`errpred.correct_path.compensate_path`);
4. write the 5-axis program for the scenario's machine and dialect
   (:mod:`nc.writer`) and read it back (round trip);
5. verify in the simulated machine (:func:`sim.verify.verify_program`): the
   planned program and the corrected one over their whole length (each run in
   stretches split at air moves, :func:`sim.verify.split_at_air`, on the workers at
   once, each on the one that frees up next, and judged as one run), the CAM program
   over its worst pass; chatter or not, the surface error of each;
6. the stability lobes at representative points (CAM and planned posture).

No reporting here: :mod:`sim.job_report` turns a :class:`JobResult` into the
page and the JSON. The programs are written into a working folder, because the
simulated machine reads its program as a machine would.

With a Dask ``client`` the planner's gains and margins, the error prediction's
geometry stage and the verification runs go to its workers; the result is the
same as in one process (the physics is deterministic).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from errpred.cluster import balanced, restart_compiled_workers
from errpred.constants import FALLBACK_REACH_RADII
from errpred.correct_path import PathCompensation, compensate_path
from errpred.findings import error_findings, findings_line
from errpred.pipeline import build_predictor
from errpred.predict import Prediction
from errpred.repredict import Repredictor
from nc.atomic import atomic_write
from nc.command import Refused
from nc.gcode import parse_program
from nc.path import CutterLocations, cutter_locations
from nc.writer import PostOptions, PostResult, post, round_trip_error
from orient.plan import PlanResult, plan
from orient.pointwise import point_lobes, point_setup
from orient.report import infeasible_summary
from orient.scenario import PlanScenario

from .constants import (
    JOB_CORRECTION_PASSES,
    JOB_LOBE_SPEEDS,
    JOB_SURFACE_RATIO,
    VERIFY_STRETCHES,
)
from .program import PartProgram
from .verify import (Verification, judge, scenario_with_program, simulate_stretch,
                     split_at_air)
from .warmup import warm_apart

__all__ = ["JobResult", "run_job"]

#: ``progress(stage, done, total)``
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True, eq=False)
class JobResult:
    """Everything one run of the main job found.

    Attributes
    ----------
    scenario : PlanScenario
    plan : PlanResult
    compensation : PathCompensation
        The correction passes (predictions before and after).
    planned, final : PostResult
        The program written from the planned path and from the corrected one.
    planned_path, final_path : Path
        Where they were written (the working folder).
    findings : list of dict
        Error-level findings of the planned program's prediction (rapid moves into
        material, cuts deeper than the flutes: :func:`errpred.findings.error_findings`).
    round_trip : tuple (float [mm], float [rad])
        Largest tip and axis difference between the final path and the final program
        read back through nc's reader and the machine.
    collisions : int
        Cutter locations of the final path where shank or holder meet the stock or
        the tool gouges the design (FCL).
    verify_planned, verify_final, verify_cam : Verification
        The simulated machine on the planned program, the corrected one, and the CAM
        program over its worst pass (``cam_points``).
    cam_points : tuple (int, int)
    lobes : list of dict
        Per representative point: ``point``, ``why``, ``cam`` and ``planned`` Lobes,
        the operating point.
    seconds : dict
        Wall time per stage [s].
    stage1_computed : list of int
        Per dense prediction of the correction (the reference first): the blocks whose
        stage 1 was computed (the others' taken from the prediction before,
        :class:`errpred.repredict.Repredictor`).
    """

    scenario: PlanScenario
    plan: PlanResult
    compensation: PathCompensation
    planned: PostResult
    final: PostResult
    planned_path: Path
    final_path: Path
    round_trip: tuple[float, float]
    collisions: int
    findings: list
    verify_planned: Verification
    verify_final: Verification
    verify_cam: Verification
    cam_points: tuple[int, int]
    lobes: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    stage1_computed: list = field(default_factory=list)

    @property
    def surface_ratio(self) -> float:
        """RMS simulated surface error of the corrected program over the planned one's [-]."""
        return _rms(self.verify_final.surface_um) / max(_rms(self.verify_planned.surface_um),
                                                        1e-12)

    @property
    def checks(self) -> dict[str, bool]:
        """The job's acceptance checks, each True when it holds."""
        idx = self.plan.touching_index
        v = self.compensation.verified
        return {
            "margin_above_1_where_cutting": bool(np.all(self.plan.margin[idx] > 1.0)),
            "no_collisions": self.collisions == 0 and self.plan.infeasible.size == 0,
            "no_program_errors": not self.findings,
            "correction_verified_nowhere_worse": bool(self.compensation.corrected
                                                      and v.comparison is not None
                                                      and v.comparison.ok),
            "round_trip_within_1um": self.round_trip[0] <= 1e-3,
            "simulation_covered_the_program": all(
                v.complete for v in (self.verify_planned, self.verify_final, self.verify_cam)),
            "no_chatter_in_simulation": self.verify_final.sustained_chatter == 0,
            "surface_error_reduced_to_25pct": self.surface_ratio <= JOB_SURFACE_RATIO,
        }


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if np.size(x) else 0.0


def _worst_cam_pass(res: PlanResult) -> tuple[int, int]:
    """The CAM pass (cutter locations from two before its first touch to two after its
    last) holding the lowest CAM-posture margin: where the CAM program chatters most."""
    idx = res.touching_index
    i = int(idx[np.argmin(res.cam_margin[idx])])
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts = np.r_[idx[0], idx[breaks + 1]]
    ends = np.r_[idx[breaks], idx[-1]]
    k = int(np.searchsorted(starts, i, side="right") - 1)
    return max(int(starts[k]) - 2, 0), min(int(ends[k]) + 2, len(res.cl) - 1)


def _lobes(scn: PlanScenario, res: PlanResult) -> list[dict]:
    """Lobes (zero-order) at the lowest-CAM-margin and the lowest-planned-margin points,
    for the CAM posture and for the planned one, at the planned speed. Both at the plan's
    cutter location (its contact: the planner keeps the ball centre), with the plan's
    contacts: the written planned program has more cutter locations than the plan (the
    writer's linearization), so the plan's index does not name the same point there."""
    idx = res.touching_index
    picks = [(int(idx[np.argmin(res.cam_margin[idx])]), "lowest margin of the CAM posture"),
             (int(idx[np.argmin(res.margin[idx])]), "lowest margin of the planned posture")]
    if picks[0][0] == picks[1][0]:
        picks = picks[:1]
    rpm = res.spindle_rpm
    speeds = np.linspace(0.5 * rpm, 1.5 * rpm, JOB_LOBE_SPEEDS)
    out = []
    for i, why in picks:
        cam = point_setup(scn, i, spindle_rpm=rpm, workpiece=res.workpiece,
                          contacts=res.contacts)
        pl = point_setup(scn, i, axis=res.cl.axis[i], spindle_rpm=rpm,
                         workpiece=res.workpiece, contacts=res.contacts)
        lc, op = point_lobes(scn, cam, ("zoa",), speeds)
        lp, _ = point_lobes(scn, pl, ("zoa",), speeds)
        out.append({"point": i, "why": why, "cam": lc[0], "planned": lp[0],
                    "operating_point": op})
    return out


def run_job(scn: PlanScenario, workdir: str | Path, *, client=None,
            progress: Progress | None = None, allow_fallback: bool | None = None
            ) -> JobResult:
    """Plan, correct, write and verify the scenario's CAM program.

    Parameters
    ----------
    scn : PlanScenario
    workdir : path-like
        Existing folder for the written programs (``NAME-planned.nc``, ``NAME.nc``).
    client : dask.distributed.Client, optional
        Run the parallel stages on its workers.
    progress : callable, optional
        ``progress(stage, done, total)``; stages ``plan`` (and the planner's own without
        a client), ``predict k`` (candidate k, blocks), ``write``, ``verify`` (runs),
        ``lobes``.
    allow_fallback : bool, optional
        Keep the CAM posture where no posture is feasible (default: the scenario's
        ``[orient] allow_fallback``); otherwise such points end the job.

    Returns
    -------
    JobResult

    Raises
    ------
    nc.command.Refused
        Points without a feasible posture (unless allowed), or a rapid move into
        material in the planned program: nothing is corrected or written.
    """
    say = progress or (lambda stage, done, total: None)
    work = Path(workdir)
    seconds: dict[str, float] = {}
    t0 = t_start = time.perf_counter()
    # a worker compiles what later stages need (numba caches it on disk for every
    # process): one task that does the prediction's and the planner's parts in turn,
    # behind the planner's (priority), so that the other worker is free for the planner's
    # first task (the speed's sample of gains, which compiles the gain kernel). The
    # prediction's part first: the plan's own tasks compile the margins' kernels where
    # they need them (the worker that did is started again before the prediction), and
    # the prediction waited for this child (margins, then prediction) with a core idle;
    # the other order: a fresh job 125.0-127.6 s instead of 129.7-130.3 s. As three
    # tasks, both workers took a part before the planner had submitted anything, and the
    # sample waited behind them (on a fresh cache: 52 s of compiling, then its own 57 s).
    # The simulation's part is submitted after the plan and waited for before the
    # verification only: run whole, it took 35 s even with the kernels cached (its finite
    # elements, lobes and a few cutter locations), which the prediction waited for (with
    # the kernels cached no child is started: sim/warmup.py)
    warm = [] if client is None else [client.submit(
        warm_apart, scn, ("predict", "margins"), pure=False, priority=-1)]
    warm_sim: list = []

    def lap(name: str) -> None:
        nonlocal t0
        seconds[name] = round(time.perf_counter() - t0, 2)
        t0 = time.perf_counter()

    # 1-2: plan
    say("plan", 0, 1)
    res = plan(scn, progress=lambda stage, d, t: say(f"plan: {stage}", d, t), client=client)
    say("plan", 1, 1)
    allow = scn.options.allow_fallback if allow_fallback is None else allow_fallback
    if res.infeasible.size and not allow:
        raise Refused(f"{scn.path}: {infeasible_summary(res)}; nothing written (allow the "
                      "CAM posture there with --allow-fallback or [orient] allow_fallback)")
    machine = res.machine
    base = scn.base
    wp = res.workpiece
    lap("plan")
    opts = PostOptions(dialect=scn.options.dialect, spindle_rpm=res.spindle_rpm,
                       source=f"firstcut job on {scn.name}: planned lead/tilt, error corrected")

    # 3: predict and correct, iterated
    stock = base.stock.load()
    state = {"pass": 0}
    dense = base.resolution.dense()
    found: list = []
    # a fallback candidate differs from the one before it only near the worse points:
    # stage 1 is taken from that prediction wherever it cannot have changed
    repro = Repredictor()

    def predict(cl: CutterLocations) -> Prediction:
        text = post(cl, machine, opts).text
        prog = parse_program(text, file=f"<{scn.name}: correction pass {state['pass']}>")
        # the error's sensitivity to a move (a second engagement a point) only where a
        # fit reads it: the plan's prediction and the candidates of a pass another may
        # follow (the last pass's are compared, not fitted; its fallbacks refit the
        # field of the candidate before: the plan's, or an accepted one's)
        k = state["pass"]
        pred = build_predictor(base, prog, dense, stock, workpiece=wp.modes_at,
                               machine=machine, sensitivity=k == 0 or k < passes)
        blocks = list(range(len(prog)))
        stage = f"predict {state['pass']}"
        out = repro.run(pred, blocks, client=client,
                        progress=lambda d: say(stage, d, len(blocks)) if d % 25 == 0 else None)
        say(stage, len(blocks), len(blocks))
        if state["pass"] == 0:
            found.extend(error_findings(out))
            if found:
                raise Refused(f"{scn.path}: the planned program: {findings_line(found)}")
        return out

    def on_pass(k: int, _cl) -> None:
        state["pass"] = k

    if warm:        # the prediction's kernels: compiled (and cached) before it starts
        from distributed import wait

        # a worker that compiled the planner's kernels (the warm-up child had not cached
        # them yet) keeps the compiler's memory: started again, while it is idle (before
        # the next task: the scheduler may not yet list one just submitted; the worker
        # that waits for the warm-up child is busy, and compiles nothing itself)
        restart_compiled_workers(client)
        # the simulation's part beside the prediction's, not beside the prediction (on a
        # fresh cache its 30 s of compiling slowed the prediction by 9-16 s)
        warm_sim.append(client.submit(warm_apart, scn, ("simulate",), pure=False,
                                      priority=-1))
        wait(warm)
        del warm
    # at most JOB_CORRECTION_PASSES, fewer where the scenario's [correction] says so (a
    # long program: each pass costs a dense prediction or more); one pass applies its
    # fit whole, as errpred's single correction does (the fallback guards it). Iterating
    # stops once a verified candidate's dense RMS is within the verification's tolerance
    # (the error the comparison does not tell from the prediction's own): on the bundled
    # default the third pass took two of the seven dense predictions to lower the RMS from
    # 0.692 to 0.589 um (largest |E| 14.5 -> 12.4 um); without it the correction's stage
    # takes 60 s instead of 78 s (kernels cached) and the simulated ratio is 23.5 %
    passes = min(JOB_CORRECTION_PASSES, base.correction.max_iterations)
    try:
        comp = compensate_path(res.cl, predict, iterate=passes > 1,
                               relaxation=base.correction.relaxation,
                               tolerance_mm=base.correction.tolerance_um * 1e-3,
                               max_iterations=passes, progress=on_pass,
                               tolerance_um=base.correction.verify_tolerance_um,
                               spacing_mm=dense.point_spacing_mm,
                               reach_mm=FALLBACK_REACH_RADII * base.tool.radius_mm,
                               enough_rms_um=base.correction.verify_tolerance_um,
                               verify_walls=base.correction.verify_walls)
    finally:
        repro.close()
    lap("predict_and_correct")

    # 4: write both programs and read the final one back
    say("write", 0, 1)
    planned_post = post(res.cl, machine, opts)
    final_post = post(comp.cl, machine, opts)
    planned_path = work / f"{scn.name}-planned.nc"
    final_path = work / f"{scn.name}.nc"
    for path, p in ((planned_path, planned_post), (final_path, final_post)):
        with atomic_write(path) as fh:
            fh.write(p.text)
    back = cutter_locations(parse_program(final_post.text, file=str(final_path)), machine)
    rt = round_trip_error(final_post, back)
    chk = scn.interference_checker()
    feed = ~comp.cl.rapid
    r = chk.check(comp.cl.tip[feed], comp.cl.axis[feed])
    collisions = int(np.count_nonzero(r.collides | r.gouges))
    say("write", 1, 1)
    lap("write")

    # 5: verify in the simulated machine: each whole program's run in stretches split at
    # air moves (VERIFY_STRETCHES), the corrected program's first (the longest run), run
    # apart and judged as one run, their program's local cuts derived once for them all;
    # the CAM program's worst pass whole
    cam_points = _worst_cam_pass(res)
    programs = [scenario_with_program(scn, planned_path), scenario_with_program(scn, final_path),
                scn]
    stretches: dict[int, list] = {2: [cam_points]}
    say("verify", 0, len(programs))

    def runs() -> list[tuple[int, int, tuple[int, int]]]:
        """(program, seed, stretch) of each run, in the order they are started."""
        return [(w, k, p) for w in (1, 0, 2) for k, p in enumerate(stretches[w])]

    # 6: lobes at representative points
    def lobes_stage() -> list[dict]:
        say("lobes", 0, 1)
        out = _lobes(scn, res)
        say("lobes", 1, 1)
        return out

    done: dict[int, list] = {}
    judged: dict[int, Verification] = {}

    def finished(w: int, run) -> None:
        """Stretch ``run`` of program ``w`` is done (in program order): the program is
        judged when its last one is, and its streams let go."""
        done.setdefault(w, []).append(run)
        if len(done[w]) == len(stretches[w]):
            judged[w] = judge(done.pop(w))
            say("verify", len(judged), len(programs))

    if client is not None:
        if warm_sim:    # the simulation's kernels: compiled (and cached) before it starts
            from distributed import wait

            wait(warm_sim)
            warm_sim.clear()
        restart_compiled_workers(client)
        wp_f = client.scatter(wp, broadcast=True)
        # each program's part and local cuts on a worker, kept there for its stretches;
        # the splits here meanwhile (the geometry alone, 0.1 s a program)
        part_f = {w: client.submit(PartProgram, programs[w], pure=False) for w in (1, 0)}
        stretches.update((w, split_at_air(programs[w], VERIFY_STRETCHES)) for w in (1, 0))
        # each stretch on the worker that frees up next, the longest runs first (Dask
        # alone ran every stretch of a program where its part was made)
        results = balanced(client, [(simulate_stretch, (programs[w],),
                                     dict(points=p, seed=k, workpiece=wp_f,
                                          part=part_f.get(w)))
                                    for w, k, p in runs()])
        t_lobes = time.perf_counter()
        lobes = lobes_stage()                       # while the workers verify
        seconds["lobes"] = round(time.perf_counter() - t_lobes, 2)
        for (w, _k, _p), run in zip(runs(), results):
            finished(w, run)
        del part_f
        verified = [judged[w] for w in range(len(programs))]
        lap("verify")
    else:
        parts = {w: PartProgram(programs[w]) for w in (1, 0)}
        stretches.update((w, split_at_air(programs[w], VERIFY_STRETCHES, part=parts[w]))
                         for w in (1, 0))
        for w, k, p in runs():
            finished(w, simulate_stretch(programs[w], points=p, seed=k, workpiece=wp,
                                         part=parts.get(w)))
        verified = [judged[w] for w in range(len(programs))]
        lap("verify")
        lobes = lobes_stage()
        lap("lobes")
    seconds["total"] = round(time.perf_counter() - t_start, 2)
    return JobResult(scenario=scn, plan=res, compensation=comp, planned=planned_post,
                     final=final_post, planned_path=planned_path, final_path=final_path,
                     round_trip=rt, collisions=collisions, findings=found,
                     verify_planned=verified[0],
                     verify_final=verified[1], verify_cam=verified[2], cam_points=cam_points,
                     lobes=lobes, seconds=seconds,
                     stage1_computed=[r["computed"] for r in repro.stats])
