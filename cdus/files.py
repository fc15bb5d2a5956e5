"""How cdus writes a file a person or another process reads: atomically."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any


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
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, p)


def _jsonable(x: Any) -> Any:
    if hasattr(x, "item"):
        return x.item()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")
