"""Whose process is up: which liveliness tokens does the world take, and what do their
changes do?

A vehicle's process is the Zenoh session whose token the world took for it; a token no process
declares, or a second one of a vehicle, is ignored and counted in ``integrity``
(docs/security.md, "Liveliness"). A change goes to the clock (lockstep: Lockstep decides the
roster; realtime: a roster change at once) and to the live graph's event."""

from __future__ import annotations

from collections import Counter
from typing import Any

import zenoh

from cdus.core.events import RosterChange
from cdus.sim.reports import graph_event
from cdus.sim.runmetrics import Integrity
from cdus.wire import keys
from cdus.wire.access import ROS2_ROLE
from cdus.wire.messages import encode_control
from cdus.wire.schemas import FleetEvent
from cdus.wire.text import printable
from world_sim.limits import SUSPECT_TOKEN_REASONS


class Liveness:
    """Whose liveliness token the World takes, and what a process coming or going does (a mixin
    of World)."""

    def _on_alive_sample(self, sample: Any) -> None:
        """Liveliness news (Zenoh's thread): queued for the main thread (:meth:`_on_token`), which a
        wake fetches. The wake carries nothing: the news never travels over the wire."""
        self._alive_news.append((str(sample.key_expr), not str(sample.kind).endswith("DELETE")))
        try:
            self._wake()
        except zenoh.ZError:
            pass

    def _on_token(self, key: str, up: bool) -> None:
        """A liveliness token came (``up``) or went: whose it is, then :meth:`_on_alive`.

        A vehicle's process is the session whose token the world took for it: the first token
        of that vehicle (``alive/<id>/<zid>``) while it has none; its loss is that token's going,
        whatever other token of the vehicle is up. Zenoh merges tokens of one key (a second is no
        news, and keeps the key up after the first goes): the session id in the key makes each
        process's token its own. Ignored, and counted in :attr:`integrity`: a token on a key no
        process declares (``alive/**``: it intersects every watch), of a name not in the fleet,
        a second token of a vehicle (or of the world) while one is up, and any later token of a
        session refused once or holding another vehicle's (docs/security.md, "Liveliness")."""
        token = keys.alive_token(key)
        if token is None:
            if up:
                self._tamper("token_key", f"a liveliness token on {printable(key, 80)}, no process's key: ignored")
            return
        name, zid = token
        if name == ROS2_ROLE and name not in self.index and self.scenario.ros2.enabled:
            self._on_bridge_token(zid, up)  # the ROS 2 bridge (docs/ros2.md): the fleet's, no vehicle
            return
        if name == keys.WORLD or name not in self.index:
            if up and zid != self.zid:
                self._tamper("token_extra" if name == keys.WORLD else "token_unknown",
                             f"a liveliness token {printable(name, 64)} of session {zid}: "
                             + ("not this world's" if name == keys.WORLD else "no process of this fleet"))
            return
        taken = self._token_of.get(name)
        if not up:
            if taken == zid:
                del self._token_of[name]
                self._on_alive(name, False)
            return
        if taken == zid:
            return
        if taken is None and zid not in self._not_taken and zid not in self._token_of.values():
            self._token_of[name] = zid
            self._on_alive(name, True)
            return
        self._not_taken.add(zid)
        self._tamper("token_extra", f"a second liveliness token of {name} (session {zid}) while "
                     + (f"session {taken}'s is up" if taken else "it has none it can take") + ": ignored")

    def _on_bridge_token(self, zid: str, up: bool) -> None:
        """The ROS 2 bridge's token (``alive/ros2/<zid>``, a fleet with ``[ros2]`` enabled): its
        first is taken as the bridge's (it was counted ``token_unknown``, every ``--ros2`` run
        TAMPERED); a second while one is up is counted ``token_extra``, as a vehicle's."""
        taken = self._token_of.get(ROS2_ROLE)
        if not up:
            if taken == zid:
                del self._token_of[ROS2_ROLE]
            return
        if taken == zid or (taken is None and zid not in self._not_taken and zid not in self._token_of.values()):
            self._token_of[ROS2_ROLE] = zid
            return
        self._not_taken.add(zid)
        self._tamper("token_extra", f"a second liveliness token of the ROS 2 bridge (session {zid}): ignored")

    def _tamper(self, reason: str, note: str) -> None:
        """Something that may have altered the run (a forged or unexplained token): counted by
        reason for the metrics (``integrity``), the first of each logged and made an event."""
        self.integrity[reason] += 1
        if reason not in self._integrity_notes:
            self._integrity_notes[reason] = note
            self._note(FleetEvent.of(self._sim_now(), "suspect", note + " (docs/security.md)"))

    def integrity_block(self) -> Integrity:
        """``integrity`` of the metrics: ``tampered`` when the world, or a vehicle watching the
        world's token, saw a token that is no process's (docs/metrics.md)."""
        reasons = Counter(self.integrity)
        notes = list(self._integrity_notes.values())
        for s in self._processes():
            for reason in SUSPECT_TOKEN_REASONS:
                if s.rejected_by_reason.get(reason):
                    reasons["vehicle_" + reason] += s.rejected_by_reason[reason]
                    notes.append(f"{s.id} counted {s.rejected_by_reason[reason]} {reason!r}: a liveliness token "
                                 f"on its watch of the world's that is not the world's")
        return Integrity(tampered=bool(reasons), reasons=dict(sorted(reasons.items())), notes=tuple(notes))

    def _on_alive(self, name: str, up: bool) -> None:
        st = self.st
        if name not in self.index:
            return
        if up:
            st.alive.add(name)
        else:
            st.alive.discard(name)
            st.downs[name] = st.downs.get(name, 0) + 1
        if self.finished:
            return  # agents leaving after the stop are not news
        j = self.index[name]
        self.clock.on_alive(name, j, up)
        if self.started:
            self._check_graph()

    def _note_fault(self, vid: str, action: str) -> None:
        """Keep which vehicles a fault killed or paused (realtime: asked of the launcher; lockstep:
        landed on its tick): realtime decides moot faults by it, and the status shows a vehicle
        paused by a fault as paused after its token lapses (the lockstep roster says gone then)."""
        if action == "kill" or action == "pause" and self._faulted.get(vid) != "killed":
            self._faulted[vid] = "killed" if action == "kill" else "paused"
        elif action in ("resume", "restart") and (action == "restart" or self._faulted.get(vid) == "paused"):
            self._faulted.pop(vid, None)

    def _send_roster(self, ch: RosterChange, to: int | None = None) -> None:
        targets = self.ids if to is None else [self.ids[to]]
        self._put(keys.ctl(self.fleet, targets),
                         encode_control("roster", vehicle=self.ids[ch.vehicle], tick=ch.tick, state=ch.state,
                                        fresh=ch.fresh))

    def _check_graph(self) -> None:
        """The live graph after a liveliness change, at the tick of the roster change it belongs
        to when there is one (lockstep: a kill at 150 s is news of tick 7500, not of the newest
        tick recorded, 7499), as the in-process fleet stamps it."""
        news = self.clock.news_tick()
        t = self._sim_now() if news is None else news * self.period
        self._note(graph_event(t, self.ids, self.pairs, self.st.alive))
