"""How does the world stream a run to Rerun? A sink for a viewer and/or an .rrd file.

What goes where (docs/rerun.md; timeline ``sim_time``, a duration):

- ``world/paths/<id>``: the prescribed path, static (one period; a window around the run
  for an open path); USV paths at z = 0. Blue-ish for USVs, orange-ish for UAVs.
- ``world/vehicles/<id>``: a Transform3D per control tick (position, yaw from the
  heading). Static children draw the vehicle in its own frame: a USV is a flat hull
  elongated along its heading with a bow arrow; a UAV a quadrotor cross with rotors.
  A UAV also carries, per tick, a vertical line down to the water (its altitude).
- ``world/trails/<id>``: the last ``TRAIL_SECONDS`` of positions, every ``UPDATE_EVERY`` ticks.
- ``metrics/path_error/<id>``, ``metrics/omega_rate/<id>``, ``metrics/coord_error/<i>__<k>``:
  Scalars, one sample per control tick (the Recorder's rows); SeriesLines styling static.
- ``comms/links/<src>__<dst>``: StateChange ``up | lossy | down``: ``up`` at t = 0 for every
  link of the graph (as the link emulator starts them), then each change the runner reports.
- ``comms/events``: TextLog of the runner's events (vehicles lost and back, faults, link news),
  and of the safety: when a vehicle's filter starts intervening, when a pair first comes
  within the safety radius.
- ``world/safety/interventions`` (with [safety] on): Points3D, a red dot above every vehicle
  whose filter intervened at that tick, labelled with its id; an empty row where none did.
  Only rows where the picture changes are logged. From the Recorder's per-vehicle counts:
  exact per tick in process, as the agents' stats report them in the world.
- ``world/safety/closest/<domain>``: LineStrips3D, the closest approach so far of each domain
  (``usv``, ``uav``, ``uav-usv``: cdus.core.metrics.closest_pairs), a line between the pair at
  that time labelled with the ids, the distance and the time; red below the safety radius.
  Logged at the time of the approach when a batch finds a closer one, so the last one is
  the metrics' ``closest_pairs``.
- ``world/radio/links`` (with [radio]): LineStrips3D at each radio geometry sample, a segment
  from sender to receiver for every link of the graph between live vehicles, coloured by
  its delivery probability (red 0, yellow 0.5, green 1); ``world/radio/station``: the base
  station (station topology); ``metrics/radio_utilisation``: the channel utilisation
  (offered airtime per second) at each sample.

Cost: one ``rr.log`` costs ~70 µs, and every chunk (one entity's rows) ~90 µs of CPU in
Python and Rerun's threads whatever its length, while a 10-vehicle ring computes a
simulated second in ~16 ms. So the per-tick rows are never logged one by one: every
entity's new rows go out together in one Arrow record batch (``rr.send_record_batch``,
one chunk per entity, one call), and updates are coalesced so a batch goes out every
``flush_every`` simulated seconds: at the default 5 s, logging stays under 10% of the
world's CPU (bench/rerun_cost.py; every update, 0.5 s, would cost ~42%). A live viewer
therefore sees data in 5 s steps. ``close()`` sends whatever is left.

A file survives a crash (docs/rerun.md, "After a crash"). Rerun's FileSink writes an .rrd's
footer only when it closes, and after a failed write (a full disk) its flush times out and
its disconnect blocks for good (rerun-sdk 0.41). So files are written by this module: the
stream goes into a Rerun ``BinaryStream``, and every ``segment_every`` simulated seconds
(10 s) one ``read()`` of it, a complete .rrd with its footer, is written to
``PATH.parts/NNN.rrd`` (through ``NNN.rrd.partial`` and a rename, so a segment is either
whole or absent). After a SIGKILL every segment passes ``rerun rrd verify`` and
``rerun PATH.parts/*.rrd`` opens them as one recording (one recording id): all but the last
``segment_every`` seconds survive. A clean ``close()`` merges the segments into PATH and
removes the parts, so a finished run leaves one file as before. A write that fails (ENOSPC,
EFBIG, any OSError) stops the file recording with one warning and the run goes on; free
space is checked at the start against the expected size (:data:`BYTES_PER_VEHICLE_SECOND`).
Live viewers (spawn, connect) get their own RecordingStream with the same recording id.
"""

