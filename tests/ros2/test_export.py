"""`cdus export RUN_DIR --mcap FILE`: a run's trace as ROS 2 messages, read back with the mcap and
mcap-ros2-support readers and imported by Rerun's MCAP importer."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from cdus.app.cli import main as cdus_main
from cdus.ros2.export import ExportError, export_mcap, speeds
from cdus.ros2.fleet import topics
from cdus.scenario.config import load_scenario
from tests.e2e.conftest import ROOT

CONFIG = ROOT / "configs" / "lake_circle.toml"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A 4 s lake_circle run (cdus sim: the same trace a lockstep fleet writes, to the bit) with an
    event in its metrics, and its MCAP export."""
    d = tmp_path_factory.mktemp("run")
    assert cdus_main(["sim", str(CONFIG), "--duration", "4", "-q", "--rerun", "off", "--set", "ros2.rate=5",
                      "--trace-out", str(d / "trace.npz"), "--metrics-out", str(d / "metrics.json")]) == 0
    m = json.loads((d / "metrics.json").read_text())
    m["events"] = [{"t": 1.0, "kind": "fleet", "text": "fleet paused by gs", "severity": "info"}]
    (d / "metrics.json").write_text(json.dumps(m))
    scenario = load_scenario(CONFIG, {"ros2.rate": 5.0})
    counts = export_mcap(d, d / "run.mcap", scenario=scenario)
    return d, scenario, counts


def read(path):
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        schemas = {c.topic: (summary.schemas[c.schema_id].name, summary.schemas[c.schema_id].encoding,
                             c.message_encoding) for c in summary.channels.values()}
        msgs: dict[str, list] = {}
        for _, channel, message, decoded in reader.iter_decoded_messages():
            msgs.setdefault(channel.topic, []).append((message.log_time, decoded))
    return schemas, msgs


def test_every_topic_with_its_schema_and_the_trace_values(run):
    d, scenario, counts = run
    schemas, msgs = read(d / "run.mcap")
    assert schemas == {t.name: (t.type_name, "ros2msg", "cdr") for t in topics(scenario.ros2, scenario.ids)}
    trace = np.load(d / "trace.npz")
    clocks = [m.clock.sec * 10**9 + m.clock.nanosec for _, m in msgs["/clock"]]
    assert clocks == [round(t * 1e9) for t in trace["t"]]  # every control tick, in order
    assert [at for at, _ in msgs["/clock"]] == clocks  # log time = simulated time
    poses = msgs["/cdus/usv2/pose"]
    assert len(poses) == 4 * 5 + 1  # 5 Hz over 4 s, both ends
    k = 50  # 1 s: row 50 at 50 Hz
    _, p = poses[5]
    assert (p.pose.position.x, p.pose.position.y) == tuple(trace["q"][k, 1, :2])
    assert p.header.stamp.sec == 1 and p.header.frame_id == "world"
    _, o = msgs["/cdus/uav1/odom"][5]
    assert o.pose.pose.position.z == trace["q"][k, 3, 2] and o.child_frame_id == "uav1/base_link"
    assert o.twist.twist.linear.x == pytest.approx(np.linalg.norm(trace["q"][k + 1, 3] - trace["q"][k, 3]) * 50)
    assert o.twist.twist.angular.z == pytest.approx((trace["heading"][k, 3] - trace["heading"][k - 1, 3]) * 50)
    assert msgs["/cdus/usv1/omega"][5][1].data == trace["omega"][k, 0]
    assert len(msgs["/tf"]) == 6 * 21 and {tr.child_frame_id for _, m in msgs["/tf"] for tr in m.transforms} == \
        {f"{v}/base_link" for v in scenario.ids}
    assert len(msgs["/cdus/usv1/path"]) == 1 and len(msgs["/cdus/usv1/path"][0][1].poses) == 401
    assert [(at, json.loads(m.data)["text"]) for at, m in msgs["/cdus/events"]] == [(10**9, "fleet paused by gs")]
    assert counts["/clock"] == 201 and sum(counts.values()) == sum(len(v) for v in msgs.values())


def test_rerun_imports_it(run, tmp_path):
    d, scenario, _ = run
    rrd = tmp_path / "run.rrd"
    subprocess.run([sys.executable, "-m", "rerun", "mcap", "convert", str(d / "run.mcap"), "-o", str(rrd)],
                   check=True, capture_output=True, timeout=120)
    printed = subprocess.run([sys.executable, "-m", "rerun", "rrd", "print", str(rrd)], check=True,
                             capture_output=True, text=True, timeout=120).stdout
    assert all(t.name in printed for t in topics(scenario.ros2, scenario.ids) if t.field != "events")


