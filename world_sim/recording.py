"""Where does the world's picture go? The ``--rerun`` targets and the sink they make.

The sink interface the runners feed is :mod:`cdus.sim.sink`. A ``--rerun`` value is
parsed here into targets, without importing Rerun (a bad value starts nothing);
:func:`world_sim.sinks.make_sink` turns it into a sink.
"""

from __future__ import annotations

import os
import shlex
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping


DEFAULT_URL = "rerun+http://127.0.0.1:9876/proxy"  # where `rerun` listens by default
RECORDING_NAME = "recording.rrd"  # the file `auto` writes into the run directory
PARTS_SUFFIX = ".parts"  # PATH.parts/NNN.rrd: the segments of save:PATH while it is written (rerun_sink)
SPEC_FORMS = ("off", "auto", "spawn", "save:PATH", "connect[:URL]")


@dataclass(frozen=True)
class Target:
    """One place the stream goes: ``spawn`` (a new viewer), ``save`` (an .rrd file at
    ``where``) or ``connect`` (a running viewer at the URL ``where``)."""

    kind: str
    where: str = ""


def has_display(env: Mapping[str, str] | None = None) -> bool:
    """Can a viewer window open here? Linux needs X11 or Wayland; macOS and Windows always can."""
    env = os.environ if env is None else env
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"))


def parse_spec(spec: str | None, run_dir: Path | None = None,
               env: Mapping[str, str] | None = None) -> tuple[Target, ...]:
    """The targets of a ``--rerun`` value; ``()`` for ``off``. Raises ValueError naming the valid forms.

    ``auto`` is ``spawn`` when there is a display, else ``save:<run_dir>/recording.rrd``
    (the current directory without a run directory). Items combine with commas
    (``spawn,save:run.rrd``: a viewer and a file at once).
    """
    if spec is None or spec.strip() in ("", "off"):
        return ()
    targets: list[Target] = []
    for raw in spec.split(","):
        item = raw.strip()
        name, sep, arg = item.partition(":")
        name = name.strip().lower()
        if name == "off":
            _bad(spec, "off cannot be combined with other sinks")
        elif name == "auto" and not sep:
            if has_display(env):
                targets.append(Target("spawn"))
            else:
                targets.append(Target("save", str((run_dir or Path(".")) / RECORDING_NAME)))
        elif name == "spawn" and not sep:
            if not has_display(env):
                _bad(spec, "spawn needs a display (DISPLAY or WAYLAND_DISPLAY is unset); use save:PATH "
                           "and open the file with `rerun PATH`, or auto")
            targets.append(Target("spawn"))
        elif name == "save":
            path = arg.strip()
            if not path:
                _bad(spec, "save needs a file, e.g. save:runs/lake.rrd")
            targets.append(Target("save", path))
        elif name == "connect":
            url = arg.strip() or DEFAULT_URL
            if not url.startswith(("rerun+http://", "rerun+https://", "rerun://")):
                _bad(spec, f"connect needs a Rerun URL such as {DEFAULT_URL}, got {url!r}")
            targets.append(Target("connect", url))
        else:
            _bad(spec, f"unknown sink {item!r}")
    unique: list[Target] = []
    for t in targets:
        if t not in unique:
            unique.append(t)
    return tuple(unique)


def _bad(spec: str, why: str) -> None:
    raise ValueError(f"--rerun {spec!r}: {why}; valid forms: {' | '.join(SPEC_FORMS)}, "
                     f"comma-separated to combine (e.g. spawn,save:run.rrd)")


def recording_line(path: Path) -> str:
    """What a ``save:path`` recording left, said as it is: the file; or, when the run was cut
    short (a SIGKILLed world, a disk that filled before the segments could be merged), its
    segments in ``path.parts``; or that there is none (the world's log says why)."""
    q = shlex.quote(str(path))
    if path.is_file() and path.stat().st_size > 0:
        return f"  recording: {path} (open it with: rerun {q})"
    parts = path.with_name(path.name + PARTS_SUFFIX)
    segments = sorted(parts.glob("*.rrd")) if parts.is_dir() else []
    if segments:
        return (f"  recording: {path} was not written; what was recorded is in {len(segments)} segments (open them "
                f"with: rerun {shlex.quote(str(parts))}/*.rrd; the world's log says why)")
    return f"  recording: none; {path} was not written (the world's log says why)"

