"""The neighbour table: newest-wins storage and the stale-neighbour policies."""

import pytest

from cdus.core.guidance import Consensus
from cdus.wire.messages import OmegaMsg
from cdus.core.neighbours import POLICIES, NeighbourLink, NeighbourTable

LINKS = (NeighbourLink(k=1, weight=1.0, delta=0.5), NeighbourLink(k=3, weight=2.0, delta=-1.0))


def _msg(sender, seq, t_send, omega, rate=-1.0):
    return OmegaMsg(sender=sender, seq=seq, t_send=t_send, omega=omega, omega_rate=rate)


def test_offer_keeps_the_newest_and_counts_stale_and_duplicates():
    table = NeighbourTable(LINKS)
    assert table.offer(_msg(1, 5, 1.0, 10.0), now=1.0)
    assert not table.offer(_msg(1, 5, 1.0, 10.0), now=1.1)  # duplicate
    assert not table.offer(_msg(1, 3, 0.6, 10.4), now=1.2)  # stale (reordered)
    assert table.rejected_stale == 2
    assert table.latest[1].seq == 5 and table.received_at[1] == 1.0
    assert table.offer(_msg(1, 9, 1.8, 9.2), now=1.9)  # gaps are fine
    assert table.latest[1].omega == 9.2 and table.received_at[1] == 1.9
    assert table.rejected_stale == 2


def test_sequence_numbers_are_per_sender():
    table = NeighbourTable(LINKS)
    assert table.offer(_msg(1, 5, 1.0, 10.0), now=1.0)
    assert table.offer(_msg(3, 0, 1.0, 20.0), now=1.0)
    assert table.rejected_stale == 0


def test_accepts_only_linked_senders():
    table = NeighbourTable(LINKS)
    assert table.accepts(1) and table.accepts(3)
    assert not table.accepts(0) and not table.accepts(2)


def test_empty_table_gives_no_coupling():
    assert NeighbourTable(LINKS).consensus(5.0) == Consensus(0.0, 0.0, 0.0)


def test_hold_uses_the_last_values_as_they_are():
    table = NeighbourTable(LINKS, policy="hold")
    table.offer(_msg(1, 0, 1.0, 10.0, -1.0), now=1.0)
    table.offer(_msg(3, 0, 2.0, 20.0, -0.9), now=2.0)
    cons = table.consensus(100.0)  # however old, still used
    assert cons.W == pytest.approx(3.0)
    assert cons.B0 == pytest.approx(1.0 * (10.0 + 0.5) + 2.0 * (20.0 - 1.0))
    assert cons.B1 == 0.0


def test_timeout_drops_a_silent_neighbour():
    table = NeighbourTable(LINKS, policy="timeout", timeout=1.5)
    table.offer(_msg(1, 0, 1.0, 10.0), now=1.0)
    table.offer(_msg(3, 0, 1.0, 20.0), now=1.0)
    table.offer(_msg(3, 1, 2.0, 19.0), now=2.2)
    cons = table.consensus(2.5)  # neighbour 1 silent for exactly 1.5 s: still in
    assert cons.W == pytest.approx(3.0)
    assert cons.B0 == pytest.approx(10.5 + 2.0 * 18.0)
    cons = table.consensus(2.6)  # neighbour 1 silent for 1.6 s > 1.5 s: dropped
    assert cons == Consensus(2.0, 2.0 * 18.0, 0.0)
    assert table.consensus(2.5 + 1e-6).W == pytest.approx(2.0)
    table.offer(_msg(1, 1, 2.7, 9.0), now=2.7)  # heard again: back in
    assert table.consensus(2.8).W == pytest.approx(3.0)


def test_timeout_uses_the_receive_time_not_the_send_time():
    table = NeighbourTable(LINKS, policy="timeout", timeout=1.5)
    table.offer(_msg(1, 0, t_send=-100.0, omega=10.0), now=1.0)  # sender's clock is elsewhere
    assert table.consensus(2.0).W == pytest.approx(1.0)


def test_extrapolate_moves_the_value_with_the_sender_rate():
    table = NeighbourTable(LINKS, policy="extrapolate")
    table.offer(_msg(1, 0, 1.0, 10.0, -1.0), now=1.2)
    table.offer(_msg(3, 0, 1.5, 20.0, -0.8), now=1.6)
    t = 2.0
    cons = table.consensus(t)
    want_w1 = 10.0 - 1.0 * (t - 1.0)
    want_w3 = 20.0 - 0.8 * (t - 1.5)
    assert cons.W == pytest.approx(3.0)
    assert cons.B0 == pytest.approx(1.0 * (want_w1 + 0.5) + 2.0 * (want_w3 - 1.0))
    assert cons.B1 == pytest.approx(1.0 * -1.0 + 2.0 * -0.8)  # Σ a_ik ω̇_k


def test_extrapolation_cancels_a_delay_bias():
    """A neighbour exactly on the common rate: its extrapolated value is where it is now."""
    table = NeighbourTable((NeighbourLink(1, 1.0, 0.0),), policy="extrapolate")
    true_omega = lambda t: 5.0 - t  # noqa: E731
    table.offer(_msg(1, 0, 0.3, true_omega(0.3), -1.0), now=0.7)
    assert table.consensus(0.8).B0 == pytest.approx(true_omega(0.8))
    held = NeighbourTable((NeighbourLink(1, 1.0, 0.0),), policy="hold")
    held.offer(_msg(1, 0, 0.3, true_omega(0.3), -1.0), now=0.7)
    assert held.consensus(0.8).B0 - true_omega(0.8) == pytest.approx(0.5)  # τ·|ω̇|


def test_forget_removes_a_neighbour_from_the_sum():
    table = NeighbourTable(LINKS)
    table.offer(_msg(1, 4, 1.0, 10.0), now=1.0)
    table.offer(_msg(3, 4, 1.0, 20.0), now=1.0)
    table.forget(3)
    assert table.consensus(1.5) == Consensus(1.0, 10.5, 0.0)
    assert 3 not in table.ages(1.5)


def test_ages_use_the_send_time():
    table = NeighbourTable(LINKS)
    table.offer(_msg(1, 0, 1.0, 10.0), now=1.4)
    assert table.ages(2.0) == {1: pytest.approx(1.0)}


def test_unknown_policy_raises():
    with pytest.raises(ValueError) as info:
        NeighbourTable(LINKS, policy="interpolate")
    for p in POLICIES:
        assert p in str(info.value)