def test_a_run_without_a_trace_says_how_to_get_one(tmp_path, capsys):
    with pytest.raises(ExportError, match=r"run the fleet with --trace-out .*trace.npz"):
        export_mcap(tmp_path, tmp_path / "x.mcap")
    np.savez(tmp_path / "trace.npz", ids=np.array(["a"]))
    with pytest.raises(ExportError, match="no scenario.json .* give --config FILE"):
        export_mcap(tmp_path, tmp_path / "x.mcap")
    assert cdus_main(["export", str(tmp_path / "nothing"), "--mcap", str(tmp_path / "x.mcap")]) == 2
    assert "no trace at" in capsys.readouterr().err
    lost = tmp_path / "lost"  # a SIGKILLed world: asked for a trace, never wrote it (the launcher's metrics)
    lost.mkdir()
    (lost / "metrics.json").write_text(json.dumps({"completed": False, "completion": "world_lost"}))
    with pytest.raises(ExportError, match=r"the world process was lost before the run's end .* end only"):
        export_mcap(lost, tmp_path / "x.mcap")


def _spoil(d, tmp_path, how):
    """A copy of the run in ``d`` with its trace (or the output) spoiled as ``how`` says."""
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "metrics.json").write_text((d / "metrics.json").read_text())
    whole = (d / "trace.npz").read_bytes()
    arrays = dict(np.load(d / "trace.npz"))
    if how == "truncated":
        (bad / "trace.npz").write_bytes(whole[:len(whole) // 2])
    elif how == "empty":
        (bad / "trace.npz").write_bytes(b"")
    elif how == "a directory":
        (bad / "trace.npz").mkdir()
    elif how in ("no q", "t not finite", "t past a stamp", "rows cut"):
        if how == "no q":
            del arrays["q"]
        elif how == "rows cut":
            arrays["q"] = arrays["q"][:-3]
        else:
            arrays["t"] = arrays["t"].copy()
            arrays["t"][3] = np.nan if how == "t not finite" else 1e300
        np.savez(bad / "trace.npz", **arrays)
    else:
        (bad / "trace.npz").write_bytes(whole)
    return bad


@pytest.mark.parametrize("how, said", [
    ("truncated", "not a cdus trace"), ("empty", "not a cdus trace"), ("no q", "not a cdus trace: no q"),
    ("rows cut", "q has shape"), ("t not finite", "not finite"), ("t past a stamp", "int32"),
    ("a directory", "cannot read the trace"), ("out is a directory", "cannot write"),
    ("out on a read-only path", "cannot write"),
])
def test_a_corrupt_run_or_an_unwritable_output_is_said_not_a_traceback(run, tmp_path, capsys, how, said):
    """Before: a truncated or empty trace.npz was a zipfile/EOFError traceback, a time that is NaN
    or past int32 seconds a ValueError/struct traceback mid-file, an --mcap that cannot be written
    an OSError traceback. Each is an error naming the file, exit 2, no half .mcap left."""
    d, scenario, _ = run
    bad = _spoil(d, tmp_path, how)
    out = tmp_path / "x.mcap"
    if how == "out is a directory":
        out.mkdir()
    elif how == "out on a read-only path":
        out = bad / "trace.npz" / "x.mcap"  # under a file: ENOTDIR, as a read-only disk's EROFS
    assert cdus_main(["export", str(bad), "--mcap", str(out), "--config", str(CONFIG)]) == 2
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err, err
    assert not out.is_file()


def test_events_at_times_a_stamp_cannot_carry_are_left_out(run, tmp_path):
    """A metrics.json whose events have a NaN, negative or huge time (hand-edited, corrupt): those
    are left out, not a traceback in the stamp's encoding."""
    d, scenario, _ = run
    bad = _spoil(d, tmp_path, "whole")
    m = json.loads((d / "metrics.json").read_text())
    m["events"] = [{"t": float("nan"), "kind": "x"}, {"t": 1e300, "kind": "y"}, {"t": -5, "kind": "z"},
                   {"t": 1.0, "kind": "fleet", "text": "kept"}]
    (bad / "metrics.json").write_text(json.dumps(m))
    counts = export_mcap(bad, tmp_path / "x.mcap", scenario=scenario)
    assert counts["/cdus/events"] == 1


def test_speeds_are_the_forward_differences():
    q = np.array([[[0.0, 0, 0]], [[3.0, 4, 0]], [[3.0, 4, 1]]])
    assert speeds(q, np.array([0.0, 1.0, 2.0]))[:, 0].tolist() == [5.0, 1.0, 1.0]
