"""The world in Rerun: sink specs, and a recording read back with rerun.chunk.RrdReader.

The recording is lake_circle for 10 simulated seconds at 50 Hz control: ticks 0..500, so
every per-tick entity (poses, path error, ω̇, coordination error) holds exactly
10 × 50 + 1 = 501 rows, one per control tick, at t = n / 50 s exactly.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
from collections import defaultdict
from pathlib import Path

import numpy as np
import pyarrow as pa

from cdus.wire.schemas import FleetEvent
import pytest
from rerun.chunk import RrdReader

from cdus.scenario.config import load_scenario
from cdus.wire.transport import free_tcp_port
from cdus.sim.fleet import InProcessFleet
from cdus.sim.sink import UPDATE_EVERY, NullSink
from world_sim.recording import DEFAULT_URL, Target, parse_spec
from world_sim.sinks import make_sink

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "configs" / "lake_circle.toml"
DURATION = 10.0
RATE = 50.0
TICKS = int(DURATION * RATE) + 1  # ticks 0..500 inclusive


def rerun_cli(*args: str, **kw) -> subprocess.CompletedProcess:
    """The `rerun` command line of the installed rerun-sdk."""
    return subprocess.run([sys.executable, "-m", "rerun_cli", *args], capture_output=True, text=True, **kw)


class Recording:
    """An .rrd read back: per entity, its static flag, timelines and temporal columns."""

    def __init__(self, path: Path):
        reader = RrdReader(str(path))
        self.stores = reader.recordings()
        self.blueprints = reader.blueprints()
        self.static: set[str] = set()
        self.temporal: dict[str, list[pa.RecordBatch]] = defaultdict(list)
        self.timelines: dict[str, set[str]] = defaultdict(set)
        for chunk in reader.stream(store=self.stores[0]):
            entity = chunk.entity_path.lstrip("/")
            if chunk.is_static:
                self.static.add(entity)
            else:
                self.timelines[entity].update(chunk.timeline_names)
                self.temporal[entity].append(chunk.to_record_batch())

    def rows(self, entity: str) -> int:
        return sum(b.num_rows for b in self.temporal.get(entity, []))

    def column(self, entity: str, name: str) -> tuple[np.ndarray, list]:
        """(sim_time in ns, values) of one component, in time order."""
        times, values = [], []
        for b in self.temporal[entity]:
            times += [int(x.value) for x in b.column(b.schema.names.index("sim_time"))]
            values += b.column(b.schema.names.index(name)).to_pylist()
        order = np.argsort(times, kind="stable")
        return np.array(times)[order], [values[i] for i in order]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """lake_circle, 10 s, in process, saved to an .rrd; plus an event from another thread
    and a link going down and up, as the runners report them."""
    path = tmp_path_factory.mktemp("rec") / "lake.rrd"
    sc = load_scenario(CONFIG, {"scenario.duration": DURATION})
    sink = make_sink(f"save:{path}")
    fleet = InProcessFleet(sc, sink=sink)
    result = fleet.run()
    worker = threading.Thread(target=sink.event,
                              args=(FleetEvent.of(2.5, "vehicle_lost", "vehicle usv2 lost", vehicle="usv2"),))
    worker.start()
    worker.join()
    sink.link_state(2.5, "usv2", "usv1", "down")
    sink.link_state(4.0, "usv2", "usv1", "up")
    sink.close()
    sink.close()  # twice is fine
    return sc, result.recorder, path, Recording(path)


def test_every_vehicle_edge_and_link_has_its_entities(recorded):
    sc, _, _, rec = recorded
    assert len(rec.stores) == 1 and rec.stores[0].application_id == "cdus"
    assert len(rec.blueprints) == 1  # the layout is sent from code
    for v in sc.vehicles:
        assert f"world/paths/{v.id}" in rec.static
        for family in ("world/vehicles", "world/trails", "metrics/path_error", "metrics/omega_rate"):
            assert rec.rows(f"{family}/{v.id}") > 0, (family, v.id)
        marker = ("hull", "bow") if v.kind == "usv" else ("body", "rotors", "nose")
        assert {f"world/vehicles/{v.id}/{part}" for part in marker} <= rec.static
    for e in sc.metric_edges():
        assert rec.rows(f"metrics/coord_error/{e.i}__{e.k}") > 0
    for e in sc.edges:  # i listens to k: ω goes k -> i
        assert rec.rows(f"comms/links/{e.k}__{e.i}") >= 1
    _, texts = rec.column("comms/events", "TextLog:text")
    # the runner's one event; lake_circle's random starts also bring two pairs within 2 m (the sink's own lines)
    assert [t[0] for t in texts if not t[0].startswith("near collision:")] == ["vehicle usv2 lost"]


def test_one_sample_per_control_tick(recorded):
    sc, recorder, _, rec = recorded
    assert len(recorder) == TICKS
    ticks_ns = np.arange(TICKS, dtype=np.int64) * 20_000_000  # t_n = n / 50 s, exact in ns
    per_tick = [f"{family}/{v.id}" for v in sc.vehicles
                for family in ("world/vehicles", "metrics/path_error", "metrics/omega_rate")]
    per_tick += [f"metrics/coord_error/{e.i}__{e.k}" for e in sc.metric_edges()]
    for entity in per_tick:
        assert rec.rows(entity) == TICKS, entity
    for j, v in enumerate(sc.vehicles):
        t, pe = rec.column(f"metrics/path_error/{v.id}", "Scalars:scalars")
        np.testing.assert_array_equal(t, ticks_ns)
        np.testing.assert_array_equal([x[0] for x in pe], recorder.view("path_error")[:, j])
        _, rate = rec.column(f"metrics/omega_rate/{v.id}", "Scalars:scalars")
        np.testing.assert_array_equal([x[0] for x in rate], recorder.view("omega_rate")[:, j])
        _, xyz = rec.column(f"world/vehicles/{v.id}", "Transform3D:translation")
        np.testing.assert_allclose(np.array([x[0] for x in xyz]), recorder.view("q")[:, j], atol=1e-4)
    for m, e in enumerate(recorder.edges):
        _, ce = rec.column(f"metrics/coord_error/{e.name}", "Scalars:scalars")
        np.testing.assert_allclose([x[0] for x in ce], recorder.edge_error()[:, m], rtol=0, atol=1e-12)


def test_an_edge_with_an_end_not_live_has_no_error_in_the_recording(tmp_path):
    """Issue 27: a killed vehicle's edges kept an error in the recording while it was dead (its
    frozen ω against the live ones: growing to ~10 rad), which the metrics leave out. Now each
    such tick is an empty row (a gap in the plot); the others are the recorder's errors."""
    cfg = tmp_path / "kill.toml"
    cfg.write_text(CONFIG.read_text().replace("duration = 250.0", "duration = 6.0") + """
[[event]]
at = 2.0
action = "kill"
vehicle = "usv2"

[[event]]
at = 4.0
action = "restart"
vehicle = "usv2"
""")
    path = tmp_path / "kill.rrd"
    sink = make_sink(f"save:{path}")
    res = InProcessFleet(load_scenario(cfg), sink=sink).run()
    sink.close()
    rec, recorder = Recording(path), res.recorder
    live, err = recorder.view("live"), recorder.edge_error()
    assert not live[150, 1] and live[150].sum() == 5  # usv2 dead from 2 s to 4 s
    touching = 0
    for m, e in enumerate(recorder.edges):
        t, ce = rec.column(f"metrics/coord_error/{e.name}", "Scalars:scalars")
        assert len(t) == len(recorder)  # a row every tick, empty where an end is not live
        both = live[:, e.i] & live[:, e.k]
        assert [len(x) for x in ce] == [1 if b else 0 for b in both], e.name
        np.testing.assert_array_equal([x[0] for x in ce if x], err[both, m])
        touching += not both.all()
    assert touching == 2  # usv2's two edges of the ring


