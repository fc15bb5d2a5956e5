"""What can a JSON file hold, and where in it? Any small JSON value (a Hypothesis strategy) and
every path into a decoded tree: for tests that spoil a file anywhere (the metrics' decoders)."""

from __future__ import annotations

from typing import Any, Iterator

from hypothesis import strategies as st

#: any small JSON value (no NaN: a value that is not equal to itself would not compare)
JSON = st.recursive(st.none() | st.booleans() | st.integers(-10, 10) | st.floats(allow_nan=False) | st.text(max_size=4),
                    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner, max_size=3),
                    max_leaves=6)


def paths(d: Any, prefix: tuple = ()) -> Iterator[tuple]:
    """Every path (keys and indices) into ``d``, the empty one first."""
    yield prefix
    if isinstance(d, dict):
        for k, v in d.items():
            yield from paths(v, (*prefix, k))
    elif isinstance(d, list):
        for j, v in enumerate(d):
            yield from paths(v, (*prefix, j))
