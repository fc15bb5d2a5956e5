"""A file system with no room left: a 64 KiB tmpfs, filled, for the tests of a full disk.

Mounting needs root: without it (or where tmpfs cannot be mounted) the test is skipped, not
faked. Unmounted in teardown."""

from __future__ import annotations

import errno
import os
import subprocess
from pathlib import Path

import pytest


@pytest.fixture
def full_fs(tmp_path):
    """A directory on a full file system: writing a byte there fails with ENOSPC."""
    where = tmp_path / "full"
    where.mkdir()
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs (a full disk) needs root")
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(where)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.decode(errors='replace').strip()}")
    try:
        fd = os.open(where / "filler", os.O_WRONLY | os.O_CREAT)
        try:  # fill it: the last write is refused
            while os.write(fd, b"\0" * 4096):
                pass
        except OSError as e:
            assert e.errno == errno.ENOSPC, e
        finally:
            os.close(fd)
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False)


def no_room(where: Path) -> bool:
    """Is ``where`` really full (a byte cannot be written)?"""
    try:
        with open(where / ".probe", "wb") as fh:
            fh.write(b"x")
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as e:
        return e.errno == errno.ENOSPC
    return False
