"""Which sink does a ``--rerun`` value make?

``off`` a :class:`~cdus.sim.sink.NullSink`, without importing Rerun at all: Rerun and the
pandas it pulls in are ~0.8 s of CPU, most of a world process's start-up, and most runs
(every test fleet) record nothing (tests/test_startup.py). Anything else a
:class:`world_sim.rerun_sink.RerunSink`, Rerun imported there.
"""

from __future__ import annotations

from pathlib import Path

from cdus.sim.sink import NullSink, Sink
from world_sim.recording import parse_spec


def make_sink(spec: str | None, run_dir: Path | None = None) -> Sink:
    """A sink for ``--rerun SPEC``: ``off`` | ``auto`` | ``spawn`` | ``save:PATH`` | ``connect[:URL]``,
    comma-separated to combine. ``off`` (or None) gives a :class:`NullSink` and imports no
    Rerun; anything else a Rerun sink. A bad spec raises ValueError."""
    targets = parse_spec(spec, run_dir)
    if not targets:
        return NullSink()
    from world_sim.rerun_sink import RerunSink  # only a recording pays for Rerun

    return RerunSink(targets)