from __future__ import annotations

import math
import os
import shlex
import socket
import sys
import threading
import uuid
from pathlib import Path
from typing import Any, Sequence
from urllib.parse import urlparse

import numpy as np
import pyarrow as pa
import rerun as rr

from cdus.sim.polyline import pad3 as _pad3, path_polyline
from world_sim import blueprint as bp
from cdus.core.metrics import closest_pairs
from cdus.core.link import LINK_STATES
from cdus.scenario.model import Scenario
from cdus.sim.sink import UPDATE_EVERY
from cdus.wire.schemas import FleetEvent
from world_sim.recording import Target
from world_sim.rerun_draw import (  # noqa: F401 (CLOSEST, INTERVENTIONS, NEAR_COLOUR, intervened, probability_colour: as before)
    APP_ID, CLOSEST, CLOSEST_COLOUR, EDGE_COLOURS, INTERVENTION_COLOUR, INTERVENTIONS, LEVELS, NEAR_COLOUR,
    STATE_COLOURS, STATION_COLOUR, TRAIL_POINTS_EVERY, TRAIL_SECONDS, UTILISATION_COLOUR, _LABELS, _POSITIONS,
    _QUATERNION, _SCALAR, _TRANSLATION, _Layout, _fade, _lists, _strip_lists, _time, _vec_lists, colour,
    intervened, marker_size, probability_colour, trail_indices, yaw_quaternions, OBSTACLE_COLOUR, OBSTACLES,
    obstacle_strips,
)
from world_sim.rerun_files import (  # noqa: F401 (BYTES_PER_VEHICLE_SECOND: as before)
    BYTES_PER_VEHICLE_SECOND, _free_bytes, _parts, _segment, _write_whole, expected_bytes, merge_segments,
)

FLUSH_EVERY = 5.0  # simulated seconds between batches sent to Rerun (bench/rerun_cost.py)
SEGMENT_EVERY = 10.0  # simulated seconds per file segment: what a crash can lose at most

EPISODE_GAP = 1.0  # s without an intervention after which a vehicle's next one is news in the event log


# --------------------------------------------------------------------------- the sink