def test_usv_heading_and_uav_altitude(recorded):
    sc, recorder, _, rec = recorded
    for j, v in enumerate(sc.vehicles):
        _, quat = rec.column(f"world/vehicles/{v.id}", "Transform3D:quaternion")
        yaw = np.array([2 * np.arctan2(x[0][2], x[0][3]) for x in quat])
        np.testing.assert_allclose(np.angle(np.exp(1j * (yaw - recorder.view("heading")[:, j]))), 0, atol=1e-5)
        if v.kind == "usv":
            assert np.all(recorder.view("q")[:, j, 2] == 0.0)  # on the water
        else:  # a line from the drone down to z = 0, in its own frame
            _, strips = rec.column(f"world/vehicles/{v.id}", "LineStrips3D:strips")
            drop = np.array([s[0][1][2] for s in strips])
            np.testing.assert_allclose(drop, -recorder.view("q")[:, j, 2], rtol=1e-6)


def test_the_timeline_is_sim_time_as_a_duration(recorded):
    _, _, _, rec = recorded
    assert rec.temporal
    for entity, batches in rec.temporal.items():
        assert "sim_time" in rec.timelines[entity], entity
        for b in batches:
            assert b.schema.field("sim_time").type == pa.duration("ns"), entity
    # the batched columns carry sim_time only; rr.log'd events and link changes add log_time
    assert rec.timelines["metrics/path_error/usv1"] == {"sim_time"}


