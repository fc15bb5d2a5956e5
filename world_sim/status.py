"""What does the world tell whoever watches the fleet: its status and its events?

The status (about once a second, signed with the launcher's key when there is one) and what a
live console shows beyond it (StatusExtra); the fleet's events, each marked with its origin,
those of a flood of commands held to their quota."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from cdus.sim.reports import newest_events
from cdus.wire.schemas import (
    FleetEvent, MAX_TEXT as MAX_EVENT_TEXT, ORIGIN_WORLD, StatusExtra, encode_event, encode_status, status_signature,
)


def closest_live_pair(q: np.ndarray, live: np.ndarray, kinds: list[str], ids: list[str]) -> tuple | None:
    """(a, b, distance) of the closest pair of live vehicles of one kind at one instant (boats on
    the water in x, y; drones in 3-D, as cdus.core.metrics.min_separation), None without a pair
    at a finite distance. ``q``: (vehicles, 3) positions, ``live``: (vehicles,) bools."""
    best = None
    for kind, axes in (("usv", 2), ("uav", 3)):
        idx = [j for j, k in enumerate(kinds) if k == kind and live[j]]
        if len(idx) < 2:
            continue
        p = np.asarray(q, dtype=float)[idx, :axes]
        with np.errstate(invalid="ignore", over="ignore"):
            d = np.sqrt(((p[:, None, :] - p[None, :, :]) ** 2).sum(axis=-1))
        d[np.tril_indices(len(idx))] = np.inf  # each pair once, never a vehicle with itself
        d[~np.isfinite(d)] = np.inf
        a, b = np.unravel_index(int(np.argmin(d)), d.shape)
        if math.isfinite(d[a, b]) and (best is None or d[a, b] < best[2]):
            best = (ids[idx[a]], ids[idx[b]], float(d[a, b]))
    return best


def _status_key(text: str | None) -> bytes | None:
    """The launcher's status key from its hex form; None when there is none (or it is not hex)."""
    try:
        return bytes.fromhex(text) if text else None
    except ValueError:
        return None


class Reporting:
    """What the World publishes about the fleet: its status and its events (a mixin of World)."""

    def _note(self, event: FleetEvent, by_command: bool = False) -> None:
        """An event the world built (from validated fields only), marked with its origin. A refused
        command's (kind ``rejected``) and a change a command made (``by_command``) go out at most
        as their quota lets (_event_quotas): the next one that does says how many did not."""
        if event.origin is None:
            event = replace(event, origin=ORIGIN_WORLD)
        kind = "change" if by_command else event.kind
        quota = self._event_quotas.get(kind)
        if quota is not None:
            if not quota.take(self._quota_clock()):
                return
            held = quota.passed()
            if held:
                more = (f" ({held} refused commands since the last one logged were not: a flood; each was "
                        f"answered and counted in the world's rejects)" if kind == "rejected" else
                        f" ({held} changes by command since the last one logged were not: a flood; each was "
                        f"made, answered and is listed in world/settings)")
                event = replace(event, text=event.text[:MAX_EVENT_TEXT - len(more)] + more)
        self.events.append(event)
        self.sink.event(event)
        for line in self._console.lines(event):
            self.log(line)
        if self.session is not None:
            self.pub_events.put(encode_event(event))

    def _publish_status(self, completion: str | None = None) -> None:
        """The fleet's status; ``completion`` once the run is over (its last status)."""
        n = len(self.recorder)
        t = (self.next_tick - 1) * self.period
        path = coord = None
        if n:  # over the live formation, as the metrics (docs/metrics.md)
            worst_path, worst_coord = self.recorder.worst_errors(start=n - 1)
            path = None if math.isnan(worst_path[-1]) else float(worst_path[-1])
            coord = None if math.isnan(worst_coord[-1]) or not self.recorder.edges else float(worst_coord[-1])
        paused = self.clock.paused()
        extra = replace(self._status_extra(), completion=completion)
        payload = encode_status(t, self.duration, self.clock.name, sorted(self.st.alive), self.ids, path, coord,
                                newest_events(self.events), paused, roster=dict(zip(self.ids, extra.states)),
                                extra=extra)
        self._status_payload = payload  # what a status query is answered (bytes: replaced whole, never changed)
        if self._status_key is None:
            self.pub_status.put(payload)
        else:
            self.pub_status.put(payload, attachment=status_signature(self._status_key, payload))

    def _status_extra(self) -> StatusExtra:
        """What a live console shows beyond the summary (cdus.wire.schemas.STATUS_EXTRA), at the
        newest recorded tick: each vehicle's kind and roster state, each edge's error, each
        emulated link's counters, each vehicle's received and dropped ω, the [safety] radius and
        the closest pair of live vehicles of one kind."""
        rec, n = self.recorder, len(self.recorder)
        kinds = [v.kind for v in self.scenario.vehicles]
        tick = max(0, self.next_tick - 1)
        states = self.clock.roster_states(tick)
        edges = closest = path_errors = None
        if n:
            omega, live, q = rec.omega[n - 1], rec.live[n - 1], rec.q[n - 1]
            path_errors = [float(x) if live[j] else None for j, x in enumerate(rec.path_error[n - 1])]
            # the offsets in force at that row (a formation change moves them), as coord_error_max
            d = rec.deltas(n - 1, n)
            deltas = [e.delta for e in rec.edges] if d is None else [float(x) for x in d[0]]
            edges = [(self.ids[e.i], self.ids[e.k],
                      float(abs(omega[e.i] - omega[e.k] - delta)) if live[e.i] and live[e.k] else None)
                     for e, delta in zip(rec.edges, deltas)]
            closest = closest_live_pair(q, live, kinds, self.ids)
        # a restarted vehicle's links and receipts add up over its processes, as in the metrics
        links: dict[tuple[str, str], tuple] = {}
        rx: list[tuple[int, int] | None] = [None] * len(self.ids)
        for s in self._processes():  # the retired first: the newest process says a link's state
            if isinstance(s.faults, dict):
                last_state = {c["link"]: c["state"] for c in s.faults["state_changes"]}
                for name, c in s.faults["links"].items():
                    src, _, dst = name.partition("->")
                    _, _, sent, dropped, state = links.get((src, dst), (src, dst, 0, 0, None))
                    links[(src, dst)] = (src, dst, sent + c["sent"], dropped + min(c["dropped"], c["sent"]),
                                         last_state.get(name, state))
            j = self.index[s.id]
            sent, dropped = rx[j] or (0, 0)
            rx[j] = (sent + s.sent_to_me, dropped + min(s.dropped, s.sent_to_me))
        return StatusExtra(kinds=kinds, states=states, edges=edges, links=[links[k] for k in sorted(links)], rx=rx,
                           safety_radius=self.scenario.safety.radius, closest=closest, path_errors=path_errors,
                           directed=self.scenario.directed)

    def _recording_stopped(self, text: str) -> None:
        """The sink's file recording stopped (ENOSPC...): an event, so the launcher's console and
        the ground stations say it at once, and the metrics' events keep it."""
        self._note(FleetEvent.of(max(0, self.next_tick - 1) * self.period, "recording_stopped", text))


def _say(text: str, prefix: str = "[world] ") -> None:
    """One line on stdout (the world's log); a log on a full disk is no reason to stop the world."""
    try:
        print(f"{prefix}{text}", flush=True)
    except OSError:
        pass
