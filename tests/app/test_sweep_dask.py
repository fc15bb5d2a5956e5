"""The Dask executor: the same table as local processes, on a LocalCluster of 2 worker
processes on 127.0.0.1; a LocalCluster the sweep starts itself is stopped with it."""

import multiprocessing

import pytest

distributed = pytest.importorskip("distributed")

from cdus.app.executors import LOCAL_CLUSTER  # noqa: E402
from cdus.app.sweep import sweep  # noqa: E402
from cdus.app.sweepstore import WALL_CLOCK_FIELDS  # noqa: E402

CONFIG = "configs/concentric_circles.toml"
GRID = {"link.loss": [0, 0.3], "link.policy": ["hold", "extrapolate"]}


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, **LOCAL_CLUSTER) as c:
        yield c.scheduler_address


def table(res):
    return [{k: v for k, v in r.items() if k not in WALL_CLOCK_FIELDS} for r in res.rows()]


def test_a_sweep_on_a_cluster_gives_the_same_table_as_local_processes(tmp_path, cluster):
    assert cluster.startswith("tcp://127.0.0.1:")
    local = sweep(CONFIG, GRID, 3, tmp_path / "local", jobs=2, duration=10.0, quiet=True)
    on_dask = sweep(CONFIG, GRID, 3, tmp_path / "dask", cluster=cluster, duration=10.0, quiet=True)
    assert on_dask.executor == f"dask ({cluster})"
    assert (local.done, on_dask.done, on_dask.failed) == (12, 12, 0)
    assert table(on_dask) == table(local)
    assert any(r["link_dropped"] > 0 for r in table(local))  # the seeds matter: lossy cells drop messages
    assert (tmp_path / "dask" / "summary.md").read_text().split("\n", 3)[3] == \
        (tmp_path / "local" / "summary.md").read_text().split("\n", 3)[3]  # all but the header line


def test_a_cluster_sweep_resumes_a_local_one(tmp_path, cluster):
    a = sweep(CONFIG, GRID, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    b = sweep(CONFIG, GRID, 2, tmp_path, cluster=cluster, duration=5.0, quiet=True)
    assert (a.ran, b.ran, b.resumed, b.done) == (4, 4, 4, 8)


def test_the_dask_executor_starts_a_local_cluster_and_stops_it(tmp_path):
    before = set(multiprocessing.active_children())
    res = sweep(CONFIG, {"link.loss": [0, 0.3]}, 2, tmp_path, executor="dask", jobs=2, duration=5.0, quiet=True)
    assert res.executor == "dask (LocalCluster, 2 processes)"
    assert (res.done, res.failed, res.lost) == (4, 0, 0)
    assert set(multiprocessing.active_children()) <= before  # its worker processes are gone


def test_a_local_cluster_listens_on_loopback_only():
    from cdus.app.executors import make_executor

    ex = make_executor("dask", jobs=1)
    try:
        addresses = [ex.cluster.scheduler_address, *ex.client.nthreads()]
        assert len(addresses) == 2 and all(a.startswith("tcp://127.0.0.1:") for a in addresses)
        assert ex.cluster.scheduler.http_server is not None
        http = [s.getsockname()[0] for s in ex.cluster.scheduler.http_server._sockets.values()]
        assert http and set(http) == {"127.0.0.1"}
    finally:
        ex.close()


def test_a_scheduler_without_workers_is_said_and_the_sweep_runs_once_one_joins(tmp_path):
    import io
    import threading
    import time

    with distributed.LocalCluster(n_workers=0, threads_per_worker=1, processes=True, **LOCAL_CLUSTER) as c:
        said = io.StringIO()
        out: dict = {}
        t = threading.Thread(target=lambda: out.setdefault("res", sweep(
            CONFIG, {"link.loss": [0]}, 1, tmp_path, cluster=c.scheduler_address, duration=2.0, quiet=True,
            stream=said)), daemon=True)
        t.start()
        deadline = time.monotonic() + 60  # a hang limit, not a speed check
        while "has no workers" not in said.getvalue() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert f"the Dask scheduler at {c.scheduler_address} has no workers" in said.getvalue()
        assert t.is_alive()  # waiting for a worker
        c.scale(1)
        t.join(120)
        assert not t.is_alive() and out["res"].done == 1
