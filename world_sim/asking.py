"""How is the world asked, and how does it answer?

Queries (Zenoh's threads) of its status, settings and every vehicle's last telemetry are
answered at once, within their quotas; a command (a query on world/cmd/gs, or a put on
to/+world+/cmd/<from>) is handed to the main thread, decoded, given to its handler
(world_sim.commands) and answered with a CommandReply: applied from a tick, rejected with the
reason, or (a vehicle fault) once it is decided. The world's queryables are one table
(:meth:`Asking.queryables`): Zenoh's queries reach them through it, and so does the public door
:meth:`Asking.ask`, which answers an :class:`Asked` (no Zenoh object) by the same code."""

from __future__ import annotations

from typing import Any, Callable

import zenoh

from cdus.core.quota import Quota
from cdus.sim.lockstep import Decided
from cdus.wire import keys
from cdus.wire.messages import COMMAND_OPS, decode_control, encode_states
from cdus.wire.schemas import (
    CommandReply, ID_RE, MAX_REASON, MAX_SETTINGS_CHANGES, decode_reply, encode_reply, encode_settings,
)
from cdus.wire.text import printable
from cdus.wire.rejected import Rejected
from world_sim.limits import ANSWERS_PER_PASS, MAX_QUEUED_QUERIES, MAX_WAITING, QUERIES_PER_S, RATE_REFUSAL
from world_sim.verdict import LATER, Verdict


class Asked:
    """A query put to the world through :meth:`Asking.ask`, and what the world said to it: its
    ``key`` and ``payload``; ``replies``, one (key, payload) per reply; ``errors``, one payload per
    error reply (a query past its quota); ``done`` once the world has said all it will (a
    command's answer, which may come on a later pass: a lockstep vehicle fault is answered when
    it lands). The world replies to it as to a Zenoh query (``reply``, ``reply_err``, ``drop``);
    a subclass may fail as an asker gone does (``reply`` raising zenoh.ZError)."""

    def __init__(self, key: str, payload: bytes | None = None):
        self.key = key
        self.payload = payload
        self.replies: list[tuple[str, bytes]] = []
        self.errors: list[bytes] = []
        self.done = False

    @property
    def key_expr(self) -> str:
        """The key, as the world reads a Zenoh query's."""
        return self.key

    def reply(self, key: Any, payload: Any) -> None:
        assert not self.done, f"{self.key}: replied after the query was finalized"
        self.replies.append((str(key), bytes(payload)))

    def reply_err(self, payload: Any) -> None:
        assert not self.done, f"{self.key}: replied after the query was finalized"
        self.errors.append(bytes(payload))

    def drop(self) -> None:
        self.done = True

    @property
    def answer(self) -> CommandReply | Rejected | None:
        """A command's answer (a CommandReply, decoded), None while it waits. A command is
        answered once, on its own key, and then finalized: anything else raises ValueError."""
        if not self.replies:
            return None
        if len(self.replies) > 1 or self.replies[0][0] != self.key or not self.done:
            raise ValueError(f"{self.key}: not one command's answer: {len(self.replies)} replies on "
                             f"{sorted({k for k, _ in self.replies})}, finalized: {self.done}")
        return decode_reply(self.replies[0][1])


def _payload_bytes(payload: Any) -> bytes:
    """A query's payload as bytes: an Asked's (bytes or None) or a Zenoh query's (ZBytes or None)."""
    if payload is None:
        return b""
    return payload if isinstance(payload, (bytes, bytearray)) else payload.to_bytes()


