"""Stage 1 of the error prediction on a Dask cluster: a LocalCluster of two worker
processes on loopback gives the same prediction as one process, bit for bit."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from errpred.cli import main
from errpred.pipeline import blocks_in_scope, build_predictor, load

SCENARIO = "errpred/scenarios/mold-ball/scenario.toml"
LINES = (6131, 6250)       # about 120 blocks of the contour slice


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as c, \
            distributed.Client(c) as client:
        yield client


def _fields(pred):
    return [(p.geometry.block, p.status, p.E_um, p.line) for p in pred.points]


def test_local_cluster_prediction_equals_one_process(cluster):
    scn = dataclasses.replace(load(SCENARIO), lines=LINES)
    pred = build_predictor(scn)
    blocks = blocks_in_scope(scn, pred.program)
    assert len(blocks) > 60
    one = pred.run(blocks)
    dist = build_predictor(scn).run(blocks, client=cluster)
    assert len(cluster.scheduler_info()["workers"]) == 2
    a, b = _fields(one), _fields(dist)
    assert a == b                                         # exact, floats included
    np.testing.assert_array_equal(one.wear_mm, dist.wear_mm)
    assert sum(1 for p in one.points if p.status == "predicted") > 30


def test_cli_scheduler_option_gives_the_same_report(cluster, tmp_path):
    r1, r2 = tmp_path / "one.json", tmp_path / "dask.json"
    base = ["predict", SCENARIO, "--lines", str(LINES[0]), str(LINES[1]), "-q", "--no-design"]
    assert main(base + ["-o", str(r1)]) == 0
    assert main(base + ["-o", str(r2), "--scheduler", cluster.scheduler.address]) == 0
    one, dist = json.loads(r1.read_text()), json.loads(r2.read_text())
    one.pop("timing", None)
    dist.pop("timing", None)
    assert one["points"] == dist["points"]
    assert one["summary"] == dist["summary"]


def test_the_local_cluster_workers_keep_freed_memory_for_reuse():
    """The command lines' local cluster starts its workers with the malloc settings of
    ``WORKER_MALLOC_ENV`` (not Dask's 64 kB trim threshold, which maps and unmaps every
    array above 128 kB), and keeps Dask's one-thread settings for the numeric libraries."""
    import os

    from errpred.cluster import dask_client
    from errpred.constants import WORKER_MALLOC_ENV

    keys = (*WORKER_MALLOC_ENV, "OMP_NUM_THREADS")
    with dask_client(workers=1) as client:
        seen = list(client.run(lambda: {k: os.environ.get(k) for k in keys}).values())
    assert seen == [{**WORKER_MALLOC_ENV, "OMP_NUM_THREADS": "1"}]
