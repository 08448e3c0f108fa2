"""Planning on a Dask cluster: a two-worker LocalCluster on loopback plans the bundled
thin wall exactly as one process does."""

from __future__ import annotations

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from orient.plan import plan  # noqa: E402


def test_local_cluster_plan_equals_one_process(planned):
    scn, one = planned
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        dist = plan(scn, client=client)
        assert len(client.scheduler_info()["workers"]) == 2
    np.testing.assert_array_equal(one.cl.axis, dist.cl.axis)
    np.testing.assert_array_equal(one.cl.tip, dist.cl.tip)
    np.testing.assert_array_equal(one.margin, dist.margin)
    np.testing.assert_array_equal(one.cam_margin, dist.cam_margin)
    np.testing.assert_array_equal(one.grid_margin, dist.grid_margin)
    assert one.reason == dist.reason
    assert [c["sdm_margin"] for c in one.sdm_checks] == [c["sdm_margin"] for c in dist.sdm_checks]
