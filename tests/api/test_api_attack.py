"""Trace.from_npz on crafted files: a ValueError naming the file (or an OSError for a missing
one), never an exception from deep inside numpy, and never an unpickling."""

from __future__ import annotations

import io
import os
import pickle
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cdus.api import TRACE_ARRAYS, Trace

NAMES = (*TRACE_ARRAYS, "ids", "edge_names", "interventions")


def _good() -> dict:
    T, N, E = 4, 2, 1
    return {"t": np.arange(T, dtype=float), "ids": np.array(["a", "b"]), "q": np.zeros((T, N, 3)),
            "heading": np.zeros((T, N)), "omega": np.zeros((T, N)), "omega_rate": np.zeros((T, N)),
            "path_error": np.zeros((T, N)), "edge_error": np.zeros((T, E)), "edge_names": np.array(["a-b"]),
            "live": np.ones((T, N), bool)}


def _npy(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=True)
    return buf.getvalue()


class _Evil:
    def __reduce__(self):
        return (os.system, ("touch PWNED",))


_member = st.one_of(
    st.binary(max_size=40),  # not a .npy at all
    st.just(_npy(np.array([_Evil()], dtype=object))),  # a pickle inside: must not be loaded
    st.sampled_from([_npy(np.array(["x", "y"])), _npy(np.zeros(())), _npy(np.zeros((4, 2, 3, 1))),
                     _npy(np.zeros((4, 2), complex)), _npy(np.array([b"a"])), _npy(np.zeros((0,)))]))


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.dictionaries(st.sampled_from(NAMES), _member, max_size=4), st.booleans())
def test_a_crafted_npz_is_a_value_error_and_nothing_is_unpickled(tmp_path, monkeypatch, replaced, keep_rest):
    monkeypatch.chdir(tmp_path)
    members = {k: _npy(v) for k, v in _good().items()} if keep_rest else {}
    members.update(replaced)
    path = tmp_path / "t.npz"
    with zipfile.ZipFile(path, "w") as zf:
        for k, data in members.items():
            zf.writestr(k + ".npy", data)
    try:
        Trace.from_npz(path)
    except ValueError as e:
        assert str(path) in str(e)
    assert not (tmp_path / "PWNED").exists()


@pytest.mark.parametrize("content", [b"", b"PK\x03\x04garbage", _npy(np.zeros(3)), pickle.dumps([1])])
def test_a_file_that_is_not_an_npz_archive_is_a_value_error_naming_it(tmp_path, content):
    path = tmp_path / "t.npz"
    path.write_bytes(content)
    with pytest.raises(ValueError, match="t.npz: not a cdus trace"):
        Trace.from_npz(path)


def test_a_saved_trace_still_reads_back(tmp_path):
    Trace(**{k: v for k, v in _good().items() if k not in ("ids", "edge_names")}, ids=("a", "b"),
          edge_names=("a-b",)).save(tmp_path / "t.npz")
    tr = Trace.from_npz(tmp_path / "t.npz")
    assert tr.ids == ("a", "b") and tr.edge_names == ("a-b",) and len(tr) == 4 and tr.interventions is None
