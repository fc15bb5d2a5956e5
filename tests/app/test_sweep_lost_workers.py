"""A local worker process that dies (killed, out of memory) loses only the runs in flight:
the sweep goes on in a new pool, writes its tables, counts the lost runs, and the same call
again runs just those. A script that starts a sweep without the ``__main__`` guard (spawned
workers import it) gets an error that says so, not a confusing one."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
import warnings
from collections import Counter
from pathlib import Path

import pytest

import cdus
import cdus.app.sweep as engine
from cdus.app.sweep import sweep

ROOT = Path(__file__).resolve().parents[2]
CONFIG = "configs/concentric_circles.toml"
MARK = "CDUS_TEST_DIE_MARK"


def dies_once(scenario, clock):
    """In a worker: the run of seed 2 kills its own process the first time (a kill -9 from
    outside, an OOM kill); every other run is the real one."""
    mark = Path(os.environ[MARK])
    if scenario.seed == 2 and not mark.exists():
        mark.touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return engine.run_task(scenario, clock)  # a spawned worker imports the module unpatched


def always_dies(scenario, clock):
    os.kill(os.getpid(), signal.SIGKILL)


def pairs(out: Path) -> Counter:
    with open(out / "results.jsonl") as fh:
        return Counter((json.dumps(r["cell"], sort_keys=True), r["seed"]) for r in map(json.loads, fh))


@pytest.fixture
def patched(monkeypatch, tmp_path):
    monkeypatch.setenv(MARK, str(tmp_path / "died"))
    return monkeypatch


def test_a_killed_local_worker_loses_only_its_runs_and_the_sweep_goes_on(patched, tmp_path):
    out = tmp_path / "out"
    patched.setattr(engine, "run_task", dies_once)
    a = sweep(CONFIG, {"link.loss": [0, 0.2]}, 4, out, jobs=2, duration=3.0, quiet=True)
    assert (tmp_path / "died").exists()
    assert a.lost >= 1 and a.done + a.lost <= a.planned == 8 and a.done >= 8 - 4  # at most the runs in flight (4 slots)
    assert f"{a.lost} lost by the executor" in (out / "summary.md").read_text()
    patched.undo()
    b = sweep(CONFIG, {"link.loss": [0, 0.2]}, 4, out, jobs=2, duration=3.0, quiet=True)
    assert (b.lost, b.done, b.ran) == (0, 8, 8 - a.done)
    assert len(pairs(out)) == 8 and set(pairs(out).values()) == {1}


def test_a_pool_that_cannot_run_anything_is_not_started_again_and_again(patched, tmp_path):
    patched.setattr(engine, "run_task", always_dies)
    res = sweep(CONFIG, {"link.loss": [0, 0.2]}, 4, tmp_path, jobs=2, duration=3.0, quiet=True)
    assert res.done == 0 and res.lost >= 1 and not res.interrupted
    assert (tmp_path / "summary.md").exists()


def test_the_api_warns_when_runs_are_missing_from_the_table(patched, tmp_path):
    patched.setattr(engine, "run_task", dies_once)
    with pytest.warns(RuntimeWarning, match="runs are not in the table"):
        table = cdus.sweep(CONFIG, {"link.loss": [0, 0.2]}, seeds=4, out=tmp_path / "out", jobs=2, duration=3.0)
    assert len(table) < 8
    patched.undo()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(cdus.sweep(CONFIG, {"link.loss": [0, 0.2]}, seeds=4, out=tmp_path / "out", jobs=2,
                              duration=3.0)) == 8


def test_a_script_without_the_main_guard_is_told_so(tmp_path):
    script = tmp_path / "unguarded.py"
    script.write_text(textwrap.dedent(f"""
        import cdus
        cdus.sweep({str(ROOT / CONFIG)!r}, {{"link.loss": [0, 0.2]}}, seeds=2, duration=3.0,
                   out={str(tmp_path / "out")!r}, jobs=2)
    """))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=240, env=env,
                          cwd=tmp_path, start_new_session=True)
    assert 'if __name__ == "__main__":' in proc.stderr
    assert "another sweep is running" not in proc.stderr


def _children(pid: int) -> list[int]:
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as fh:
            return [int(c) for c in fh.read().split()]
    except OSError:
        return []


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"  # a zombie has exited
    except OSError:
        return False


@pytest.mark.skipif(not Path(f"/proc/{os.getpid()}/task/{os.getpid()}/children").exists(), reason="needs Linux /proc")
def test_local_workers_exit_when_the_driver_is_killed(tmp_path):
    """kill -9 of the driver (it cannot stop its pool): its worker processes go too, instead of
    waiting on its queue forever."""
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.Popen([sys.executable, "-m", "cdus", "sweep", CONFIG, "--set", "link.loss=0,0.1,0.2,0.3",
                             "--seeds", "10", "--duration", "20", "--jobs", "2", "-q", "--out", str(out)],
                            cwd=ROOT, env=env, start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    workers: list[int] = []
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            workers = _children(proc.pid)
            if len(workers) >= 2 and (out / "results.jsonl").exists() and (out / "results.jsonl").stat().st_size:
                break
            time.sleep(0.1)
        assert proc.poll() is None and len(workers) >= 2, "the sweep ended before it was killed: proves nothing"
        proc.kill()
        proc.wait()
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and any(map(_alive, workers)):
            time.sleep(0.2)
        assert not [w for w in workers if _alive(w)], "workers left behind"
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        for w in workers:
            try:
                os.kill(w, signal.SIGKILL)
            except ProcessLookupError:
                pass


def test_the_summary_says_how_long_each_run_was(tmp_path):
    """"never settled" means "not within the run": the summary says how long a run was."""
    sweep(CONFIG, {"link.loss": [0]}, 1, tmp_path, jobs=1, duration=3.0, quiet=True)
    assert "3 simulated s per run" in (tmp_path / "summary.md").read_text()
