"""What does the launcher write when the world is lost? Where the world's metrics went, or its own.

The world writes the run's metrics.json; if it dies first, the launcher writes what it knows
(``completed: false``, ``completion: "world_lost"``, the world's last status). A world that
could not write where asked (a full disk) kept them in a fallback place the launcher finds
(cdus.files.metrics_fallbacks). :class:`WorldLostMetrics` is the Launcher's part that does this.
"""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

from cdus.app.report import WORLD_LOST
from cdus.core.metrics import Recorder
from cdus.files import keep_json, metrics_fallbacks
from cdus.sim.build import metric_edges
from cdus.sim.runmetrics import Integrity, Metrics, WorldLost
from cdus.sim.summary import run_metrics
from cdus.wire import keys
from cdus.wire.schemas import FleetEvent


class WorldLostMetrics:
    """The launcher's metrics for a lost world (mixed into cdus.app.launcher.Launcher, whose
    ``scenario``, ``opts``, ``children``, ``status``, ``alive``, ``rejected``, ``metrics_out``,
    ``run_dir``, ``fleet`` and ``log`` it reads)."""

    def metrics_mark(self, path: Path | None = None) -> tuple | None:
        """What the metrics file (or ``path``) is now (None: absent), to tell later whether the world wrote it."""
        try:
            st = os.stat(path or self.metrics_out)
        except OSError:
            return None
        return (st.st_ino, st.st_mtime_ns, st.st_size)

    def world_fallbacks(self) -> list[Path]:
        """Where the world keeps its metrics when it cannot write them to metrics_out (a full disk;
        cdus.files.metrics_fallbacks, as the world computes them)."""
        w = self.children.get(keys.WORLD)
        if w is None or w.proc is None:
            return []
        return metrics_fallbacks(self.metrics_out, self.run_dir, f"{self.fleet}-{w.proc.pid}")

    def find_world_metrics(self, marks: dict[Path, tuple | None]) -> Path | None:
        """Where the world wrote its metrics in this run: metrics_out or a fallback that changed
        since ``marks`` (their :meth:`metrics_mark` before the run); None: it wrote none."""
        for place in (self.metrics_out, *self.world_fallbacks()):
            now = self.metrics_mark(place)
            if now is not None and now != marks.get(place):
                return place
        return None

    def write_world_lost(self, code: int, wall_s: float) -> Metrics:
        """The world died without writing its metrics: write what the launcher knows (an empty
        record, ``completed: false``, ``completion: "world_lost"``, the world's last status)."""
        sc = self.scenario
        if self.opts.duration is not None:
            sc = replace(sc, duration=self.opts.duration)
        rec = Recorder(list(sc.ids), [v.dim for v in sc.vehicles], metric_edges(sc))
        st = self.status  # the world's last status (WorldStatus), None if none was heard
        events = list(st.events) if st is not None else []
        how = f"exited with status {code}" if code >= 0 else f"was killed by signal {-code}"
        t_last = st.t if st is not None else None
        events.append(FleetEvent.of(t_last or 0.0, "fault", f"the world process {how}; the launcher wrote these "
                                    "metrics from the world's last status", severity="error"))
        ignored = self.rejected.get("token_key", 0)
        integrity = Integrity(tampered=bool(ignored), reasons={"token_key": ignored} if ignored else {},
                              notes=(f"the launcher ignored {ignored} liveliness tokens on keys no process declares",)
                              if ignored else ())
        m = run_metrics(sc, rec, mode=self.opts.clock, link=None, wall_s=wall_s,
                        policy=self.opts.policy or sc.link.policy, events=events, completed=False,
                        completion=WORLD_LOST, integrity=integrity)
        last = None
        if st is not None:  # what the world last said, in the fields a reader looks at first (the trace is lost)
            ran = max(0.0, t_last)  # a status before tick 0 says t = -T: no simulated time has passed
            m = replace(m, duration_s=ran, realtime_factor=ran / wall_s if wall_s > 0 else None,
                        final_path_error_max=st.path_error_max, final_coord_error_max=st.coord_error_max,
                        live_final=tuple(sorted(set(st.alive) & set(sc.ids))))
            last = {k: getattr(st, k) for k in ("alive", "path_error_max", "coord_error_max", "paused")}
        lost = WorldLost(world_exit=code, last_status_t=t_last, last_status=last,
                         alive_tokens=tuple(sorted(self.alive & set(sc.ids))),  # the scenario's names only
                         restarts={n: c.restarts for n, c in self.children.items() if n != keys.WORLD and c.restarts},
                         rejected_by_launcher=dict(self.rejected))
        m = replace(m, written_by="launcher", world_lost=lost)
        fallbacks = metrics_fallbacks(self.metrics_out, self.run_dir, f"{self.fleet}-launcher-{os.getpid()}")
        self.metrics_at = keep_json(self.metrics_out, m.to_dict(), fallbacks, self.log)
        if self.metrics_at is None:  # no disk takes them: the terminal does
            self.log("the metrics could be written nowhere; here they are:")
            self.log(json.dumps(m.to_dict()))
        return m