def test_paths_and_markers_are_static(recorded):
    sc, _, _, rec = recorded
    for v in sc.vehicles:
        assert f"world/paths/{v.id}" in rec.static
        assert f"world/paths/{v.id}" not in rec.temporal
    assert "world" in rec.static  # z up


def test_trails_every_update_and_at_the_end(recorded):
    sc, recorder, _, rec = recorded
    expected = len(range(0, TICKS, UPDATE_EVERY)) + (0 if (TICKS - 1) % UPDATE_EVERY == 0 else 1)
    for j, v in enumerate(sc.vehicles):
        assert rec.rows(f"world/trails/{v.id}") == expected
        t, strips = rec.column(f"world/trails/{v.id}", "LineStrips3D:strips")
        assert t[-1] == (TICKS - 1) * 20_000_000
        np.testing.assert_allclose(strips[-1][0][-1], recorder.view("q")[-1, j], atol=1e-4)  # ends at the vehicle


def test_events_and_link_changes_on_sim_time(recorded):
    _, _, _, rec = recorded
    t, text = rec.column("comms/events", "TextLog:text")
    _, level = rec.column("comms/events", "TextLog:level")
    mine = [k for k, x in enumerate(text) if not x[0].startswith("near collision:")]  # not the sink's own lines
    assert [text[k] for k in mine] == [["vehicle usv2 lost"]] and t[mine].tolist() == [2_500_000_000]  # from a thread
    assert [level[k] for k in mine] == [["WARN"]]
    t, state = rec.column("comms/links/usv2__usv1", "StateChange:state")
    assert state == [["up"], ["down"], ["up"]]
    assert t.tolist() == [0, 2_500_000_000, 4_000_000_000]
    assert "comms/links/usv2__usv1" in rec.static  # the colours of up / lossy / down


def test_rerun_rrd_verify_accepts_the_file(recorded):
    path = recorded[2]
    r = rerun_cli("rrd", "verify", str(path))
    assert r.returncode == 0, r.stdout + r.stderr


def test_close_after_ctrl_c_keeps_every_recorded_tick(tmp_path):
    sc = load_scenario(CONFIG, {"scenario.duration": DURATION})
    path = tmp_path / "interrupted.rrd"
    sink = make_sink(f"save:{path}")
    fleet = InProcessFleet(sc, sink=sink)
    step = fleet.step

    def interrupted_step():
        if fleet.tick == 260:
            raise KeyboardInterrupt
        step()

    fleet.step = interrupted_step
    with pytest.raises(KeyboardInterrupt):
        fleet.run()
    sink.close()
    assert rerun_cli("rrd", "verify", str(path)).returncode == 0
    rec = Recording(path)
    assert rec.rows("metrics/path_error/usv1") == 260  # ticks 0..259, the last ones sent by close()
    assert rec.rows("world/vehicles/uav3") == 260


# --------------------------------------------------------------------------- specs


