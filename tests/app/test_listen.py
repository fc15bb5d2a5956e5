"""`cdus launch --listen` on an endpoint the router cannot take: a usage error (exit 2) that
names the endpoint and says nothing was started, not a traceback; no process, no run
directory left behind."""

from __future__ import annotations

import os
import socket
import subprocess
import sys

import psutil
import pytest

from cdus.app import cli
from cdus.app.launcher import ListenError, check_listen, listen_problem


@pytest.fixture
def busy():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        yield f"tcp/127.0.0.1:{s.getsockname()[1]}"


def test_a_busy_port_is_named_and_a_free_one_passes(busy):
    assert "already in use" in listen_problem(busy)
    with pytest.raises(ListenError, match=busy.replace(".", r"\.")):
        check_listen(["tcp/127.0.0.1:0", busy])
    check_listen(["tcp/127.0.0.1:0", "unixsock-stream//tmp/x.sock"])  # port 0, a socket file: Zenoh's to say


def test_launch_on_a_busy_port_is_a_usage_error_and_starts_nothing(busy, tmp_path):
    run = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=os.getcwd())
    r = subprocess.run([sys.executable, "-m", "cdus", "launch", "configs/lake_circle.toml", "--listen", busy,
                        "--logs", str(run), "--rerun", "off", "-q"], capture_output=True, text=True, env=env,
                       timeout=120)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr + r.stdout
    assert f"--listen: the router cannot listen on {busy}: " in r.stderr and "nothing was started." in r.stderr
    assert not run.exists()  # no run directory, no credentials


def test_a_port_taken_after_the_check_is_still_a_usage_error(busy, tmp_path, monkeypatch, capsys):
    """The router's own failure to listen (the port taken between the check and the start)."""
    monkeypatch.setattr(cli, "check_listen", lambda eps: None)
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    run = tmp_path / "run"
    assert cli.main(["launch", "configs/lake_circle.toml", "--listen", busy, "--logs", str(run), "--rerun", "off",
                     "-q"]) == 2
    err = capsys.readouterr().err
    assert f"the router cannot listen on {busy}: " in err and "nothing was started." in err
    assert {p.pid for p in psutil.Process().children(recursive=True)} <= before
    assert not run.exists()  # the directory this command made (credentials) is gone
