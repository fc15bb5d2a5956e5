"""What came in to the world, and what is dropped?

Every sample addressed to the world (telemetry, counters, commands put, the ticker's wake)
arrives through one subscription into one channel; :meth:`Intake._handle` takes one, and what
cannot be genuine (an unknown sender, a forged or future row, a second different row for a
tick, a restarted process's stats before its old token went) is counted by reason
(``st.rejects``) and dropped, never raising."""

from __future__ import annotations

import time
from typing import Any

from cdus.ros2.robot import gap_events
from cdus.sim.reports import link_state_event
from cdus.wire import keys
from cdus.wire.messages import decode_states
from cdus.wire.schemas import AgentStats, FleetEvent, OdometryGap, decode_stats
from cdus.wire.text import printable
from cdus.wire.rejected import Rejected
from world_sim.limits import (
    MAX_LOGGED_REJECTS, MAX_ODOMETRY_EVENTS, SUSPECT_EVERY, SUSPECT_REASONS, SUSPECT_TOKEN_REASONS,
    SUSPECT_WORLD_REASONS,
)


class Intake:
    """The World's intake: its public door (feed, alive, drain), the inbox, and the checks of
    telemetry and counters (a mixin of World)."""

    # ------------------------------------------------------------------ the public door
    def feed(self, key: str, payload: bytes = b"") -> None:
        """One message on a key addressed to the world, as its inbox hands it over (the door a
        test or a mock fleet uses, as dora's testing node is fed): handled, or counted by reason
        and dropped, never raising; then the command queries waiting are answered (at most
        ANSWERS_PER_PASS). A wake (``keys.wake``) carries nothing: it only lets them be answered."""
        self._take(key, payload, answer=True)

    def alive(self, vehicle: str, up: bool) -> None:
        """News that the process taken as ``vehicle``'s came up (``up``) or went: what the
        liveliness watch says once it has decided whose token it is (:meth:`_on_token`)."""
        self._on_alive(vehicle, up)

    def drain(self) -> None:
        """Handle everything waiting in the inbox without waiting, then answer the queries waiting."""
        self._drain(block=False)

    # ------------------------------------------------------------------ from Zenoh
    def _drain(self, block: bool, until: float | None = None) -> None:
        """Handle what is waiting (and, if ``block`` and no command waits, wait for at least one
        sample), then answer at most ANSWERS_PER_PASS of the command queries waiting: the rest
        wait for the next pass, after the fleet's grants and recording. ``until``: a
        time.monotonic() after which it takes no more (an inbox that a flood keeps from emptying)."""
        if block and not self._queries:
            self._handle(self.inbox.recv(), answer=False)
        while (until is None or time.monotonic() < until) and (sample := self.inbox.try_recv()) is not None:
            self._handle(sample, answer=False)
        self._answer_waiting()

    def _handle_alive_news(self) -> None:
        while self._alive_news:
            key, up = self._alive_news.popleft()
            self._on_token(key, up)

    def _handle(self, sample: Any, answer: bool = True) -> None:
        """One Zenoh sample of the inbox: :meth:`_take` of its key and payload."""
        self._take(str(sample.key_expr), sample.payload, answer)

    def _take(self, key: str, payload: Any, answer: bool) -> None:
        """One message (anything anyone can put on a key addressed to the world): handled, or
        counted by reason and dropped. Never raises. ``payload``: bytes, or Zenoh's (read only
        if the key is one the world takes). ``answer``: then answer command queries waiting."""
        try:
            self._dispatch(key, payload)
        except Exception as e:  # a bug of ours, not the sender's: counted, logged once, the run goes on
            self._reject("?", "internal", f"{type(e).__name__}: {e}")
        self._handle_alive_news()
        if answer:
            self._answer_waiting()

    def _dispatch(self, key: str, payload: Any) -> None:
        parts = key.split("/")
        kind, src = keys.leaf(key)
        if kind == "wake":
            return  # the ticker, or liveliness news (queued by _on_alive_sample)
        if not isinstance(payload, bytes):
            payload = payload.to_bytes()
        if kind not in ("state", "stats", "cmd") or len(parts) != 6 or parts[1] != self.fleet:
            return self._reject("?", "key")
        if kind == "state":
            self._on_state(src, payload)
        elif kind == "stats":
            self._on_stats(src, payload)
        else:
            self._on_command(src, payload)

    def _reject(self, sender: str, reason: str, detail: str = "") -> None:
        """Count a dropped message by reason; log the first of each (sender, reason)."""
        self.st.rejects[reason] += 1
        pair = (sender[:64], reason)
        if pair in self._logged_rejects or len(self._logged_rejects) > MAX_LOGGED_REJECTS:
            return
        self._logged_rejects.add(pair)
        more = "" if len(self._logged_rejects) <= MAX_LOGGED_REJECTS else " (further senders are counted only)"
        self.log(f"rejected from {printable(sender, 64)}: {reason}"
                 + (f" ({printable(detail, 200)})" if detail else "") + more)

    def _on_state(self, vid: str, payload: bytes) -> None:
        if vid not in self.index:
            return self._reject(vid, "unknown_sender")
        rows = decode_states(payload, len(self.ids))
        if isinstance(rows, Rejected):
            return self._reject(vid, rows.reason)
        j = self.index[vid]
        if any(m.sender != j for m in rows):
            return self._reject(vid, "sender_mismatch")
        limit = self.clock.tick_limit()
        if any(m.tick > limit for m in rows):  # the whole batch: it cannot all be genuine
            return self._reject(vid, "future", f"tick {max(m.tick for m in rows)} > {limit}")
        st = self.st
        by_tick, first, every = st.rows, self.next_tick, self.sensing[0] if self.sensing is not None else 0
        newest = None  # the batch's newest row taken: latest, acked and the report once per batch
        for m in rows:
            if m.tick >= first:
                have = by_tick.setdefault(m.tick, {}).setdefault(j, m)
                if have is not m and have != m:  # a second, different row for a tick: the first stands
                    self._reject(vid, "conflict", f"tick {m.tick}")
                    continue
            if every and m.tick % every == 0 and m.tick > self.lockstep.sensed:
                self._sample_rows.setdefault(m.tick, {}).setdefault(j, m.q)
            if (self._radio_from_rows and m.tick % self.radio[0] == 0
                    and m.tick > self.lockstep.radioed):  # realtime samples from the newest telemetry
                self._radio_rows.setdefault(m.tick, {}).setdefault(j, m.q)
            if newest is None or m.tick >= newest.tick:
                newest = m
        if newest is None:
            return
        prev = st.latest.get(j)
        if prev is None or newest.tick >= prev.tick:
            with self._lock:
                st.latest[j] = newest
        st.acked[j] = max(st.acked.get(j, -1), newest.tick)
        self.lockstep.on_report(j, newest.tick)

    def _on_stats(self, vid: str, payload: bytes) -> None:
        if vid not in self.index:
            return self._reject(vid, "unknown_sender")
        s = decode_stats(payload, self.index)
        if isinstance(s, Rejected):
            return self._reject(vid, s.reason)
        if s.id != vid:
            return self._reject(vid, "sender_mismatch")
        if s.odometry_gaps and (why := self._odometry_problem(vid, s.odometry_gaps)) is not None:
            return self._reject(vid, why)  # before anything of the report is taken: it cannot be genuine
        old = self.st.stats.get(vid)
        if old is not None and old.incarnation != s.incarnation:  # a restarted process: its counters start anew
            if self.st.downs.get(vid, 0) == self.st.downs_at_stats.get(vid, 0):  # the old one never went away
                return self._reject(vid, "incarnation")  # forged (a genuine restart's next report is believed)
            self.st.retired.append(old)
            old = None
        if old is None:
            self.st.downs_at_stats[vid] = self.st.downs.get(vid, 0)
        self.st.stats[vid] = s
        j = self.index[vid]
        self._interventions[j] = s.interventions + sum(x.interventions for x in self.st.retired if x.id == vid)
        for x in s.latencies_ms:  # each message carries the samples since the previous one
            self.st.latencies.record_latency(x / 1000.0)
        if s.faults is not None:
            self._forward_link_changes(s.faults)
        for b in s.bursts:  # rebuilt by the decoder from its numbers and ids
            self._note(b.event(origin=vid))
        if s.odometry_gaps:
            self._odometry_gaps(vid, s.odometry_gaps)
        self._suspects(vid, s, old)
        if s.final and self.st.finals is not None:
            self.st.finals.add(vid)

    def _odometry_problem(self, vid: str, gaps: tuple[OdometryGap, ...]) -> str | None:
        """Why a report's spells without odometry cannot be genuine (its whole report is dropped):
        ``odometry_not_robot`` (its vehicle is emulated), ``odometry_future`` (past the newest tick
        a vehicle can have stepped); None: they can."""
        if self.scenario.vehicle(vid).robot is None:
            return "odometry_not_robot"
        if any(max(g.t, g.back or 0.0) > (self.clock.tick_limit() + 1) * self.period for g in gaps):
            return "odometry_future"
        return None

    def _odometry_gaps(self, vid: str, gaps: tuple[OdometryGap, ...]) -> None:
        """A robot's spells without odometry (checked by :meth:`_odometry_problem`): each
        ``odometry_stale`` / ``odometry_back`` event noted once (an agent repeats its newest
        spells); past MAX_ODOMETRY_EVENTS, counted (``odometry_flood``) and not noted."""
        robot = self.scenario.vehicle(vid).robot
        noted = self._odometry_noted.setdefault(vid, set())
        for g in gaps:
            for e in gap_events(vid, robot.odom, robot.timeout, g):
                if (e.kind, e.t) in noted:
                    continue
                if len(noted) >= MAX_ODOMETRY_EVENTS:
                    return self._reject(vid, "odometry_flood")
                noted.add((e.kind, e.t))
                self._note(e)

    def _suspects(self, vid: str, s: AgentStats, old: AgentStats | None) -> None:
        """A vehicle that counts new ω it cannot trust (from beyond its sender's possible seq, a
        second different message for a seq, a jump its dynamics cannot make) or a second, different
        radio geometry sample for a tick (someone else speaks as the world): a ``suspect``
        event, at most one per (vehicle, reason) per SUSPECT_EVERY seconds."""
        now = time.monotonic()
        for reason in SUSPECT_REASONS + SUSPECT_WORLD_REASONS + SUSPECT_TOKEN_REASONS:
            new = s.rejected_by_reason.get(reason, 0) - (old.rejected_by_reason.get(reason, 0) if old else 0)
            last = self._suspect_seen.get((vid, reason))
            if new <= 0 or last is not None and now - last < SUSPECT_EVERY:
                continue
            self._suspect_seen[(vid, reason)] = now
            what = ("ω" if reason in SUSPECT_REASONS else "radio geometry not the world's"
                    if reason in SUSPECT_WORLD_REASONS else "a liveliness token not the world's")
            self._note(FleetEvent.of(self._sim_now(), "suspect",
                                     f"{vid} received {what} it cannot trust: {new} new {reason!r} rejects "
                                     f"({s.rejected_by_reason[reason]} in all)", vehicle=vid, origin=vid))

    def _forward_link_changes(self, faults: dict) -> None:
        """New link state changes an agent reports (checked by decode_stats): to the event log and
        the recording."""
        for ch in faults["state_changes"]:
            key = (ch["t"], ch["link"], ch["state"])
            if key in self.st.link_changes:
                continue
            self.st.link_changes.add(key)
            src, _, dst = key[1].partition("->")
            self.sink.link_state(key[0], src, dst, key[2])
            if self.started:
                self._note(link_state_event(*key))
