"""Attacks on the world's command handling as a ground station can make them (rev-gs): faults
put without a query, fuzzed formation/path/radio commands, forged replies. No network: the
world's fakes of tests/world_sim."""

from __future__ import annotations

from cdus.wire import keys
from cdus.wire.messages import LAUNCHER_OPS, decode_control, encode_control
from tests.fakes import Payload, Sample
from tests.world_sim.test_world import FLEET, world
from tests.world_sim.test_world_commands import ask, launcher_done


def _put(w, op: str, **fields) -> None:
    """A command put on to/+world+/cmd/gs (the ground role may: GroundStation.send, older clients)."""
    w._handle(Sample(keys.world_cmd(FLEET, keys.GROUND), Payload(encode_control(op, **fields))))


def test_realtime_a_put_faults_word_from_the_launcher_does_not_answer_a_later_query():
    """A ground station's kill of usv2 put (no answer asked) then another's restart of usv2 asked:
    the launcher's fault_done for the kill answered the restart 'applied' before the launcher
    had restarted anything (the put fault held no place in the per-vehicle queue)."""
    w = world(clock="realtime")
    for vid in w.ids:
        w._on_alive(vid, True)
    _put(w, "kill", vehicle="usv2")
    q = ask(w, "restart", vehicle="usv2")
    assert [decode_control(p, LAUNCHER_OPS).op for p in w.pub_launcher.puts] == ["kill", "restart"]
    launcher_done(w, "usv2")  # the kill
    assert q.answer is None
    launcher_done(w, "usv2")  # the restart
    assert q.answer is not None and q.answer.applied and q.answer.op == "restart"
    assert not any(w._rt_asked.values())