def test_off_gives_the_null_sink():
    assert isinstance(make_sink("off"), NullSink)
    assert isinstance(make_sink(None), NullSink)
    assert parse_spec("") == ()


@pytest.mark.parametrize("spec", ["bogus", "save:", "save", "off,save:x.rrd", "connect:http://host:9876",
                                  "spawn:9876", "auto:x"])
def test_a_bad_spec_names_the_valid_forms(spec):
    with pytest.raises(ValueError) as e:
        make_sink(spec)
    assert "valid forms: off | auto | spawn | save:PATH | connect[:URL]" in str(e.value)


def test_spec_forms(tmp_path):
    no_display: dict[str, str] = {}
    x11 = {"DISPLAY": ":0"}
    assert parse_spec("save:a.rrd", env=no_display) == (Target("save", "a.rrd"),)
    assert parse_spec("connect", env=no_display) == (Target("connect", DEFAULT_URL),)
    assert parse_spec("connect:", env=no_display) == (Target("connect", DEFAULT_URL),)
    assert parse_spec("connect:rerun+http://10.0.0.2:9000/proxy", env=no_display) == (
        Target("connect", "rerun+http://10.0.0.2:9000/proxy"),)
    assert parse_spec("spawn, save:a.rrd", env=x11) == (Target("spawn"), Target("save", "a.rrd"))
    assert parse_spec("auto", tmp_path, env=x11) == (Target("spawn"),)
    assert parse_spec("auto", tmp_path, env={"WAYLAND_DISPLAY": "wayland-0"}) == (Target("spawn"),)
    assert parse_spec("auto", tmp_path, env=no_display) == (Target("save", str(tmp_path / "recording.rrd")),)
    if sys.platform.startswith("linux"):
        with pytest.raises(ValueError, match="spawn needs a display"):
            parse_spec("spawn", env=no_display)