class Asking:
    """How the World is asked and answers: queries within their quotas, commands decided on the
    main thread (a mixin of World)."""

    def queryables(self) -> list[tuple[str, Callable[[Any], None]]]:
        """The world's queryables, (key expression, handler of one query), as World.open declares
        them on Zenoh and :meth:`ask` reaches them: each handler runs on Zenoh's thread."""
        f = self.fleet
        return [(keys.world_last(f, "*"), self._on_last_query), (keys.world_settings(f), self._on_settings_query),
                (keys.world_status(f), self._on_status_query), (keys.any_world_command(f), self._on_command_query)]

    def ask(self, key: str, payload: bytes | None = None, answer: bool = True, asked: Asked | None = None) -> Asked:
        """The door a test, a bench or a mock asks the world by (as ``feed`` hands it a message): a
        query on ``key`` with ``payload``, given to each of the world's :meth:`queryables` whose key
        expression intersects ``key``, as Zenoh routes a query (none: nobody answers), by the
        same code as Zenoh's queries. A status, settings or last-telemetry query is answered (or
        refused past its quota) before this returns; a command waits for the main thread, which
        answers it if ``answer`` (one pass: ``feed`` of a wake; without it, the next ``feed`` or
        ``drain`` does, as while the main thread is busy elsewhere). Returns ``asked`` (a new
        :class:`Asked` if None) with what the world said."""
        asked = Asked(key, payload) if asked is None else asked
        try:
            expr = zenoh.KeyExpr(key)
        except zenoh.ZError:  # a key Zenoh refuses reaches nobody
            asked.drop()
            return asked
        reached = [handler for on, handler in self.queryables() if expr.intersects(zenoh.KeyExpr(on))]
        for handler in reached:
            handler(asked)
        if self._on_command_query not in reached:
            asked.drop()  # all said, as Zenoh finalizes a query its callbacks have let go (a command's: its answer)
        if answer:
            self.feed(keys.wake(self.fleet, keys.WORLD))
        return asked

    def _over_quota(self, quota: Quota, reason: str) -> bool:
        """Zenoh's thread: has the asker of a query gone past ``quota``? Counted as ``reason``."""
        with self._quota_lock:
            if quota.take(self._quota_clock()):
                return False
            self._refused_offthread[reason] += 1
            return True

    def _query_refused(self, query: Any, name: str, key: str) -> bool:
        """A query of the world's status, settings or every vehicle's last telemetry past its
        quota (QUERIES_PER_S): answered at once with an error reply that says so, counted."""
        if not self._over_quota(self._query_quotas[name], "query_rate"):
            return False
        try:
            query.reply_err(f"busy: at most {QUERIES_PER_S:g} queries per second on {key} "
                            f"(a flood); try again".encode())
        except zenoh.ZError:
            pass
        return True

    def _on_last_query(self, query: Any) -> None:
        """A restarted agent asks where its vehicle was: reply with its newest telemetry. A ground
        station asks ``world/last/*``: one reply per vehicle heard from (on its own key), at most
        QUERIES_PER_S such queries a second (a vehicle's own key has no quota: a flood on it must
        not keep a restarting vehicle from where it was; its reply is one row)."""
        vid = str(query.key_expr).rsplit("/", 1)[-1]
        wanted = self.ids if vid in ("*", "**") else [vid] if vid in self.index else []
        if len(wanted) > 1 and self._query_refused(query, "last", keys.world_last(self.fleet, "*")):
            return
        with self._lock:
            rows = [(v, self.st.latest.get(self.index[v])) for v in wanted]
        for v, m in rows:
            if m is not None:
                query.reply(keys.world_last(self.fleet, v), encode_states([m]))

    def _on_status_query(self, query: Any) -> None:
        """A ground station attaching asks for the status at once rather than wait up to a second
        for the next one: the newest published (none before the first)."""
        payload = self._status_payload
        if payload is not None and not self._query_refused(query, "status", keys.world_status(self.fleet)):
            query.reply(keys.world_status(self.fleet), payload)

    def _on_settings_query(self, query: Any) -> None:
        """A ground station asks what the run's settings are now (``gs snapshot``): the reply is
        made here, on the first query after a change, from what the main thread last said the
        settings are made of (:meth:`_settings_changed`), and kept for the next queries. A change
        costs the main thread no encoding (it cost the whole list's at each change: a flood of
        commands was quadratic)."""
        if self._query_refused(query, "settings", keys.world_settings(self.fleet)):
            return
        made_of = self._settings_from
        cached = self._settings_cache
        if cached is None or cached[0] is not made_of:
            count, phases, link = made_of[1:]
            kept = self._commands[max(0, count - MAX_SETTINGS_CHANGES):count]  # one atomic slice (the GIL)
            cached = (made_of, encode_settings([(c.kept_for, c.payload) for c in kept], phases, link, total=count))
            self._settings_cache = cached
        query.reply(keys.world_settings(self.fleet), cached[1])

    def _settings_changed(self, op: str) -> None:
        """Main thread, at each change: what the settings reply is made of now (a new tuple, which
        a query reads whole): the number of changes listed, the phases (made again only when a
        change can move them) and the [link] table in force. O(1) for a gains change."""
        old = self._settings_from
        if op in ("gains", "link", "radio") and old:
            phases = old[2]
        else:
            phases = (tuple(zip(self.ids, self.recorder.formation.phases_at(2**62)))
                      if self.recorder.formation is not None else ())
        self._settings_from = (object(), len(self._commands), phases, self._link_table)

    def _on_command_query(self, query: Any) -> None:
        """A command as a query (Zenoh's thread): handed to the main thread, which answers it. Past
        the ground credentials' rate (COMMANDS_PER_S) or MAX_QUEUED_QUERIES waiting (a flood),
        answered at once: rejected, busy."""
        # the ground credentials' key only: a query on world/** (an open fleet, or a vehicle's if the
        # router lets it through) must not spend the ground stations' rate; the main thread refuses it
        if str(query.key_expr) == self._ground_key and self._over_quota(self._command_quota, "rate"):
            self._reply(query, "?", "", Verdict.no(RATE_REFUSAL))
            return
        if len(self._queries) >= MAX_QUEUED_QUERIES:
            with self._quota_lock:
                self._refused_offthread["busy"] += 1
            self._reply(query, "?", "", Verdict.no("busy: too many commands waiting; try again"))
            return
        self._queries.append(query)
        try:
            self._wake()
        except zenoh.ZError:
            pass

    def _answer_waiting(self) -> None:
        """Answer at most ANSWERS_PER_PASS command queries, oldest first; count what Zenoh's
        threads refused meanwhile."""
        for _ in range(min(ANSWERS_PER_PASS, len(self._queries))):
            self._answer(self._queries.popleft())
        with self._quota_lock:
            refused = +self._refused_offthread
        if refused != self._refused_moved:
            self.st.rejects.update(refused - self._refused_moved)
            self._refused_moved = refused

    def _answer(self, query: Any) -> None:
        """A command query (main thread): decide it, answer it (a lockstep vehicle fault: once
        Lockstep decides it, see _act), never raise."""
        parts = str(query.key_expr).split("/")
        sender = parts[4] if len(parts) == 5 and parts[1] == self.fleet and parts[2:4] == ["world", "cmd"] else "?"
        payload = _payload_bytes(query.payload)
        ref = self._next_ref
        self._next_ref += 1
        waiting = len(self._waiting) < MAX_WAITING
        try:
            if sender != keys.GROUND:  # the launcher puts; by query, only ground stations command
                self._reject(sender, "sender")
                op, by, verdict = "?", "", Verdict.no(f"commands by query are asked as {keys.GROUND!r} "
                                                      f"({keys.world_command(self.fleet, keys.GROUND)})")
            else:
                op, by, verdict = self._command(sender, payload, ref if waiting else None)
        except Exception as e:  # a bug of ours: the asker hears it, the run goes on
            self._reject(sender, "internal", f"{type(e).__name__}: {e}")
            op, by, verdict = "?", sender, Verdict.no(f"internal error in the world: {type(e).__name__}")
        if verdict is LATER:
            self._waiting[ref] = (query, op, by)
            return
        self._reply(query, op, by, verdict)

    def _reply(self, query: Any, op: str, by: str, v: Verdict) -> None:
        t = v.t if v.t is not None else (None if v.tick is None else v.tick * self.period)
        reply = CommandReply("applied" if v.applied else "rejected", op, printable(v.reason, MAX_REASON),
                             v.tick if v.applied else None, t if v.applied else None, by if ID_RE.match(
                                 by.replace(":", "_", 1)) else "")
        try:
            query.reply(str(query.key_expr), encode_reply(reply))
        except zenoh.ZError as e:  # the asker left (a ground station killed mid-command): nothing to tell
            self.log(f"could not answer {by}'s {op}: {printable(str(e), 120)}")
        finally:
            query.drop()

    def _decided(self, a: Decided) -> None:
        """Lockstep decided a vehicle fault a ground station waits on."""
        waiting = self._waiting.pop(a.ref, None)
        if waiting is not None:
            query, op, by = waiting
            self._reply(query, op, by, Verdict(True, "", a.tick) if a.reason is None else Verdict.no(a.reason))

    def _answer_the_rest(self, reason: str) -> None:
        """At the end: every query still waiting is answered (rejected: its fault never came)."""
        undecided = dict(self.lockstep.undecided())
        for ref, (query, op, by) in list(self._waiting.items()):
            tick = undecided.get(ref)
            self._reply(query, op, by, Verdict.no(reason + ("" if tick is None else f" (before its tick {tick})")))
        self._waiting.clear()
        self.clock.forget_faults()
        while self._queries:
            q = self._queries.popleft()
            self._reply(q, "?", "", Verdict.no(reason))

    def _on_command(self, sender: str, payload: bytes) -> None:
        """A command put on ``to/+world+/cmd/<sender>`` (the launcher, older clients): carried out
        as a query's would be; nobody is told the verdict (a vehicle fault is decided likewise). The
        ground credentials' puts share their queries' rate (COMMANDS_PER_S): past it, counted as
        `rate` and dropped."""
        if sender == keys.GROUND and self._over_quota(self._command_quota, "rate"):
            return
        self._command(sender, payload, None)

    def _command(self, sender: str, payload: bytes, ref: int | None) -> tuple[str, str, Verdict]:
        """Decide one command: (op, who sent it, verdict). Bad input is counted by reason."""
        if not ID_RE.match(sender):
            self._reject(sender, "key")
            return "?", "", Verdict.no("the command's key names no sender")
        c = decode_control(payload, COMMAND_OPS)
        if isinstance(c, Rejected):
            self._reject(sender, c.reason)
            return "?", sender, Verdict.no(f"the command could not be read: {c.reason}")
        by = sender if c.name is None else f"{sender}:{c.name}"
        if c.op == "fault_done" or c.op == "stop" and sender == keys.LAUNCHER:
            pass  # the launcher's own, whatever the run's state
        elif self.stop_requested or self.finished:
            return c.op, by, Verdict.no("the run is over" if self.finished else "the run is stopping")
        out = self.carry_out(c.op, c.fields, by, ref)  # world_sim.commands: parsed, then its handler
        if out is LATER:  # decided later; with nobody waiting, said applied from the next tick
            return c.op, by, LATER if ref is not None else Verdict(True, out.reason, self._effect_tick())
        if out is None:
            out = Verdict(True, "", self._effect_tick())
        elif isinstance(out, str):
            out = Verdict.no(out)
        return c.op, by, out
