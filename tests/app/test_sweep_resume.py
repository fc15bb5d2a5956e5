"""Streaming and resume: rows on disk as they come, a crash or Ctrl-C loses only the runs in
flight, the same command again runs each missing (cell, seed) once, another sweep's
directory is refused."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cdus.app.cli import main
from cdus.app.sweep import sweep
from cdus.app.sweepplan import _Plan
from cdus.app.sweepstore import scan_rows
from cdus.scenario.config import ConfigError

ROOT = Path(__file__).resolve().parents[2]
CONFIG = "configs/concentric_circles.toml"


def pairs(out: Path) -> Counter:
    """(cell, seed) -> how many whole rows results.jsonl has of it."""
    c: Counter = Counter()
    with open(out / "results.jsonl", "rb") as fh:
        for line in fh:
            try:
                row = json.loads(line) if line.endswith(b"\n") else None
            except ValueError:
                row = None  # an unreadable line: not a row
            if row is not None:
                c[(json.dumps(row["cell"], sort_keys=True), row["seed"])] += 1
    return c


def test_a_second_run_skips_what_is_done_and_more_seeds_run_only_the_new_ones(tmp_path):
    grid = {"link.loss": [0, 0.2]}
    a = sweep(CONFIG, grid, 2, tmp_path, jobs=1, duration=5.0, quiet=True)
    assert (a.ran, a.resumed, a.done) == (4, 0, 4)
    b = sweep(CONFIG, grid, 2, tmp_path, jobs=1, duration=5.0, quiet=True)
    assert (b.ran, b.resumed, b.done) == (0, 4, 4)
    assert "4 done before" in (tmp_path / "summary.md").read_text()
    c = sweep(CONFIG, grid, 3, tmp_path, jobs=1, duration=5.0, quiet=True)
    assert (c.ran, c.resumed, c.done) == (2, 4, 6)
    assert set(pairs(tmp_path).values()) == {1} and len(pairs(tmp_path)) == 6
    # fewer seeds: the table is the plan's, the other rows stay in the file
    d = sweep(CONFIG, grid, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    assert (d.ran, d.done) == (0, 2) and len(d.rows()) == 2
    assert "4 rows of results.jsonl are of seeds not in this plan" in (tmp_path / "summary.md").read_text()


def test_a_torn_last_line_is_ignored_counted_and_its_run_runs_again(tmp_path):
    grid = {"link.loss": [0, 0.2]}
    sweep(CONFIG, grid, 2, tmp_path, jobs=1, duration=5.0, quiet=True)
    path = tmp_path / "results.jsonl"
    lines = path.read_bytes().splitlines(keepends=True)
    path.write_bytes(b"".join(lines[:-1]) + lines[-1][:40])  # the last write cut off by a crash
    res = sweep(CONFIG, grid, 2, tmp_path, jobs=1, duration=5.0, quiet=True)
    assert (res.torn, res.ran, res.resumed, res.done) == (1, 1, 3, 4)
    assert path.read_bytes().endswith(b"\n")
    assert all(json.loads(line) for line in path.read_bytes().splitlines())  # the torn piece is gone
    assert set(pairs(tmp_path).values()) == {1} and len(pairs(tmp_path)) == 4


def test_an_unreadable_line_in_the_middle_is_skipped_and_its_run_runs_again(tmp_path):
    grid = {"link.loss": [0]}
    sweep(CONFIG, grid, 3, tmp_path, jobs=1, duration=5.0, quiet=True)
    path = tmp_path / "results.jsonl"
    lines = path.read_bytes().splitlines(keepends=True)
    path.write_bytes(lines[0] + b'{"cell": garbage\n' + lines[2])
    res = sweep(CONFIG, grid, 3, tmp_path, jobs=1, duration=5.0, quiet=True)
    assert (res.unreadable, res.ran, res.done) == (1, 1, 3)
    assert len(pairs(tmp_path)) == 3


@settings(max_examples=150, deadline=None)
@given(st.lists(st.one_of(
    st.binary(max_size=60).filter(lambda b: b"\n" not in b),
    st.builds(lambda l, s, st_: json.dumps({"cell": {"link.loss": l}, "seed": s, "status": st_}).encode(),
              st.sampled_from([0, 0.2, 0.5, "x"]), st.one_of(st.integers(-2, 5), st.just(True), st.none()),
              st.sampled_from(["ok", "failed", 3])),
    st.just(b'{"cell": []}'), st.just(b"[1, 2]"), st.just(b"\xff\xfe")), max_size=12), st.booleans())
def test_any_results_file_is_scanned_without_an_exception_every_line_accounted_for(tmp_path_factory, lines, torn):
    path = tmp_path_factory.mktemp("scan") / "results.jsonl"
    data = b"".join(line + b"\n" for line in lines)
    if torn and lines:
        data = data[:-1]
    path.write_bytes(data)
    p = _Plan([("link.loss", [0, 0.2])], [1, 2, 3])
    s = scan_rows(path, p.index_of)
    whole = len(lines) - (1 if torn and lines else 0)
    assert len(s.offsets) + s.unreadable + s.duplicates + s.outside == whole
    assert s.torn == (1 if torn and lines and lines[-1] else 0)  # an empty last line cut short is nothing
    assert all(0 <= j < p.size for j in s.offsets)
    assert s.end == len(b"".join(line + b"\n" for line in lines[:whole]))


def test_another_sweep_s_directory_is_refused_and_left_as_it_was(tmp_path):
    sweep(CONFIG, {"link.loss": [0, 0.2]}, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    with pytest.raises(ConfigError, match=r"another sweep: the grid differs \(it was link.loss=0,0.2\)"):
        sweep(CONFIG, {"link.loss": [0, 0.3]}, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    with pytest.raises(ConfigError, match="the config differs"):
        sweep(CONFIG, {"link.loss": [0, 0.2]}, 1, tmp_path, jobs=1, duration=6.0, quiet=True)
    with pytest.raises(ConfigError, match="the config differs"):
        sweep(CONFIG, {"link.loss": [0, 0.2]}, 1, tmp_path, jobs=1, duration=5.0, quiet=True,
              overrides={"graph.topology": "chain"})
    with pytest.raises(ConfigError, match="the clock differs"):
        sweep(CONFIG, {"link.loss": [0, 0.2]}, 1, tmp_path, jobs=1, duration=5.0, quiet=True, clock="lockstep")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_rows_without_a_manifest_are_refused(tmp_path):
    (tmp_path / "results.jsonl").write_text("{}\n")
    with pytest.raises(ConfigError, match="no manifest.json"):
        sweep(CONFIG, {"link.loss": [0]}, 1, tmp_path, jobs=1, duration=5.0, quiet=True)


def test_the_cli_refuses_another_sweep_s_out_with_exit_2(tmp_path, capsys):
    out = str(tmp_path / "o")
    assert main(["sweep", CONFIG, "--set", "link.loss=0", "--seeds", "1", "--duration", "5", "--jobs", "1", "-q",
                 "--out", out]) == 0
    capsys.readouterr()
    assert main(["sweep", CONFIG, "--set", "link.loss=0.1", "--seeds", "1", "--duration", "5", "--jobs", "1", "-q",
                 "--out", out]) == 2
    err = capsys.readouterr().err
    assert "holds the results of another sweep" in err and "nothing was started" in err


def test_an_unreachable_cluster_is_a_usage_error_naming_it_and_nothing_runs(tmp_path, capsys):
    out = tmp_path / "o"
    code = main(["sweep", CONFIG, "--set", "link.loss=0", "--seeds", "1", "--duration", "5", "-q", "--out", str(out),
                 "--cluster", "tcp://127.0.0.1:9", "--connect-timeout", "0.5"])
    assert code == 2
    err = capsys.readouterr().err
    assert "--cluster" in err and "tcp://127.0.0.1:9" in err and "nothing was started" in err
    assert not out.exists()


# 10 simulated seconds a run (0.1 s of CPU in process): what is checked is which runs are on disk, not their results
RUN_S = "10"


def _start(out: Path, jobs: int, seeds: int = 10) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "cdus.app.cli", "sweep", CONFIG, "--set", "link.loss=0,0.1",
                             "--seeds", str(seeds), "--duration", RUN_S, "--jobs", str(jobs), "--out", str(out)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _kill_group(proc: subprocess.Popen, sig: int = signal.SIGKILL) -> None:
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            pass


def _wait_rows(proc: subprocess.Popen, out: Path, n: int, timeout: float = 120.0) -> int:
    path = out / "results.jsonl"
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if path.exists() and path.read_bytes().count(b"\n") >= n:
            return path.read_bytes().count(b"\n")
        time.sleep(0.02)
    raise AssertionError(f"the sweep wrote fewer than {n} rows (exit {proc.poll()})")


@pytest.mark.parametrize("jobs", [1, 2])  # the driver alone; the driver and its pool of processes
def test_a_sweep_killed_half_way_and_restarted_runs_each_pair_exactly_once(tmp_path, jobs):
    out = tmp_path / "o"
    proc = _start(out, jobs)
    try:
        _wait_rows(proc, out, 3)
        _kill_group(proc)
        proc.wait(timeout=30)
    finally:
        _kill_group(proc)
        proc.communicate()
    done = sum(pairs(out).values())
    assert 3 <= done < 20, "the sweep finished before it was killed: the test proves nothing"
    assert not (out / "results.csv").exists()  # it never got to the end
    again = subprocess.run([sys.executable, "-m", "cdus.app.cli", "sweep", CONFIG, "--set", "link.loss=0,0.1",
                            "--seeds", "10", "--duration", RUN_S, "--jobs", "1", "--out", str(out)],
                           cwd=ROOT, capture_output=True, text=True, timeout=300, start_new_session=True)
    assert again.returncode == 0, again.stderr
    assert f"{done} of 20 runs already done" in again.stderr
    counts = pairs(out)
    assert len(counts) == 20 and set(counts.values()) == {1}
    with open(out / "results.csv") as fh:
        table = list(csv.DictReader(fh))
    assert [(r["link.loss"], r["seed"]) for r in table] == [(loss, str(s)) for loss in ("0", "0.1")
                                                            for s in range(1, 11)]


@pytest.mark.parametrize("jobs, how", [(1, "ctrl-c"), (2, "ctrl-c"), (2, "sigterm")])
def test_ctrl_c_keeps_the_rows_done_and_says_how_to_resume(tmp_path, jobs, how):
    out = tmp_path / "o"
    proc = _start(out, jobs)
    try:
        _wait_rows(proc, out, 2)
        if how == "ctrl-c":
            _kill_group(proc, signal.SIGINT)  # as a terminal's Ctrl-C: the whole group
        else:
            proc.send_signal(signal.SIGTERM)  # as a batch system's stop: the driver alone
        _, err = proc.communicate(timeout=60)
    finally:
        _kill_group(proc)
        proc.wait()
    assert proc.returncode == 130, err
    assert "interrupted:" in err and "Run the same command again (same --out)" in err
    with open(out / "results.csv") as fh:
        table = list(csv.DictReader(fh))
    assert 2 <= len(table) < 20 and len(table) == sum(pairs(out).values())
    assert "interrupted" in (out / "summary.md").read_text()


def test_runs_the_executor_loses_are_not_recorded_and_run_again(tmp_path, monkeypatch):
    import cdus.app.sweep as engine

    real = engine.run_task
    calls = []

    def flaky(scenario, clock):
        calls.append(scenario.seed)
        if scenario.seed == 2 and len(calls) < 4:
            raise OSError("worker lost")  # as a killed worker looks to the driver
        return real(scenario, clock)

    monkeypatch.setattr(engine, "run_task", flaky)
    a = sweep(CONFIG, {"link.loss": [0]}, 3, tmp_path, jobs=1, duration=5.0, quiet=True)
    assert (a.ran, a.lost, a.done) == (2, 1, 2)
    assert "1 lost by the executor (run again to retry)" in (tmp_path / "summary.md").read_text()
    b = sweep(CONFIG, {"link.loss": [0]}, 3, tmp_path, jobs=1, duration=5.0, quiet=True)
    assert (b.ran, b.lost, b.done, b.resumed) == (1, 0, 3, 2)
    assert len(pairs(tmp_path)) == 3


def test_two_sweeps_never_write_into_one_directory(tmp_path):
    from cdus.app.sweepstore import RowLog

    first = RowLog(tmp_path / "results.jsonl")
    try:
        with pytest.raises(ConfigError, match="another sweep is running into this directory"):
            RowLog(tmp_path / "results.jsonl")
    finally:
        first.close()
    RowLog(tmp_path / "results.jsonl").close()  # free again once the first is done


def test_a_sweep_without_a_grid_runs_the_seeds_of_the_scenario(tmp_path):
    res = sweep(CONFIG, None, [4, 5], tmp_path, jobs=1, duration=5.0, quiet=True)
    assert [r["seed"] for r in res.rows()] == [4, 5] and res.failed == 0
    assert "| 2/2 |" in (tmp_path / "summary.md").read_text()
    assert (tmp_path / "sweep.png").stat().st_size > 10_000


def test_what_a_worker_returns_is_checked_and_its_reason_made_printable(tmp_path, monkeypatch):
    import cdus.app.sweep as engine

    answers = iter([["not", "a", "row"], {"status": "failed", "reason": "bad\x1b[2Jvalue\nhere"}])
    monkeypatch.setattr(engine, "run_task", lambda scenario, clock: next(answers))
    res = sweep(CONFIG, {"link.loss": [0]}, 2, tmp_path, jobs=1, duration=5.0, quiet=True)
    assert (res.lost, res.ran, res.failed) == (1, 1, 1)
    (row,) = res.rows()
    assert row["reason"] == "bad\\x1b[2Jvalue\\nhere"


def _launchers(marker: str) -> list[int]:
    """Pids of processes whose command line has ``marker`` (this test's temporary directory: the
    launcher's config and logs are there, and its world's and vehicles' files)."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if marker in cmd:
                out.append(int(d.name))
    return out


def test_ctrl_c_during_a_lockstep_run_stops_its_launched_fleet(tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    proc = subprocess.Popen([sys.executable, "-m", "cdus.app.cli", "sweep", CONFIG, "--seeds", "2", "--duration", "600",
                             "--clock", "lockstep", "--out", str(tmp_path / "o")], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env={**os.environ, "TMPDIR": str(tmp)})
    try:
        deadline = time.monotonic() + 60
        while not _launchers(str(tmp)) and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        assert _launchers(str(tmp)), "no launcher started"
        time.sleep(1.0)  # its fleet up and running
        _kill_group(proc, signal.SIGINT)  # the launcher is in a session of its own: it and its fleet must go too
        _, err = proc.communicate(timeout=60)
    finally:
        _kill_group(proc)
        proc.wait()
        for pid in _launchers(str(tmp)):  # teardown: nothing of this test may stay
            os.kill(pid, signal.SIGKILL)
    assert proc.returncode == 130, err
    assert _launchers(str(tmp)) == []
