"""What does the viewer show, and where? The Rerun layout of a cdus recording.

Left: the 3-D world (paths, vehicles, trails) over the link timeline and the event log.
Right: the time series (path error, coordination error, ω̇). The time panel runs on
``sim_time`` and follows the newest data. The entity paths are docs/rerun.md's.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import rerun.blueprint as rrb

WORLD = "world"
PATHS = "world/paths"
VEHICLES = "world/vehicles"
TRAILS = "world/trails"
PATH_ERROR = "metrics/path_error"
COORD_ERROR = "metrics/coord_error"
OMEGA_RATE = "metrics/omega_rate"
LINKS = "comms/links"
RADIO_LINKS = "world/radio/links"  # [radio]: each link coloured by its delivery probability
RADIO_STATION = "world/radio/station"
UTILISATION = "metrics/radio_utilisation"
EVENTS = "comms/events"
TIMELINE = "sim_time"


def camera(points: np.ndarray) -> tuple[Sequence[float], Sequence[float]]:
    """(eye position, look target) that frame ``points`` [M, 3] from the south-west, above."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    target = (lo + hi) / 2.0
    target[2] = lo[2] + 0.4 * (hi[2] - lo[2])
    size = float(max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1.0))
    direction = np.array([-0.55, -1.0, 0.75])
    eye = target + 1.05 * size * direction / np.linalg.norm(direction)
    return eye.tolist(), target.tolist()


def blueprint(scene_points: np.ndarray | None = None, radio: bool = False) -> rrb.Blueprint:
    """The layout; ``scene_points`` (paths and starts) place the 3-D camera; ``radio``: a
    scenario with [radio] gets the channel utilisation's plot too."""
    eye = None
    if scene_points is not None and len(scene_points):
        position, target = camera(scene_points)
        eye = rrb.EyeControls3D(position=position, look_target=target, eye_up=[0.0, 0.0, 1.0])
    world = rrb.Spatial3DView(origin=WORLD, name="World", eye_controls=eye)
    whole_run = rrb.TimeAxis(view_range=rrb.TimeRange(start=rrb.TimeRangeBoundary.infinite(),
                                                      end=rrb.TimeRangeBoundary.infinite()))
    links = rrb.StateTimelineView(origin=LINKS, name="Links (src → dst)", time_view=whole_run)
    events = rrb.TextLogView(origin=EVENTS, name="Events")
    top_right, bottom_right = rrb.PlotLegend(corner="RightTop"), rrb.PlotLegend(corner="RightBottom")
    series = rrb.Vertical(  # the whole run; legends where the curves settle (errors -> 0, ω̇ -> ±1)
        rrb.TimeSeriesView(origin=PATH_ERROR, name="Path error |Φ| (m)", plot_legend=top_right,
                           axis_x=whole_run),
        rrb.TimeSeriesView(origin=COORD_ERROR, name="Coordination error |ω_i − ω_k − Δ_ik|", plot_legend=top_right,
                           axis_x=whole_run),
        rrb.TimeSeriesView(origin=OMEGA_RATE, name="ω̇", plot_legend=bottom_right, axis_x=whole_run),
        *([rrb.TimeSeriesView(origin=UTILISATION, name="Radio channel utilisation", axis_x=whole_run)]
          if radio else []),
    )
    left = rrb.Vertical(world, rrb.Horizontal(links, events, column_shares=[3, 2]), row_shares=[3, 1])
    return rrb.Blueprint(
        rrb.Horizontal(left, series, column_shares=[3, 2]),
        rrb.TimePanel(timeline=TIMELINE, state="collapsed", play_state="following"),
        collapse_panels=True,
    )
