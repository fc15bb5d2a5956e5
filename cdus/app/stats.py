"""What are the statistics of a sweep's cells, and how are numbers worded for a person? The mean,
standard deviation and a bootstrap confidence interval of the mean, and the wording.

The interval is the percentile bootstrap: resample the cell's values with replacement
(``RESAMPLES`` times, numpy's generator seeded with ``SEED``), take each resample's mean,
and report the (1 - level) / 2 and (1 + level) / 2 quantiles of those means. Seeded, so a
summary is the same every time it is written from the same rows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable

import numpy as np

LEVEL = 0.95
RESAMPLES = 2000
SEED = 0
CI_WORDS = (f"{LEVEL:.0%} percentile bootstrap confidence interval of the mean "
            f"({RESAMPLES:,} resamples, seeded)").replace("%", " %")
CI_SHORT = f"{LEVEL:.0%} bootstrap CI of the mean".replace("%", " %")


@dataclass(frozen=True)
class Stat:
    """What a cell's values say: how many, their mean, their sample standard deviation
    (None below 2 values) and the bootstrap interval of the mean (lo == hi == the value for
    a single value; all None for none)."""
    n: int
    mean: float | None
    std: float | None
    lo: float | None
    hi: float | None


def bootstrap_ci(values: Iterable[float], level: float = LEVEL, resamples: int = RESAMPLES,
                 seed: int = SEED) -> tuple[float, float] | None:
    """The percentile bootstrap interval of the mean of ``values`` (None for no value)."""
    x = np.asarray([float(v) for v in values], dtype=float)
    if x.size == 0:
        return None
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level}")
    if x.size == 1 or np.all(x == x[0]):
        return float(x[0]), float(x[0])
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, x.size, size=(resamples, x.size))
    means = x[idx].mean(axis=1)
    lo, hi = np.quantile(means, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return float(lo), float(hi)


def describe(values: Iterable[float], seed: int = SEED) -> Stat:
    """n, mean, standard deviation (n - 1) and the bootstrap interval of the finite values."""
    x = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    if not x:
        return Stat(0, None, None, None, None)
    arr = np.asarray(x)
    lo, hi = bootstrap_ci(arr, seed=seed)
    std = float(arr.std(ddof=1)) if arr.size > 1 else None
    return Stat(arr.size, float(arr.mean()), std, lo, hi)


def fmt_number(x: Any, digits: int = 1) -> str:
    """A number as a person reads it: ``141.42000000000002`` -> ``141.4``; small values keep
    three significant digits (``0.000236`` -> ``0.000236``), never ``None`` or ``nan``."""
    if x is None:
        return "n/a"
    x = float(x)
    if not math.isfinite(x):
        return "n/a"
    if x != 0 and abs(x) < 10 ** -(digits - 1):  # too small for ``digits`` decimals to say much
        return f"{x:.3g}"
    return f"{x:.{digits}f}"


def fmt_seconds(x: Any, digits: int = 1, none: str = "never") -> str:
    """A duration: ``141.42000000000002`` -> ``141.4 s``; None (a run that never settled) ->
    ``never``."""
    return none if x is None else f"{fmt_number(x, digits)} s"


def fmt_stat(s: Stat, digits: int = 1, never: int = 0) -> str:
    """``mean ± sd [lo, hi]`` for a summary table; ``-`` for no value; ``(k never)`` appended
    when k runs gave no value (a settle time of a run that did not settle)."""
    if s.n == 0:
        text = "never" if never else "-"
        return text
    text = fmt_number(s.mean, digits)
    if s.std is not None:
        text += f" ± {fmt_number(s.std, digits)}"
    if s.n > 1:
        text += f" [{fmt_number(s.lo, digits)}, {fmt_number(s.hi, digits)}]"
    return text + (f" ({never} never)" if never else "")


def fmt_duration(seconds: float) -> str:
    """Wall time for a progress or summary line: ``75.3 s``, ``12 min 5 s``, ``3 h 02 min``."""
    s = max(0.0, float(seconds))
    if s < 60:
        return f"{s:.1f} s"
    if s < 3600:
        return f"{int(s // 60)} min {int(s % 60)} s"
    return f"{int(s // 3600)} h {int(s % 3600 // 60):02d} min"
