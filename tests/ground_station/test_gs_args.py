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
