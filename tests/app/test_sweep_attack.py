"""A sweep's directory, executor and cluster address under attack: a damaged manifest or
results.jsonl, an ``out`` that cannot be written, another sweep starting meanwhile, an executor
that breaks mid-sweep, a driver killed with SIGKILL, a listener that is not a scheduler. Each
ends in a clear error or in tables of the rows done, never a traceback or a hang, and a resume
still runs each (cell, seed) once."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from cdus.app.sweep import sweep
from cdus.app.sweepplan import _Plan
from cdus.app.sweepstore import FIELDS, scan_rows, write_tables
from cdus.scenario.config import ConfigError

ROOT = Path(__file__).resolve().parents[2]
CONFIG = str(ROOT / "configs/concentric_circles.toml")
GRID = {"link.loss": [0, 0.2]}


def _pairs(out: Path) -> dict:
    c: dict = {}
    for line in (out / "results.jsonl").read_bytes().splitlines():
        row = json.loads(line)
        key = (json.dumps(row["cell"], sort_keys=True), row["seed"])
        c[key] = c.get(key, 0) + 1
    return c


@pytest.mark.parametrize("grid", [5, [[1]], [["k", 5]], "x", {"a": 1}, [[1, [2]]]])
def test_a_tampered_manifest_grid_is_refused_with_a_clear_error(tmp_path, grid):
    sweep(CONFIG, GRID, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    m = json.loads((tmp_path / "manifest.json").read_text())
    m["grid"] = grid
    (tmp_path / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(ConfigError, match=r"the grid differs \(it was not a grid: "):
        sweep(CONFIG, GRID, 1, tmp_path, jobs=1, duration=5.0, quiet=True)


def test_a_manifest_nested_too_deep_is_refused_with_a_clear_error(tmp_path):
    (tmp_path / "manifest.json").write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ConfigError, match="manifest.json: cannot be read .RecursionError"):
        sweep(CONFIG, GRID, 1, tmp_path, jobs=1, duration=5.0, quiet=True)


@pytest.mark.parametrize("field, value", [("link_sent", 10 ** 30), ("wall_s", 10 ** 400), ("link_sent", 1e300),
                                          ("link_sent", -(2 ** 63) - 1)])
def test_numbers_no_column_holds_in_results_jsonl_become_empty_cells_not_a_crash(tmp_path, field, value):
    sweep(CONFIG, GRID, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    path = tmp_path / "results.jsonl"
    lines = path.read_text().splitlines(keepends=True)
    row = json.loads(lines[0])
    row[field] = value
    lines[0] = json.dumps(row) + "\n"
    path.write_text("".join(lines))
    res = sweep(CONFIG, GRID, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    rows = res.rows()
    assert (res.done, res.ran) == (2, 0) and rows[0][field] is None and rows[1][field] is not None
    assert not list(tmp_path.glob("*.tmp"))


_json = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
                     lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=3), inner,
                                                                                   max_size=3), max_leaves=6)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@example([{"link_sent": 2 ** 64, "wall_s": 10 ** 400, "interventions": 1e300}])
@given(st.lists(st.dictionaries(st.sampled_from(["status", "reason", *FIELDS]), _json, max_size=8), min_size=1,
                max_size=4))
def test_any_json_values_in_rows_make_a_table_without_an_exception(tmp_path, values):
    rows = [{"cell": {"link.loss": 0}, "seed": i, "status": "ok", **v} for i, v in enumerate(values)]
    assert write_tables(tmp_path, ["link.loss"], ["int64"], iter(rows)) == len(rows)


def test_a_line_whose_status_is_not_ok_or_failed_is_not_a_row_and_its_run_runs_again(tmp_path):
    sweep(CONFIG, GRID, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    path = tmp_path / "results.jsonl"
    lines = path.read_text().splitlines(keepends=True)
    row = json.loads(lines[0])
    row["status"] = "banana"
    path.write_text(json.dumps(row) + "\n" + lines[1])
    assert scan_rows(path, _Plan([("link.loss", [0, 0.2])], [1]).index_of).unreadable == 1
    res = sweep(CONFIG, GRID, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    assert (res.unreadable, res.ran, res.done, res.failed) == (1, 1, 2, 0)


def test_a_failure_reason_from_the_file_cannot_write_markdown_into_the_summary(tmp_path):
    sweep(CONFIG, GRID, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    path = tmp_path / "results.jsonl"
    lines = path.read_text().splitlines(keepends=True)
    row = json.loads(lines[0])
    row.update(status="failed", reason="x\n\n# INJECTED\n")
    path.write_text(json.dumps(row) + "\n" + lines[1])
    sweep(CONFIG, GRID, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    summary = (tmp_path / "summary.md").read_text()
    assert "\n# INJECTED" not in summary and "x\\n\\n# INJECTED" in summary


@pytest.mark.parametrize("kind", ["file", "dangling link", "under a file"])
def test_an_out_that_cannot_be_a_directory_is_a_config_error(tmp_path, kind):
    (tmp_path / "f").write_text("x")
    out = {"file": tmp_path / "f", "under a file": tmp_path / "f" / "o", "dangling link": tmp_path / "l"}[kind]
    if kind == "dangling link":
        out.symlink_to(tmp_path / "nowhere" / "x")
    with pytest.raises(ConfigError, match="--out: .*cannot hold the results"):
        sweep(CONFIG, GRID, 1, out, jobs=1, duration=5.0, quiet=True)
    assert (tmp_path / "f").read_text() == "x"


def test_another_sweep_that_took_the_directory_meanwhile_is_not_mixed_into(tmp_path, monkeypatch):
    """The manifest is checked first, then the executor starts (a LocalCluster: seconds), then
    the lock is taken: a sweep that ran into ``out`` meanwhile must be seen under the lock."""
    import cdus.app.sweep as engine

    real = engine.make_executor

    def slow(*args, **kwargs):
        monkeypatch.setattr(engine, "make_executor", real)
        sweep(CONFIG, {"link.delay.base": [0]}, 1, tmp_path, jobs=1, duration=5.0, quiet=True)  # the other one
        return real(*args, **kwargs)

    monkeypatch.setattr(engine, "make_executor", slow)
    with pytest.raises(ConfigError, match="holds the results of another sweep"):
        sweep(CONFIG, GRID, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    assert json.loads((tmp_path / "manifest.json").read_text())["grid"] == [["link.delay.base", [0]]]
    assert list(_pairs(tmp_path)) == [('{"link.delay.base": 0}', 1)]


def _die_on_seed_2(scenario, clock):
    """A run task whose worker dies on seed 2 (as the OOM killer would do it)."""
    from cdus.app.sweepworker import run_task

    if scenario.seed == 2:
        os._exit(9)
    return run_task(scenario, clock)


def test_a_local_worker_killed_ends_the_sweep_with_the_tables_of_the_rows_done(tmp_path, monkeypatch):
    import cdus.app.sweep as engine

    monkeypatch.setattr(engine, "run_task", _die_on_seed_2)
    seeds = list(range(1, 9))  # more than the 4 in flight: the sweep submits to the broken pool too
    res = sweep(CONFIG, {"link.loss": [0]}, seeds, tmp_path, jobs=2, duration=5.0, quiet=True)
    assert res.lost >= 1 and res.done == res.ran < 8
    assert res.parquet.exists() and len(res.rows()) == res.done
    monkeypatch.undo()
    again = sweep(CONFIG, {"link.loss": [0]}, seeds, tmp_path, jobs=1, duration=5.0, quiet=True)
    assert (again.done, again.lost) == (8, 0) and set(_pairs(tmp_path).values()) == {1}


def test_pool_workers_end_when_the_driver_is_killed(tmp_path):
    driver = subprocess.Popen([sys.executable, "-c", textwrap.dedent("""
        import os, sys, time
        from cdus.app.executors import ProcessExecutor
        ex = ProcessExecutor(2)
        futs = [ex.submit(os.getpid) for _ in range(4)]
        print(" ".join(str(p) for p in {f.result() for f in futs}), flush=True)
        time.sleep(600)
    """)], cwd=ROOT, stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        workers = [int(p) for p in driver.stdout.readline().split()]
        assert workers
        driver.send_signal(signal.SIGKILL)  # the driver alone, as the OOM killer would
        driver.wait(timeout=30)
        deadline = time.monotonic() + 60  # a liveness bound, not a speed figure: without the fix they live on
        while time.monotonic() < deadline and any(_alive(p) for p in workers):
            time.sleep(0.1)
        left = [p for p in workers if _alive(p)]
    finally:
        try:
            os.killpg(driver.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        driver.stdout.close()
    assert not left, f"pool workers {left} outlived their driver"


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(")")[-1].split()[0] != "Z"  # a zombie has ended
    except FileNotFoundError:
        return False


def test_a_listener_that_is_not_a_scheduler_is_a_config_error_not_a_hang(tmp_path):
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen(8)  # accepts (the kernel does) and never says a word
    address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
    outcome: list = []

    def go() -> None:
        try:
            sweep(CONFIG, GRID, 1, tmp_path / "o", cluster=address, connect_timeout=1.0, quiet=True)
            outcome.append("ran")
        except Exception as e:  # noqa: BLE001 (the test reports what it was)
            outcome.append(e)

    t = threading.Thread(target=go, daemon=True)
    t.start()
    t.join(120)  # a liveness bound: without the fix it waits forever
    silent.close()
    assert outcome, "the sweep hung on a listener that is not a Dask scheduler"
    assert isinstance(outcome[0], ConfigError) and "--cluster" in str(outcome[0]) and address in str(outcome[0])
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("seeds", [[2 ** 70], [2 ** 63]])
def test_a_seed_the_table_cannot_hold_is_refused_before_any_run(tmp_path, seeds):
    with pytest.raises(ConfigError, match=r"seeds: expected distinct integers in \[0, 2\*\*63\)"):
        sweep(CONFIG, GRID, seeds, tmp_path / "o", jobs=1, duration=5.0, quiet=True)
    assert not (tmp_path / "o").exists()


def test_a_plan_too_large_to_list_is_refused_before_it_is_made(tmp_path):
    with pytest.raises(ConfigError, match="more than 10,000,000 runs"):
        sweep(CONFIG, GRID, 10 ** 12, tmp_path / "o", jobs=1, duration=5.0, quiet=True)


def test_tables_interrupted_while_written_leave_no_half_written_file(tmp_path):
    def rows():
        yield {"cell": {"link.loss": 0}, "seed": 1, "status": "ok"}
        raise KeyboardInterrupt  # the second Ctrl-C

    with pytest.raises(KeyboardInterrupt):
        write_tables(tmp_path, ["link.loss"], ["int64"], rows())
    assert list(tmp_path.iterdir()) == []


def test_a_second_ctrl_c_is_exit_130_saying_how_to_resume_not_a_traceback(tmp_path, monkeypatch, capsys):
    import cdus.app.cli as cli
    import cdus.app.sweep as sweep_module

    def interrupted_twice(*args, **kwargs):
        raise KeyboardInterrupt  # not a SweepInterrupted: the second one came while the first was handled

    monkeypatch.setattr(sweep_module, "sweep", interrupted_twice)  # cmd_sweep imports it where it runs
    code = cli.main(["sweep", CONFIG, "--set", "link.loss=0", "--seeds", "1", "--duration", "5", "-q", "--out",
                     str(tmp_path / "o")])
    assert code == 130
    assert "interrupted again" in capsys.readouterr().err


def test_a_disk_that_fills_up_mid_sweep_is_an_error_saying_how_to_resume_and_loses_no_row(tmp_path, monkeypatch,
                                                                                            capsys):
    import errno

    import cdus.app.cli as cli
    from cdus.app.sweepstore import RowLog

    real = RowLog.append
    written: list = []

    def fills_up(self, row):
        if len(written) == 2:
            os.write(self.fd, b'{"cell":{"link.lo')  # what fit before ENOSPC: a torn line
            raise OSError(errno.ENOSPC, "No space left on device")
        written.append(row)
        real(self, row)

    monkeypatch.setattr(RowLog, "append", fills_up)
    out = tmp_path / "o"
    args = ["sweep", CONFIG, "--set", "link.loss=0,0.2", "--seeds", "2", "--duration", "5", "--jobs", "1", "-q",
            "--out", str(out)]
    assert cli.main(args) == 1
    err = capsys.readouterr().err
    assert "No space left on device" in err and "run the same command again" in err
    monkeypatch.undo()
    assert cli.main(args) == 0
    assert len(_pairs(out)) == 4 and set(_pairs(out).values()) == {1}
