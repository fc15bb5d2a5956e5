"""cdus.files: atomic JSON writes that never replace what is not a regular file."""

from __future__ import annotations

import json
import os
import threading

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
