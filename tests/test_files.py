"""cdus.files: atomic JSON writes that never replace what is not a regular file."""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path

from cdus.files import write_json


def test_a_regular_file_is_written_atomically(tmp_path):
    p = tmp_path / "sub" / "m.json"
    write_json(p, {"a": 1})
    assert json.loads(p.read_text()) == {"a": 1} and not (tmp_path / "sub" / "m.json.tmp").exists()


def test_a_pipe_is_written_to_not_replaced(tmp_path):
    """--metrics-out /dev/stdout or a named pipe: replacing it by a file (or /dev/null!) is not ok."""
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got: list[str] = []
    reader = threading.Thread(target=lambda: got.append(open(fifo).read()))
    reader.start()
    write_json(fifo, {"b": 2})
    reader.join(10)
    assert json.loads(got[0]) == {"b": 2}
    assert not fifo.is_file() and fifo.exists()


from tests.fullfs import full_fs, no_room  # noqa: E402,F401  (the fixture)
from cdus.files import keep_json, metrics_fallbacks  # noqa: E402


def test_a_write_to_a_full_disk_is_told_and_kept_elsewhere(full_fs, tmp_path):
    """Issue 27, broken 2: a full disk at the end lost a completed run (ENOSPC raised out of
    write_json, no metrics anywhere). The failure is told (which file, why) and the data kept
    at the first place that takes it."""
    assert no_room(full_fs)
    lines: list[str] = []
    target = full_fs / "m.json"
    spare = tmp_path / "run" / "metrics.json"
    at = keep_json(target, {"a": 1}, [full_fs / "other.json", spare], lines.append)
    assert at == spare and json.loads(spare.read_text()) == {"a": 1}
    assert not target.exists()
    assert lines[0] == f"error: could not write the metrics to {target}: No space left on device"
    assert lines[1] == f"error: could not write the metrics to {full_fs / 'other.json'}: No space left on device"
    assert lines[2] == f"the metrics were kept in {spare} instead of {target}"
    assert not list(full_fs.glob(".m.json.*")), "a temp file left on the full disk"
    lines.clear()
    assert keep_json(target, {"a": 1}, [], lines.append) is None and len(lines) == 1


def test_the_fallbacks_are_the_run_directory_then_the_temporary_one(tmp_path):
    import tempfile

    run = tmp_path / "run"
    assert metrics_fallbacks(tmp_path / "elsewhere.json", run, "f-12") == [
        run / "metrics.json", Path(tempfile.gettempdir()) / "cdus-metrics-f-12.json"]
    # the run directory's own file is not its own fallback
    assert metrics_fallbacks(run / "metrics.json", run, "f-12") == [Path(tempfile.gettempdir()) / "cdus-metrics-f-12.json"]
