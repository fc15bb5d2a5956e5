"""What does a decoder return for bytes it does not take? A :class:`Rejected`, with the reason.

Every decoder of :mod:`cdus.wire` returns the record it decoded or ``Rejected(reason)``, and
never raises, so a receiver counts the reason and drops the message without a try/except:

    msg = decode_omega(payload)
    if isinstance(msg, Rejected):
        counters[msg.reason] += 1

A reason is a short lowercase word (``malformed``, ``version``, ``type``, ``range``, ...) that
the decoder's docstring lists; the receivers count them by name in their ``rejected_by_reason``.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Rejected:
    """A message a decoder did not take, and why."""

    reason: str
