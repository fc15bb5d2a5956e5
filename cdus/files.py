"""How cdus writes a file a person or another process reads: atomically."""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Callable


def write_json(path: str | os.PathLike, data: Any, allow_inf: bool = False) -> None:
    """Write atomically (temp file + rename), so a reader never sees half a file. A path that
    exists and is not a regular file (/dev/stdout, a pipe, /dev/null) is written to directly,
    never replaced. ``allow_inf``: ±inf written as ``Infinity`` (Python's json reads it back), for
    a resolved scenario handed to a subprocess: its data may hold inf where the config takes it
    (``link.down.to``, ``radio.shadowing_distance``, ``radio.shadowing_time``)."""
    p = Path(path)
    text = json.dumps(data, indent=2, sort_keys=False, allow_nan=allow_inf, default=_jsonable) + "\n"
    if p.exists() and not p.is_file():
        with open(p, "w") as fh:
            fh.write(text)
        return
    if p.is_symlink():  # the file it names is written, the link kept (it was replaced by a file)
        p = Path(os.path.realpath(p))
    p.parent.mkdir(parents=True, exist_ok=True)
    # a temp name of its own: two writers of one file (two `cdus gs snapshot FILE`) shared FILE.tmp,
    # and one's rename found it gone (FileNotFoundError) or took the other's half-written one;
    # a FILE.tmp of the user's was overwritten and removed
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


#: The world's exit status when the run ended but its metrics could not be written where asked
#: (a full disk, a read-only directory): the world said which file and why in its log, and kept
#: them at the first of :func:`metrics_fallbacks` that took them. Not a lost world: the launcher
#: looks for them there (cdus.app.launcher).
METRICS_ELSEWHERE_EXIT = 3


def metrics_fallbacks(metrics_out: str | os.PathLike, run_dir: str | os.PathLike | None, tag: str) -> list[Path]:
    """Where metrics go when ``metrics_out`` cannot be written, in order: the run directory's
    ``metrics.json`` (when ``metrics_out`` is elsewhere), then ``cdus-metrics-<tag>.json`` in the
    temporary directory (another file system, often). ``tag`` names the writer (the world's
    fleet and process id): the launcher computes the same list to find them."""
    out = Path(metrics_out)
    places = []
    if run_dir is not None and Path(run_dir, "metrics.json").resolve() != out.resolve():
        places.append(Path(run_dir, "metrics.json"))
    places.append(Path(tempfile.gettempdir(), f"cdus-metrics-{tag}.json"))
    return places


def keep_json(path: str | os.PathLike, data: Any, elsewhere: list[Path], log: Callable[[str], None],
              what: str = "the metrics") -> Path | None:
    """``data`` written to ``path`` (:func:`write_json`), or, if that fails (ENOSPC, EROFS, any
    OSError), to the first of ``elsewhere`` that takes it; every failure told through ``log``
    (which file, why). Returns where the data is, None if nowhere (the caller keeps it some other
    way: printed)."""
    for place in [Path(path), *elsewhere]:
        try:
            write_json(place, data)
        except OSError as e:
            log(f"error: could not write {what} to {place}: {e.strerror or e}")
            continue
        if place != Path(path):
            log(f"{what} were kept in {place} instead of {path}")
        return place
    return None


def _umask() -> int:
    """The process's umask, read without changing it (os.umask would, for every thread a moment):
    mkstemp makes 0600 files, a written file gets the mode open() would give it."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    return 0o022


def _jsonable(x: Any) -> Any:
    if hasattr(x, "item"):
        return x.item()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")