def test_auto_without_a_display_saves_into_the_run_dir(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    if sys.platform in ("darwin", "win32"):
        pytest.skip("a desktop always has a display")
    sink = make_sink("auto", tmp_path)
    sink.close()
    path = tmp_path / "recording.rrd"
    assert path.exists()
    assert f"rerun {path}" in capsys.readouterr().out  # the command that opens it


def test_connect_to_nobody_warns_and_does_not_block(tmp_path, capsys):
    port = free_tcp_port()
    sink = make_sink(f"connect:rerun+http://127.0.0.1:{port}/proxy,save:{tmp_path / 'x.rrd'}")
    sink.close()
    assert "no Rerun viewer listens" in capsys.readouterr().err
    assert rerun_cli("rrd", "verify", str(tmp_path / "x.rrd")).returncode == 0


# --------------------------------------------------------------------------- processes


@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # `rerun --save` writes none
def test_viewer_and_file_at_once(tmp_path):
    """`connect:URL,save:PATH` tees the stream: a gRPC receiver (`rerun --save`, no window)
    and the file both get every row."""
    import rerun_cli

    port = free_tcp_port()
    received = tmp_path / "received.rrd"
    server = subprocess.Popen([os.path.join(os.path.dirname(rerun_cli.__file__), "rerun"), "--save", str(received),
                               "--bind", "127.0.0.1", "--port", str(port)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        _wait_for_port(port, server)
        sc = load_scenario(CONFIG, {"scenario.duration": 2.0})
        sink = make_sink(f"connect:rerun+http://127.0.0.1:{port}/proxy,save:{tmp_path / 'file.rrd'}")
        InProcessFleet(sc, sink=sink).run()
        sink.close()  # flushes both sinks
        server.send_signal(signal.SIGINT)  # `rerun --save` finishes its file
        server.wait(timeout=20)
    finally:
        if server.poll() is None:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait()
    ticks = int(2.0 * RATE) + 1
    assert Recording(tmp_path / "file.rrd").rows("metrics/path_error/usv1") == ticks
    assert Recording(received).rows("metrics/path_error/usv1") == ticks


def test_cdus_sim_writes_a_verifiable_recording(tmp_path):
    rrd, metrics = tmp_path / "sim.rrd", tmp_path / "m.json"
    proc = subprocess.run([sys.executable, "-m", "cdus.app.cli", "sim", str(CONFIG), "--duration", "5",
                           "--rerun", f"save:{rrd}", "-q", "--metrics-out", str(metrics)],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert metrics.exists()
    assert rerun_cli("rrd", "verify", str(rrd)).returncode == 0
    rec = Recording(rrd)
    assert rec.rows("metrics/coord_error/usv1__usv2") == int(5 * RATE) + 1


def _wait_for_port(port: int, proc: subprocess.Popen, timeout: float = 30.0) -> None:
    """Until something accepts on 127.0.0.1:port (readiness by observation, not a sleep)."""
    import time

    deadline = time.monotonic() + timeout
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
            return
        except OSError:
            if proc.poll() is not None or time.monotonic() > deadline:
                raise AssertionError(f"nothing listens on {port} (rc {proc.poll()})")
            time.sleep(0.05)


# --------------------------------------------------------------------------- crashes and full disks

# A child that records lake_circle in process, for a long time, in segments of 2 simulated
# seconds; it prints "started" once the sink is set up and "done" if it ends.
RECORDING_CHILD = r"""
import sys
from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from world_sim.recording import Target
from world_sim.rerun_sink import RerunSink
path, duration, segment = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
if len(sys.argv) > 4:  # a file-size limit: writes past it fail with EFBIG (SIGXFSZ ignored)
    import resource, signal
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    limit = int(sys.argv[4])
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
sc = load_scenario(sys.argv[5] if len(sys.argv) > 5 else "configs/lake_circle.toml", {"scenario.duration": duration})
sink = RerunSink([Target("save", path)], segment_every=segment, flush_every=1.0)
sink.on_stop = lambda text: print("on_stop:", text, flush=True)  # the world makes it an event
print("started", flush=True)
result = InProcessFleet(sc, sink=sink).run()
sink.close()
print("done", len(result.recorder), flush=True)
"""


def _child(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", RECORDING_CHILD, *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def test_a_sigkilled_recorder_leaves_verifiable_segments_with_all_but_the_last_seconds(tmp_path):
    import time

    path = tmp_path / "crash.rrd"
    parts = tmp_path / "crash.rrd.parts"
    proc = _child(str(path), "100000", "2.0")
    try:
        deadline = time.monotonic() + 120
        while len(list(parts.glob("*.rrd"))) < 3:  # three closed segments: 6 simulated seconds
            assert proc.poll() is None, proc.stderr.read()
            assert time.monotonic() < deadline, "no segments"
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert not path.exists()  # never merged: the run did not end
    segments = sorted(parts.glob("*.rrd"))
    assert len(segments) >= 3  # a segment cut short by the kill is a .partial, never a broken .rrd
    for seg in segments:
        r = rerun_cli("rrd", "verify", str(seg))
        assert r.returncode == 0, (seg, r.stdout + r.stderr)
    ticks = []
    for seg in segments:
        rec = Recording(seg)
        if "metrics/path_error/usv1" in rec.temporal:
            t, _ = rec.column("metrics/path_error/usv1", "Scalars:scalars")
            ticks += (t // 20_000_000).tolist()
    assert sorted(ticks) == list(range(len(ticks))) and len(ticks) >= 6 * 50  # every tick from 0, no gap
    assert "world/paths/usv1" in Recording(segments[0]).static  # the scene is in the first segment


def test_segments_merge_into_one_file_on_a_clean_close(tmp_path):
    path = tmp_path / "clean.rrd"
    proc = _child(str(path), "9", "2.0")
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert not (tmp_path / "clean.rrd.parts").exists()
    assert rerun_cli("rrd", "verify", str(path)).returncode == 0
    rec = Recording(path)
    assert rec.rows("metrics/path_error/usv1") == 9 * 50 + 1 and len(rec.blueprints) == 1
    assert "world/paths/usv1" in rec.static


def test_a_write_that_fails_stops_the_recording_with_one_warning_and_the_run_goes_on(tmp_path):
    path = tmp_path / "full.rrd"
    proc = _child(str(path), "60", "2.0", str(150_000))  # a 150 kB file-size limit: a few seconds of lake_circle
    out, err = proc.communicate(timeout=180)
    assert proc.returncode == 0, err
    assert "done 3001" in out  # every tick of the run
    assert err.count("warning: the Rerun recording stopped") == 1, err
    assert "Traceback" not in err
    # told to its owner too (issue 27: only world.log said it): once, with the file and why
    assert out.count("on_stop: ") == 1 and f"on_stop: the Rerun recording into {path} stopped: File too large; the " \
        f"run goes on" in out, out
    for seg in (tmp_path / "full.rrd.parts").glob("*.rrd"):  # what was closed before the failure is readable
        assert rerun_cli("rrd", "verify", str(seg)).returncode == 0, seg


def test_a_recording_that_fails_at_its_first_segment_names_nothing_as_recorded(tmp_path):
    """Seen with `cdus sim --metrics-out` on a full 64 KiB tmpfs: "What was recorded before stays
    readable: rerun FULL/recording.rrd.parts/*.rrd" for a directory left empty, a glob of nothing."""
    path = tmp_path / "none.rrd"
    proc = _child(str(path), "3", "2.0", "1000")  # 1 kB: the first segment (the scene) cannot be written
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert err.count("warning: the Rerun recording stopped") == 1, err
    assert "Nothing was recorded before it" in err and "stays readable" not in err, err
    assert "(nothing was recorded)" in out and "what was recorded before" not in out, out
    assert not (tmp_path / "none.rrd.parts").exists() and not path.exists()


def test_a_full_disk_warns_at_the_start_and_stops_the_recording_cleanly(tmp_path):
    mount = tmp_path / "tiny"
    mount.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=300k", "tmpfs", str(mount)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        proc = _child(str(mount / "disk.rrd"), "60", "2.0")
        out, err = proc.communicate(timeout=180)
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True)
    assert proc.returncode == 0, err
    assert "done 3001" in out
    assert "MB free on the disk of" in err and "expected to record about" in err  # the start check
    assert err.count("warning: the Rerun recording stopped") == 1, err
    assert "Traceback" not in err


def test_the_start_check_compares_free_space_with_the_expected_size(tmp_path, monkeypatch, capsys):
    import world_sim.rerun_sink as sink_module

    sc = load_scenario(CONFIG, {"scenario.duration": 120.0})
    need = sink_module.expected_bytes(6, 120.0)
    assert need == 6 * 120 * sink_module.BYTES_PER_VEHICLE_SECOND
    monkeypatch.setattr(sink_module, "_free_bytes", lambda where: 2 * need - 1)
    sink = make_sink(f"save:{tmp_path / 'a.rrd'}")
    sink.start(sc)
    assert "expected to record about 5.8 MB" in capsys.readouterr().err
    monkeypatch.setattr(sink_module, "_free_bytes", lambda where: 2 * need)
    sink2 = make_sink(f"save:{tmp_path / 'b.rrd'}")
    sink2.start(sc)
    assert "free on the disk" not in capsys.readouterr().err
    sink.close()
    sink2.close()


def test_the_recording_line_says_what_exists(tmp_path):
    """Issue 27, broken 2: the launcher printed a recording.rrd path that did not exist (a disk
    that filled, a SIGKILLed world). It says what there is: the file, its segments, or none."""
    from world_sim.recording import recording_line

    rrd = tmp_path / "recording.rrd"
    assert recording_line(rrd) == f"  recording: none; {rrd} was not written (the world's log says why)"
    parts = tmp_path / "recording.rrd.parts"
    parts.mkdir()
    assert "none" in recording_line(rrd)  # an empty parts directory holds nothing
    (parts / "000.rrd").write_bytes(b"x")
    (parts / "001.rrd").write_bytes(b"x")
    assert recording_line(rrd) == (f"  recording: {rrd} was not written; what was recorded is in 2 segments (open "
                                   f"them with: rerun {parts}/*.rrd; the world's log says why)")
    rrd.write_bytes(b"")  # cut at zero bytes: not a recording
    assert "was not written" in recording_line(rrd)
    rrd.write_bytes(b"rrd")
    assert recording_line(rrd) == f"  recording: {rrd} (open it with: rerun {rrd})"
