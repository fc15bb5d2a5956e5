"""How a value a person wrote is shown back to them in an error message (TOML spelling)."""

from __future__ import annotations

import math
from typing import Any


def quote(s: Any) -> str:
    return '"' + str(s).replace('"', '\\"') + '"'


def show(v: Any) -> str:
    """A value as the user wrote it in TOML."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return quote(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else str(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(show(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {show(x)}" for k, x in v.items()) + "}"
    return repr(v)
