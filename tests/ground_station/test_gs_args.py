"""`cdus gs` arguments, whatever a person types (rev-gs): a usage error (ConfigError, exit 2,
nothing sent), never a traceback."""

from __future__ import annotations

import pytest
from hypothesis import given, settings, strategies as hs

from cdus.scenario.config import ConfigError
from cdus.scenario.link import validate_link
from cdus.sim.radio import radio_change_problem
from ground_station.__main__ import check_gains, formation_fields, main, nested, path_fields

_keys = hs.sampled_from(["phases", "offsets", "phases.usv1", "offsets.usv2", "offsets.usv2.usv1", "k", "c", "k.x",
                         "family", "center", "radius", "loss", "delay.base", "delay", "tx_power", "station", "a.b.c",
                         "", ".", "a..b", "phases.", "x"])
_values = hs.sampled_from(["1", "3", "-1", "nan", "inf", "[1,2]", "[1]", "[]", "{}", "true", "abc", "\"s\"", "[0,0,20]",
                           "1e308", "circle", "", "=", "[1,[2]]", "{a=1}"])
_settings = hs.lists(hs.tuples(_keys, _values).map(lambda kv: "=".join(kv)) | hs.text(max_size=12), min_size=1,
                     max_size=4)


def _only_usage_errors(fn, settings_):
    try:
        fn(settings_)
    except ConfigError:
        pass


@settings(max_examples=400, deadline=None)
@given(s=_settings)
def test_every_local_check_of_the_settings_is_a_usage_error_never_a_traceback(s):
    """`formation phases=3` (or offsets=[1], or phases.usv1=1 phases=2) raised AttributeError: a
    traceback and exit 1 (read as 'rejected by the fleet'); `gains k=1 k.x=2` a TypeError."""
    _only_usage_errors(formation_fields, s)
    _only_usage_errors(path_fields, s)
    _only_usage_errors(lambda x: check_gains(nested(x), None), s)
    _only_usage_errors(lambda x: check_gains(nested(x), "usv1"), s)
    _only_usage_errors(lambda x: validate_link(nested(x), None, "command line"), s)
    _only_usage_errors(lambda x: radio_change_problem(nested(x)), s)


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