class RerunSink:
    """Streams a run to Rerun (see the module docstring for the entity layout).

    ``targets`` come from :func:`world_sim.recording.parse_spec`. Thread-safe: the world
    calls ``event`` from its transport threads.
    """

    def __init__(self, targets: Sequence[Target], *, recording_id: str | None = None,
                 flush_every: float = FLUSH_EVERY, out: Any = None, segment_every: float = SEGMENT_EVERY):
        self.flush_every = flush_every
        self.segment_every = segment_every
        self.out = out if out is not None else sys.stdout
        self.files = [Path(t.where) for t in targets if t.kind == "save"]
        #: told (once) why the file recording stopped, besides the warning: the world makes it an
        #: event the launcher and ground stations show while the run goes on
        self.on_stop: Any = None
        self.recording_id = recording_id or f"cdus-{uuid.uuid4().hex[:12]}"
        self._segment = 0  # the number of the next segment to write
        self._segment_t0 = 0.0  # simulated time the data not yet written starts at
        self._blueprint: Any = None
        self._lock = threading.RLock()
        self._closed = False
        self._recorder: Any = None
        self._sent = 0  # recorder rows already sent
        self._t_sent = -math.inf  # time of the last row sent
        self._kinds: dict[str, str] = {}
        self._rate = 50.0  # control rate, from the scenario
        self._link_states: dict[tuple[str, str], str] = {}
        self._layout: _Layout | None = None
        self._safety_on = False  # the scenario's filter is on: interventions are marked
        self._radius = 2.0  # the safety radius (the [safety] table's, or its default)
        self._marks_shown = False  # the last interventions row logged had points
        self._last_intervention: dict[int, float] = {}  # vehicle -> time of its latest intervention
        self._closest: dict[str, float] = {}  # domain -> closest distance logged so far
        self._near: set[str] = set()  # domains already reported within the radius
        self._marker = 1.0
        self._file_rec: rr.RecordingStream | None = None
        self._stream: rr.BinaryStream | None = None
        streams = []
        for f in list(self.files):
            try:
                parts = _parts(f)
                parts.mkdir(parents=True, exist_ok=True)
                for old in [*parts.glob("*.rrd"), *parts.glob("*.rrd.partial")]:
                    old.unlink()  # a previous run's segments under this name
            except OSError as e:
                _warn(f"cannot record into {f}: {e.strerror or e}; the run goes on without the file")
                self.files.remove(f)
        if self.files:
            self._file_rec = rr.RecordingStream(APP_ID, recording_id=self.recording_id)
            self._stream = self._file_rec.binary_stream()
            streams.append(self._file_rec)
        live = rr.RecordingStream(APP_ID, recording_id=self.recording_id)
        sinks = self._live_sinks(targets, live)
        if sinks:
            live.set_sinks(*sinks)
            streams.append(live)
        self.rec = _Tee(streams)  # every log goes to the file stream and the live one
        self._off = not streams  # nowhere to send: log nothing

    def _live_sinks(self, targets: Sequence[Target], live: rr.RecordingStream) -> list[Any]:
        sinks: list[Any] = []
        for t in targets:
            if t.kind == "connect":
                if _reachable(t.where):
                    sinks.append(rr.GrpcSink(t.where))
                else:
                    _warn(f"no Rerun viewer listens at {t.where}; not streaming there (start one with `rerun`)")
            elif t.kind == "spawn":
                try:
                    live.spawn(connect=False, hide_welcome_screen=True)
                    sinks.append(rr.GrpcSink())
                except Exception as e:  # no viewer binary, no window system...
                    _warn(f"could not start a Rerun viewer ({e}); use --rerun save:PATH instead")
        return sinks

    # ------------------------------------------------------------------ Sink
    def start(self, scenario: Scenario) -> None:
        with self._lock:
            if self._closed:
                return
            self._rate = float(scenario.rates.control)
            self._check_space(expected_bytes(len(scenario.vehicles), scenario.duration))
            self.rec.send_recording_name(scenario.name)
            self.rec.log(bp.WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
            rank = {"usv": 0, "uav": 0}
            lines = [path_polyline(v, scenario.duration) for v in scenario.vehicles]
            size = marker_size(lines)
            self._marker = size
            self._safety_on = bool(scenario.safety.enabled)
            self._radius = float(scenario.safety.radius)
            if self._safety_on:
                self.rec.log(INTERVENTIONS, rr.Points3D.from_fields(colors=[INTERVENTION_COLOUR], radii=[0.45 * size],
                                                                  show_labels=False), static=True)
            scene = list(lines)
            for j, o in enumerate(getattr(scenario, "obstacles", ())):  # [[obstacle]]: static outlines
                strips = obstacle_strips(o)
                scene += strips
                self.rec.log(f"{OBSTACLES}/{j}", rr.LineStrips3D(strips, colors=[OBSTACLE_COLOUR], labels=[o.name],
                                                                  radii=rr.components.Radius.ui_points(2.0)),
                             static=True)
            for v, line in zip(scenario.vehicles, lines):
                rgb = colour(v.kind, rank[v.kind])
                rank[v.kind] += 1
                self._kinds[v.id] = v.kind
                if v.start_position is not None:
                    scene.append(_pad3(np.array([v.start_position])))
                self.rec.log(f"{bp.PATHS}/{v.id}", rr.LineStrips3D([line], colors=[_fade(rgb)],
                                                                   radii=rr.components.Radius.ui_points(1.5)),
                             static=True)
                self._log_marker(v.id, v.kind, rgb, size)
                self.rec.log(f"{bp.TRAILS}/{v.id}", rr.LineStrips3D.from_fields(
                    colors=[rgb], radii=rr.components.Radius.ui_points(1.0)), static=True)
                for family in (bp.PATH_ERROR, bp.OMEGA_RATE):
                    self.rec.log(f"{family}/{v.id}", rr.SeriesLines(colors=[rgb], names=[v.id], widths=[1.5]),
                                 static=True)
            for j, e in enumerate(scenario.metric_edges()):
                self.rec.log(f"{bp.COORD_ERROR}/{e.i}__{e.k}",
                             rr.SeriesLines(colors=[EDGE_COLOURS[j % len(EDGE_COLOURS)]], names=[f"{e.i}–{e.k}"],
                                            widths=[1.5]), static=True)
            config = rr.StateConfiguration(values=list(LINK_STATES), labels=list(LINK_STATES),
                                           colors=[STATE_COLOURS[s] for s in LINK_STATES])
            links = sorted({(e.k, e.i) for e in scenario.edges})  # i listens to k: ω flows k -> i
            for src, dst in links:
                self.rec.log(f"{bp.LINKS}/{src}__{dst}", config, static=True)
            for src, dst in links:  # every link starts up, as the link emulator's do; changes come in
                self._link_change(0.0, src, dst, "up")
            radio = getattr(scenario, "radio", None) is not None
            if radio:
                self.rec.log(bp.UTILISATION, rr.SeriesLines(colors=[UTILISATION_COLOUR], names=["utilisation"],
                                                            widths=[1.5]), static=True)
            self._blueprint = bp.blueprint(np.concatenate(scene) if scene else None, radio=radio)
            self.rec.send_blueprint(self._blueprint)

    def update(self, recorder: Any) -> None:
        with self._lock:
            if self._closed:
                return
            self._recorder = recorder
            if self._off:
                return
            n = len(recorder)
            if n > self._sent and (self._sent == 0 or recorder.t[n - 1] - self._t_sent >= self.flush_every - 1e-9):
                try:
                    self._send(recorder, n)
                    if self._stream is not None and self._t_sent - self._segment_t0 >= self.segment_every - 1e-9:
                        self._write_segment()
                except (OSError, RuntimeError) as e:
                    self._stop_files(e)

    def event(self, event: FleetEvent) -> None:
        with self._lock:
            if self._closed or self._off:
                return
            try:
                self._set_time(event.t)
                self.rec.log(bp.EVENTS, rr.TextLog(event.text, level=LEVELS[event.severity]))
            except (OSError, RuntimeError) as e:
                self._stop_files(e)

    def link_state(self, t: float, src: str, dst: str, state: str) -> None:
        """``state`` is up | lossy | down (anything else is drawn too, uncoloured: it may come off the wire)."""
        with self._lock:
            if self._closed or self._off or self._link_states.get((src, dst)) == state:
                return
            try:
                self._link_change(t, src, dst, state)
            except (OSError, RuntimeError) as e:
                self._stop_files(e)

    def radio(self, t: float, watch: Any) -> None:
        """[radio], at each geometry sample (cdus.sim.radio.RadioWatch): every link of the graph
        between live vehicles drawn from sender to receiver, coloured by its delivery probability
        (red 0 -> yellow 0.5 -> green 1), the station, and the channel utilisation."""
        with self._lock:
            if self._closed or self._off:
                return
            try:
                self._set_time(t)
                strips, colours = [], []
                for (src, dst), p in sorted(watch.links.items()):
                    a, b = watch.points.get(src), watch.points.get(dst)
                    if a is not None and b is not None:
                        strips.append([a, b])
                        colours.append(probability_colour(p))
                self.rec.log(bp.RADIO_LINKS, rr.LineStrips3D(strips, colors=colours,
                                                             radii=rr.components.Radius.ui_points(1.0)))
                if watch.station is not None:
                    self.rec.log(bp.RADIO_STATION, rr.Points3D([list(watch.station)], colors=[STATION_COLOUR],
                                                               radii=[0.6 * self._marker], labels=["station"]))
                if watch.utilisation:
                    self.rec.log(bp.UTILISATION, rr.Scalars(watch.utilisation[-1][1]))
            except (OSError, RuntimeError) as e:
                self._stop_files(e)

    def close(self) -> None:
        """Send what is left, flush, close the sinks (the last segment gets its footer), and
        merge the segments into the file asked for. Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                rec = None if self._off else self._recorder
                if rec is not None and len(rec) > self._sent:
                    self._send(rec, len(rec))
                if rec is not None and len(rec) and (len(rec) - 1) % UPDATE_EVERY:
                    self._send_trails(rec, [len(rec) - 1])  # the trail as the run ended
            except (OSError, RuntimeError) as e:
                self._stop_files(e)
            finally:
                if self._stream is not None:
                    try:
                        self._write_segment()
                    except (OSError, RuntimeError) as e:
                        self._stop_files(e)
                for stream in self.rec.streams:
                    try:
                        stream.flush(timeout_sec=10.0)
                    except Exception as e:  # a viewer that went away
                        _warn(f"Rerun flush: {e}")
                    stream.disconnect()
        if self._stream is None:
            return
        self._stream = None
        for path in self.files:
            parts = _parts(path)
            try:
                merge_segments(path, parts, self.recording_id, self._blueprint)
            except (OSError, RuntimeError) as e:
                _warn(f"could not merge the recording into {path} ({getattr(e, 'strerror', None) or e}); its "
                      f"segments are kept: open them with: rerun {shlex.quote(str(parts))}/*.rrd")
                continue
            print(f"  recording: {path}  (open it with: rerun {shlex.quote(str(path))})", file=self.out)

    # ------------------------------------------------------------------ internals
    def _write_segment(self) -> None:
        """What the file stream holds since the last segment, as the next segment of every file
        (a complete .rrd: one read of a Rerun BinaryStream ends with its footer)."""
        data = self._stream.read(flush=True, flush_timeout_sec=30.0) if self._stream is not None else None
        self._segment_t0 = self._t_sent
        if not data:
            return
        for f in self.files:
            parts = _parts(f)
            whole = _segment(parts, self._segment)
            partial = whole.with_name(whole.name + ".partial")
            _write_whole(partial, data)
            os.replace(partial, whole)
        self._segment += 1

    def _stop_files(self, error: BaseException) -> None:
        """Stop writing files after ``error`` (one warning); live viewers keep their stream."""
        if self._stream is None:
            return
        self._stream = None
        reason = getattr(error, "strerror", None) or str(error)
        # only segments that exist are named: a disk full from the start leaves none, and an
        # empty PATH.parts/*.rrd told to open "what was recorded before" is a glob of nothing
        have = [f for f in self.files if any(_parts(f).glob("*.rrd"))]
        kept = " ".join(f"{shlex.quote(str(_parts(f)))}/*.rrd" for f in have)
        before = (f"What was recorded before stays readable: rerun {kept}" if have
                  else "Nothing was recorded before it (no segment could be written).")
        _warn(f"the Rerun recording stopped: {reason}; the run goes on. {before}")
        if self.on_stop is not None:
            self.on_stop(f"the Rerun recording into {', '.join(map(str, self.files))} stopped: {reason}; the run "
                         f"goes on ({f'what was recorded before: rerun {kept}' if have else 'nothing was recorded'})")
        if self._file_rec is not None:
            self.rec.streams.remove(self._file_rec)
            try:
                self._file_rec.disconnect()
            except Exception:
                pass
            self._file_rec = None
        for f in self.files:  # a segment cut short by the failure
            for partial in _parts(f).glob("*.rrd.partial"):
                try:
                    partial.unlink()
                except OSError:
                    pass
            if f not in have:  # nothing in it: no directory left to look into
                try:
                    _parts(f).rmdir()
                except OSError:
                    pass
        self._off = not self.rec.streams

    def _check_space(self, need: int) -> None:
        """A warning when the disk of a file target has less room than the run is expected to take."""
        for f in self.files:
            free = _free_bytes(_parts(f))
            if free is not None and free < 2 * need:
                _warn(f"{free / 1e6:.1f} MB free on the disk of {f}; this run is expected to record about "
                      f"{need / 1e6:.1f} MB (and twice that for a moment when it is merged at the end); the "
                      f"recording stops with a warning if the disk fills, the run goes on")

    def _send(self, recorder: Any, hi: int) -> None:
        """Rows [sent, hi) of every per-tick entity in one record batch, then the trails due in them."""
        lo = self._sent
        layout = self._layout_for(recorder)
        q = recorder.q[lo:hi].transpose(1, 0, 2)  # [N, n, 3]
        n = hi - lo
        columns = [_time(recorder.t[lo:hi])]
        columns += _vec_lists(_TRANSLATION, q)
        columns += _vec_lists(_QUATERNION, yaw_quaternions(recorder.heading[lo:hi].T.ravel()).reshape(len(q), n, 4))
        if len(layout.uav):  # a drone's line down to the water, in its own frame: (0, 0, 0) -> (0, 0, -z)
            ends = np.zeros((len(layout.uav), n, 2, 3))
            ends[:, :, 1, 2] = -q[layout.uav, :, 2]
            columns += _strip_lists(ends.reshape(len(layout.uav), 2 * n, 3), np.full(n, 2))
        scalars = np.concatenate([recorder.path_error[lo:hi].T, recorder.omega_rate[lo:hi].T,
                                  recorder.edge_error(lo, hi).T])
        # an edge with an end not live has no error (an empty row: a gap in its plot), as the
        # metrics leave it out: a killed vehicle's frozen ω made its edges' errors grow to ~10 rad
        keep = np.ones(scalars.shape, dtype=bool)
        if recorder.edges:
            live = recorder.live[lo:hi]
            keep[len(scalars) - len(recorder.edges):] = [live[:, e.i] & live[:, e.k] for e in recorder.edges]
        offsets = pa.array(np.concatenate(([0], np.cumsum(keep.ravel()))).astype(np.int32))
        columns += _lists(_SCALAR, pa.array(scalars.ravel()[keep.ravel()]), offsets, len(scalars))
        self.rec.send_record_batch(pa.RecordBatch.from_arrays(columns, schema=layout.ticks), index=bp.TIMELINE)
        first = -(-lo // UPDATE_EVERY) * UPDATE_EVERY
        self._send_trails(recorder, list(range(first, hi, UPDATE_EVERY)))
        if self._safety_on and getattr(recorder, "interventions", None) is not None:
            self._send_interventions(recorder, lo, hi)
        self._send_closest(recorder, lo, hi)
        self._sent = hi
        self._t_sent = float(recorder.t[hi - 1])

    def _send_trails(self, recorder: Any, rows: list[int]) -> None:
        """The trail of every vehicle at each of ``rows``, in one record batch."""
        if not rows:
            return
        layout = self._layout_for(recorder)
        window = int(round(TRAIL_SECONDS * self._rate))
        picks = [trail_indices(i, window, TRAIL_POINTS_EVERY) for i in rows]
        points = recorder.q[np.concatenate(picks)].transpose(1, 0, 2)  # [N, points, 3]
        columns = [_time(recorder.t[rows])] + _strip_lists(points, np.array([len(p) for p in picks]))
        self.rec.send_record_batch(pa.RecordBatch.from_arrays(columns, schema=layout.trails), index=bp.TIMELINE)

    def _send_interventions(self, recorder: Any, lo: int, hi: int) -> None:
        """Rows [lo, hi): a dot above each vehicle whose filter intervened, in one record batch
        of the rows where the picture changes (dots, or the first row without after some);
        an event line when a vehicle starts intervening after EPISODE_GAP s without."""
        hit = intervened(recorder.interventions[lo:hi], recorder.interventions[lo - 1] if lo else None)
        rows = hit.any(axis=1)
        was = np.concatenate(([self._marks_shown], rows[:-1]))
        keep = np.nonzero(rows | was)[0]
        if len(keep):
            self._marks_shown = bool(rows[-1])
            layout = self._layout_for(recorder)
            sel = hit[keep]
            pos = recorder.q[lo:hi][keep][sel].copy()  # row-major: each kept row's vehicles in order
            pos[:, 2] += 1.5 * self._marker
            offsets = pa.array(np.concatenate(([0], np.cumsum(sel.sum(axis=1)))).astype(np.int32))
            flat = pa.array(np.ascontiguousarray(pos, dtype=np.float32).ravel())
            xyz = pa.FixedSizeListArray.from_arrays(flat, type=_POSITIONS[1].value_type)
            ids = np.array(recorder.ids, dtype=object)
            labels = pa.array([str(ids[j]) for j in np.nonzero(sel)[1]], pa.string())
            columns = [_time(recorder.t[lo:hi][keep]), pa.ListArray.from_arrays(offsets, xyz, type=_POSITIONS[1]),
                       pa.ListArray.from_arrays(offsets, labels, type=_LABELS[1])]
            self.rec.send_record_batch(pa.RecordBatch.from_arrays(columns, schema=layout.interventions),
                                       index=bp.TIMELINE)
        for i, j in zip(*np.nonzero(hit)):
            t = float(recorder.t[lo + i])
            last = self._last_intervention.get(int(j))
            if last is None or t - last > EPISODE_GAP + 1e-9:
                self._set_time(t)
                self.rec.log(bp.EVENTS, rr.TextLog(f"{recorder.ids[j]}: the safety filter intervenes "
                                                   f"(first seen at t = {t:.2f} s; a fleet of processes "
                                                   f"reports its counts about once a second)",
                                                   level=rr.TextLogLevel.INFO))
            self._last_intervention[int(j)] = t

    def _send_closest(self, recorder: Any, lo: int, hi: int) -> None:
        """Rows [lo, hi): where a domain's closest approach beats the one logged so far, a line
        between the pair at that time; the first time a domain comes within the radius, an
        event line."""
        kinds = [self._kind(recorder, j) for j in range(len(recorder.ids))]
        found = closest_pairs(recorder.t[lo:hi], recorder.q[lo:hi], recorder.live[lo:hi], recorder.ids, kinds)
        for domain, p in found.items():
            if p.distance >= self._closest.get(domain, math.inf):
                continue  # ties keep the earlier approach, as the metrics do
            self._closest[domain] = p.distance
            i = lo + int(np.searchsorted(recorder.t[lo:hi], p.t))
            a, b = recorder.ids.index(p.a), recorder.ids.index(p.b)
            qa, qb = recorder.q[i, a].copy(), recorder.q[i, b].copy()
            if domain == "uav-usv":  # the boat as a drone's filter sees it, on the water
                (qa if kinds[a] == "usv" else qb)[2] = 0.0
            near = p.distance < self._radius
            gone = [v for v, live in ((p.a, p.a_live), (p.b, p.b_live)) if not live]
            label = (f"closest so far: {p.a} - {p.b} {p.distance:.2f} m at {p.t:.2f} s"
                     + (f" ({', '.join(gone)} not live)" if gone else ""))
            self._set_time(p.t)
            line = rr.LineStrips3D([[qa, qb]], colors=[NEAR_COLOUR if near else CLOSEST_COLOUR],
                                   radii=rr.components.Radius.ui_points(2.0), labels=[label], show_labels=True)
            self.rec.log(f"{CLOSEST}/{domain}", line)
            if near and domain not in self._near:
                self._near.add(domain)
                self.rec.log(bp.EVENTS, rr.TextLog(f"near collision: {p.a} and {p.b} {p.distance:.2f} m apart at "
                                                   f"t = {p.t:.2f} s, within the safety radius {self._radius:g} m",
                                                   level=rr.TextLogLevel.WARN))

    def _layout_for(self, recorder: Any) -> _Layout:
        if self._layout is None:
            self._layout = _Layout(recorder.ids, [self._kind(recorder, j) == "uav" for j in range(len(recorder.ids))],
                                   recorder.edges)
        return self._layout

    def _kind(self, recorder: Any, j: int) -> str:
        return self._kinds.get(recorder.ids[j]) or ("uav" if recorder.dims[j] == 3 else "usv")

    def _link_change(self, t: float, src: str, dst: str, state: str) -> None:
        self._link_states[(src, dst)] = state
        self._set_time(t)
        self.rec.log(f"{bp.LINKS}/{src}__{dst}", rr.StateChange(state=state))

    def _set_time(self, t: float) -> None:
        # set_time is per thread: set it on the calling thread before every non-column log
        self.rec.set_time(bp.TIMELINE, duration=np.timedelta64(int(round(t * 1e9)), "ns"))

    def _log_marker(self, vid: str, kind: str, rgb: tuple[int, int, int], s: float) -> None:
        base = f"{bp.VEHICLES}/{vid}"
        if kind == "usv":  # a flat hull along +x (the heading) and a bow arrow
            self.rec.log(f"{base}/hull", rr.Boxes3D(half_sizes=[[2.0 * s, 0.75 * s, 0.35 * s]],
                                                     centers=[[0, 0, 0.35 * s]], colors=[rgb], fill_mode="solid",
                                                     labels=[vid], show_labels=True), static=True)
            self.rec.log(f"{base}/bow", rr.Arrows3D(origins=[[0, 0, 0.75 * s]], vectors=[[3.0 * s, 0, 0]],
                                                     colors=[(255, 255, 255)], radii=[0.12 * s]), static=True)
        else:  # a quadrotor: two crossed arms, four rotors, a nose; the drop line is per tick
            c, d = math.cos(math.pi / 8), math.sin(math.pi / 8)  # ±45° arms
            self.rec.log(f"{base}/body", rr.Boxes3D(half_sizes=[[1.8 * s, 0.12 * s, 0.1 * s]] * 2,
                                                     quaternions=[[0, 0, d, c], [0, 0, -d, c]],
                                                     colors=[rgb], fill_mode="solid", labels=[vid, ""],
                                                     show_labels=True), static=True)
            r = 1.8 * s / math.sqrt(2.0)
            self.rec.log(f"{base}/rotors", rr.Points3D([[r, r, 0.1 * s], [r, -r, 0.1 * s], [-r, r, 0.1 * s],
                                                        [-r, -r, 0.1 * s]], radii=[0.55 * s], colors=[_fade(rgb)]),
                         static=True)
            self.rec.log(f"{base}/nose", rr.Arrows3D(origins=[[0, 0, 0.2 * s]], vectors=[[2.0 * s, 0, 0]],
                                                      colors=[(255, 255, 255)], radii=[0.1 * s]), static=True)
            self.rec.log(base, rr.LineStrips3D.from_fields(colors=[(150, 150, 150)],
                                                           radii=rr.components.Radius.ui_points(1.0)), static=True)


def _reachable(url: str, timeout: float = 0.5) -> bool:
    """Is something listening at the URL's host:port? (A gRPC sink with no server blocks 5 s.)"""
    parsed = urlparse(url.replace("rerun+", "", 1))
    port = parsed.port or (443 if parsed.scheme == "https" else 9876)
    try:
        with socket.create_connection((parsed.hostname or "127.0.0.1", port), timeout=timeout):
            return True
    except OSError:
        return False


class _Tee:
    """The file stream and the live stream as one: each call goes to every stream."""

    def __init__(self, streams: list[rr.RecordingStream]):
        self.streams = streams

    def send_record_batch(self, batch: pa.RecordBatch, *, index: str) -> None:
        for stream in self.streams:
            rr.send_record_batch(batch, recording=stream, index=index)

    def __getattr__(self, name: str) -> Any:
        def call(*args: Any, **kwargs: Any) -> None:
            for stream in self.streams:
                getattr(stream, name)(*args, **kwargs)
        return call


def _warn(text: str) -> None:
    print(f"warning: {text}", file=sys.stderr)

