"""Where do a recording's files go, and is there room for them? The segments' directory, a
write flushed to the disk, the free space and the size a run is expected to take, and the merge
of the segments into one .rrd.

The file side of world_sim.rerun_sink (which streams the run and writes each segment through
:func:`_write_whole`, docs/rerun.md "After a crash")."""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

import rerun as rr
from rerun.chunk import RrdReader

from world_sim.recording import PARTS_SUFFIX
from world_sim.rerun_draw import APP_ID

#: Measured .rrd size per vehicle and simulated second at 50 Hz: 7.6 kB (lake_circle, 60 s),
#: 7.7 kB (lissajous_5x5); rounded up. A clean close needs twice the recording (the segments
#: and the merged file) for a moment.
BYTES_PER_VEHICLE_SECOND = 8_000


def expected_bytes(vehicles: int, seconds: float) -> int:
    """About how large a recording of ``vehicles`` over ``seconds`` simulated seconds gets."""
    return int(BYTES_PER_VEHICLE_SECOND * max(1, vehicles) * max(0.0, seconds))


def _parts(path: Path) -> Path:
    """The directory of the segments of ``save:path``: ``path.parts``."""
    return path.with_name(path.name + PARTS_SUFFIX)


def _segment(parts: Path, n: int) -> Path:
    return parts / f"{n:03d}.rrd"


def _write_whole(path: Path, data: bytes) -> None:
    """``data`` into ``path``, flushed to the disk, or OSError (ENOSPC, EFBIG...)."""
    with open(path, "wb") as fh:
        fh.write(data)
        fh.flush()
        if os.path.isfile(path):  # not a pipe or a terminal
            os.fsync(fh.fileno())


def _free_bytes(where: Path) -> int | None:
    """Free bytes on the file system of ``where`` (or of its nearest existing parent); None if unknown."""
    for p in (where, *where.parents):
        try:
            return shutil.disk_usage(p).free
        except OSError:
            continue
    return None


def merge_segments(path: Path, parts: Path, recording_id: str, blueprint: Any) -> None:
    """The segments of ``parts`` as one .rrd at ``path``; ``parts`` removed after."""
    segments = sorted(parts.glob("*.rrd"))
    regular = not path.exists() or path.is_file()
    if len(segments) == 1 and regular:
        os.replace(segments[0], path)
    else:
        size = sum(f.stat().st_size for f in segments)
        free = _free_bytes(path.parent)
        if free is not None and free < size:
            raise OSError(28, f"{free / 1e6:.1f} MB free, {size / 1e6:.1f} MB needed to merge")
        final = rr.RecordingStream(APP_ID, recording_id=recording_id)
        out = final.binary_stream()
        for seg in segments:
            reader = RrdReader(str(seg))
            for store in reader.recordings():
                rr.send_chunks(reader.stream(store=store), recording=final)
        if blueprint is not None:
            final.send_blueprint(blueprint)
        data = out.read(flush=True, flush_timeout_sec=60.0) or b""
        final.disconnect()
        _write_whole(path, data)
    for seg in segments:
        seg.unlink(missing_ok=True)
    try:
        parts.rmdir()
    except OSError:
        pass  # something else was put there: leave it
