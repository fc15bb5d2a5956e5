"""How cdus writes a file a person or another process reads: atomically."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any


def write_json(path: str | os.PathLike, data: Any) -> None:
    """Write atomically (temp file + rename), so a reader never sees half a file. A path that
    exists and is not a regular file (/dev/stdout, a pipe, /dev/null) is written to directly,
    never replaced."""
    p = Path(path)
    text = json.dumps(data, indent=2, sort_keys=False, allow_nan=False, default=_jsonable) + "\n"
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
