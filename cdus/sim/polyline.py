"""What does a vehicle's path look like as points? Its polyline, for viewers and exports.

The Rerun sink draws it (``world/paths/<id>``, docs/rerun.md), the ROS 2 face publishes it as
``nav_msgs/msg/Path`` (docs/ros2.md).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cdus.core.paths import for_dimension, nearest_omega
from cdus.scenario.paths import make_path

PATH_POINTS = 400  # samples of a closed path's period


def path_polyline(vehicle: Any, duration: float) -> np.ndarray:
    """The path vehicle ``vehicle`` (a VehicleSpec) follows, as [M, 3] points (z = 0 on water).

    A closed path: one period. An open one: ω over the run, ω0 + s·[-10, duration + 10] s
    (steady state has ω̇ = s, the path's direction).
    """
    path = for_dimension(make_path(dict(vehicle.path)), vehicle.dim)
    if path.period is not None:
        ws = np.linspace(0.0, path.period, PATH_POINTS + 1)
    else:
        if vehicle.omega0 is not None:
            w0 = vehicle.omega0
        elif vehicle.start_position is not None:
            w0 = nearest_omega(path, tuple(vehicle.start_position))
        else:
            w0 = 0.0
        s = path.direction
        n = int(min(5000, max(PATH_POINTS, 20 * (duration + 20.0))))
        ws = w0 + s * np.linspace(-10.0, duration + 10.0, n)
    return pad3(np.array([path.eval(float(w))[0] for w in ws]))


def pad3(points: np.ndarray) -> np.ndarray:
    """[M, 2 or 3] points as [M, 3] (z = 0 for planar ones)."""
    out = np.zeros((len(points), 3))
    out[:, : points.shape[1]] = points
    return out
