"""The command line: how flags and the scenario file combine (no process is started here)."""

from __future__ import annotations

import pytest

from cdus.app.cli import build_parser, launch_options, main
from cdus.scenario.config import ConfigError, load_scenario
from cdus.scenario.model import RESTART_POLICIES

CONFIG = "configs/lake_circle.toml"


def options(*flags: str, **overrides):
    args = build_parser().parse_args(["launch", CONFIG, *flags])
    return args, launch_options(args, load_scenario(CONFIG, overrides))


def test_the_restart_policy_comes_from_the_scenario_unless_the_flag_is_given():
    args, opts = options()
    assert args.restart is None and opts.restart == "never"
    _, opts = options(**{"supervision.restart": "always"})
    assert opts.restart == "always"
    _, opts = options("--restart", "on-failure", **{"supervision.restart": "always"})
    assert opts.restart == "on-failure"


def test_the_restart_flag_takes_the_scenarios_vocabulary(capsys):
    for policy in RESTART_POLICIES:
        assert build_parser().parse_args(["launch", CONFIG, "--restart", policy]).restart == policy
    with pytest.raises(SystemExit):
        build_parser().parse_args(["launch", CONFIG, "--restart", "sometimes"])
    assert "invalid choice: 'sometimes'" in capsys.readouterr().err


def test_other_launch_options_come_from_the_flags():
    _, opts = options("--fleet", "f1", "--clock", "realtime", "--duration", "5", "--policy", "extrapolate")
    assert (opts.fleet, opts.clock, opts.duration, opts.policy) == ("f1", "realtime", 5.0, "extrapolate")
    _, opts = options()
    assert opts.fleet == "lake_circle" and opts.metrics_out is None


def test_remote_vehicles_are_checked_and_take_router_links():
    _, opts = options()
    assert opts.remote == () and opts.links == "router"  # the default
    _, opts = options("--remote", "usv1,usv2", "--remote", "uav3", "--remote", "usv1")
    assert opts.remote == ("usv1", "usv2", "uav3") and opts.links == "router"
    with pytest.raises(ConfigError, match=r"--remote: no vehicle 'usv9' in lake_circle; ids are usv1, "):
        options("--remote", "usv1,usv9")


@pytest.mark.parametrize("flag", [["--remote", "usv1"], ["--secure"], ["--tls"]])
def test_direct_links_are_refused_where_they_would_skip_the_router(flag):
    _, opts = options(*flag)
    assert opts.links == "router"
    with pytest.raises(ConfigError, match=f"--links: direct links .* with {flag[0]} use --links router"):
        options(*flag, "--links", "direct")


def test_scheduled_faults_after_the_end_are_named_not_silently_skipped(capsys, tmp_path):
    code = main(["sim", "configs/lake_circle.toml", "--rerun", "off", "-q", "--duration", "2",
                 "--metrics-out", str(tmp_path / "m.json"), "--set", 'event=[{at=100.0,action="kill",vehicle="usv2"}]'])
    assert code == 0
    assert "before kill of usv2 at 100 s: not carried out" in capsys.readouterr().err


# ---------------------------------------------------------------- safe by default: who may reach the router

from cdus.wire.transport import Transport, exposed_endpoints, is_local_endpoint  # noqa: E402


@pytest.mark.parametrize("ep", ["tcp/127.0.0.1:7447", "tcp/127.1.2.3:7447", "tcp/[::1]:7447", "tls/127.0.0.1:1",
                                "udp/127.0.0.1:7447#iface=lo", "unixsock-stream//tmp/cdus.sock", "unixpipe/cdus"])
def test_loopback_and_unix_sockets_are_local(ep):
    assert is_local_endpoint(ep)


@pytest.mark.parametrize("ep", ["tcp/0.0.0.0:7447", "tcp/[::]:7447", "tcp/192.168.1.10:7447", "tls/10.0.0.1:7447",
                                "tcp/localhost:7447", "tcp/example.org:7447", "vsock/VMADDR_CID_ANY:7447",
                                "quic/[::ffff:127.0.0.1]:7447"])
def test_wildcards_lan_addresses_and_host_names_are_not(ep):
    assert not is_local_endpoint(ep)


def test_a_router_config_file_without_endpoints_listens_where_zenoh_does_by_default(tmp_path):
    f = tmp_path / "r.json5"
    f.write_text("{}")
    assert exposed_endpoints(Transport(mode="router", config_file=str(f))) == ("tcp/[::]:7447",)
    f.write_text('{listen: {endpoints: ["tcp/127.0.0.1:7447", "tcp/0.0.0.0:7448"]}}')
    assert exposed_endpoints(Transport(mode="router", config_file=str(f))) == ("tcp/0.0.0.0:7448",)
    f.write_text('{listen: {endpoints: {router: ["unixsock-stream//tmp/x.sock"]}}}')
    assert exposed_endpoints(Transport(mode="router", config_file=str(f))) == ()


@pytest.mark.parametrize("flags", [["--listen", "tcp/0.0.0.0:7447"], ["--listen", "tcp/192.168.1.10:7447"],
                                   ["--listen", "tcp/127.0.0.1:7447", "--listen", "tcp/[::]:7447"],
                                   ["--zenoh-config", "EMPTY"]])
def test_a_router_reachable_from_other_hosts_without_credentials_is_a_usage_error(flags, tmp_path, capsys,
                                                                                  monkeypatch):
    import cdus.app.cli as cli

    monkeypatch.setattr(cli, "launch", lambda *a, **k: pytest.fail("a fleet was started"))
    (tmp_path / "empty.json5").write_text("{}")
    flags = [str(tmp_path / "empty.json5") if f == "EMPTY" else f for f in flags]
    runs = tmp_path / "runs"
    assert main(["launch", CONFIG, "--runs-dir", str(runs), "--rerun", "off", *flags]) == 2
    err = capsys.readouterr().err
    assert "which other hosts can reach: add --secure" in err and "--insecure" in err and "nothing was started" in err
    assert not runs.exists()


def test_insecure_is_refused_with_secure_and_says_what_it_allows(tmp_path, capsys, monkeypatch):
    import cdus.app.cli as cli

    assert main(["launch", CONFIG, "--runs-dir", str(tmp_path), "--listen", "tcp/0.0.0.0:7447", "--secure",
                 "--insecure"]) == 2
    assert "--insecure: contradicts --secure" in capsys.readouterr().err
    started = []
    monkeypatch.setattr(cli, "launch", lambda scenario, run, router, opts: (started.append(router), (0, _NoRun(run)))[1])
    main(["launch", CONFIG, "--logs", str(tmp_path / "run"), "--rerun", "off", "--listen", "tcp/192.168.1.10:7447",
          "--insecure"])
    assert started and started[0].listen == ("tcp/192.168.1.10:7447",)
    err = capsys.readouterr().err
    assert "WARNING: --insecure: anyone who reaches tcp/192.168.1.10:7447 can, without any credential: stop" in err
    # on loopback no flag is needed, and the secured router still passes the rule
    started.clear()
    main(["launch", CONFIG, "--logs", str(tmp_path / "run2"), "--rerun", "off", "--listen", "tcp/127.0.0.1:7447"])
    main(["launch", CONFIG, "--logs", str(tmp_path / "run3"), "--rerun", "off", "--listen", "tcp/192.168.1.10:7447",
          "--secure"])
    assert len(started) == 2 and "WARNING" not in capsys.readouterr().err


class _NoRun:
    def __init__(self, run):
        from pathlib import Path

        self.metrics_out = Path(run) / "absent.json"
        self.logs = Path(run) / "logs"
