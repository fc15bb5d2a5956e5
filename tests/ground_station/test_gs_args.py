"""`cdus gs` arguments, whatever a person types (rev-gs): a usage error (ConfigError, exit 2,
nothing sent), never a traceback."""

from __future__ import annotations

import pytest
from hypothesis import given, settings, strategies as hs

from cdus.commands.parse import BY_CLI, parse_cli
from cdus.wire.rejected import Rejected
from ground_station.__main__ import main

_keys = hs.sampled_from(["phases", "offsets", "phases.usv1", "offsets.usv2", "offsets.usv2.usv1", "k", "c", "k.x",
                         "family", "center", "radius", "loss", "delay.base", "delay", "tx_power", "station", "a.b.c",
                         "", ".", "a..b", "phases.", "x"])
_values = hs.sampled_from(["1", "3", "-1", "nan", "inf", "[1,2]", "[1]", "[]", "{}", "true", "abc", "\"s\"", "[0,0,20]",
                           "1e308", "circle", "", "=", "[1,[2]]", "{a=1}"])
_settings = hs.lists(hs.tuples(_keys, _values).map(lambda kv: "=".join(kv)) | hs.text(max_size=12), min_size=1,
                     max_size=4)


def _parsed_or_rejected(action, settings_, vehicle=None):
    got = parse_cli(action, settings_, vehicle=vehicle)
    assert isinstance(got, (Rejected, BY_CLI[action])), got
    if isinstance(got, Rejected) and got.field:  # named as typed: never path.waypoints, link.loss
        typed = any(x.startswith(f"{action}.") for x in settings_)  # `gs link link.=1`: the user's own word
        assert typed or not got.field.startswith(f"{action}."), got
    if isinstance(got, Rejected) and got.reason.startswith("expected KEY=VALUE"):
        assert "loss=0.3" not in got.reason or action == "link", got  # the example is the command's own
    if isinstance(got, Rejected):
        assert got.reason and (got.field is None or isinstance(got.field, str))


@settings(max_examples=400, deadline=None)
@given(s=_settings)
def test_every_local_check_of_the_settings_is_a_usage_error_never_a_traceback(s):
    """`formation phases=3` (or offsets=[1], or phases.usv1=1 phases=2) raised AttributeError: a
    traceback and exit 1 (read as 'rejected by the fleet'); `gains k=1 k.x=2` a TypeError."""
    for action in ("formation", "link", "radio", "gains"):
        _parsed_or_rejected(action, s)
    _parsed_or_rejected("path", s, "uav1")
    _parsed_or_rejected("gains", s, "usv1")


@pytest.mark.parametrize("args", [["formation", "phases=3"], ["formation", "offsets=[1]"],
                                  ["formation", "phases.usv1=1", "phases=2"], ["gains", "k=1", "k.x=2"]])
def test_the_cases_found_exit_2_with_nothing_sent(args, capsys):
    # no router at this port: a usage error is found before connecting
    assert main(["--fleet", "f", "-e", "tcp/127.0.0.1:9", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: command line: ") and "Traceback" not in err


def test_snapshot_files_two_writers_a_users_tmp_and_a_symlink(tmp_path):
    """`cdus gs snapshot FILE` (cdus.files.write_json): two ground stations saving to one FILE
    shared FILE.tmp, and one's rename failed at random ('could not write the snapshot', exit 2;
    measured 25 of 600 writes in two processes); a FILE.tmp of the user's was overwritten and
    removed; a FILE that is a symlink was replaced by a file (its target unchanged)."""
    import json
    import multiprocessing as mp
    import os
    import stat

    target = tmp_path / "state.json"
    mine = tmp_path / "state.json.tmp"
    mine.write_text("the user's own")
    with mp.get_context("fork").Pool(2) as pool:
        errors = pool.map(_write_many, [(str(target), k) for k in (1, 2)])
    assert errors == [[], []]
    assert json.loads(target.read_text())["who"] in (1, 2) and mine.read_text() == "the user's own"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.json", "state.json.tmp"]  # no temp left
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~_umask_now()
    link = tmp_path / "latest.json"
    link.symlink_to(target)
    from cdus.files import write_json
    write_json(link, {"who": 3})
    assert link.is_symlink() and json.loads(target.read_text()) == {"who": 3}
    assert os.readlink(link) == str(target)


def _umask_now() -> int:
    import os
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _write_many(arg) -> list[str]:
    from cdus.files import write_json
    path, k = arg
    errors = []
    for _ in range(300):
        try:
            write_json(path, {"who": k, "pad": "x" * 100_000})
        except OSError as e:
            errors.append(repr(e))
    return errors[:3]


@pytest.mark.parametrize("name", ["", "-"])
def test_snapshot_to_no_file_name_is_a_usage_error(name, capsys, tmp_path, monkeypatch):
    """`snapshot -` wrote a file named '-' in the working directory; `snapshot ''` said 'could
    not write the snapshot to : Is a directory (.)' after connecting."""
    monkeypatch.chdir(tmp_path)
    assert main(["--fleet", "f", "-e", "tcp/127.0.0.1:9", "snapshot", name]) == 2
    assert "names no file" in capsys.readouterr().err and not list(tmp_path.iterdir())


WATCH_INTO_A_CLOSED_PIPE = """
import sys
import ground_station.__main__ as gm
from cdus.wire.transport import Transport

class FakeGS:
    fleet = "f"
    def __init__(self, *a, **k): pass
    def open(self, watch=True): pass
    def wait_for_status(self, t): return True
    def fetch_last(self): return 0
    def events_since(self, seen): return [], seen
    def snapshot(self): return {"v": 1, "kind": "status", "pad": "x" * 5000}
    def world_gone(self): return False
    def close(self): pass
    view = type("V", (), {"world": None})()

gm.GroundStation = FakeGS
sys.exit(gm.main(["--fleet", "f", "-e", "tcp/127.0.0.1:9", "watch", "--jsonl", "--interval", "0.01"]))
"""


def test_watch_into_a_pipe_whose_reader_left_ends_quietly():
    """`cdus gs watch --jsonl | head -n 2`: a BrokenPipeError traceback, exit 1 (seen against a
    realtime fleet). Now it ends, exit 0, nothing on stderr."""
    import os
    import subprocess
    import sys

    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    p = subprocess.Popen([sys.executable, "-c", WATCH_INTO_A_CLOSED_PIPE], cwd=root, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, start_new_session=True)
    try:
        p.stdout.readline()
        p.stdout.close()  # the reader leaves, as head does
        _, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, 9)
            p.wait()
    assert p.returncode == 0 and b"Traceback" not in err, err.decode()
