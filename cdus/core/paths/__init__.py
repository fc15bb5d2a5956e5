"""What is a path? A parametric curve f(ω) with f', f'' in closed form.

One small module per family (``circle``, ``ellipse``, ``lissajous``, ``self_intersecting``,
``trefoil``, ``line``, ``spline``), each giving ``eval(ω) -> (f, f', f'')`` and nothing else, and
declaring itself once in the registry (:mod:`cdus.core.paths.registry`: its name, parameters and
constructor); the guidance never knows which path it follows (the Paparazzi ``gvf_parametric``
separation). Vectors are plain tuples of floats: at 2-3 components, pure Python is several times
faster than NumPy and keeps the agent's control loop cheap. Reading a config table into a path is
the scenario layer's (``cdus.scenario.paths.make_path``).

Every family takes ``beta`` (speed scaling, f(ω) -> f(βω): the on-path speed becomes
β|f0'| at |ω̇| = 1) and ``direction`` s = ±1 (the paper's (-1)^3 = -1 is the default;
the guidance uses s as the travel direction, docs/control.md §2).
"""

from __future__ import annotations

from cdus.core.paths.registry import FAMILIES, REGISTRY, TAU, Family, Param, Path, PathError, Vec, register
from cdus.core.paths.geometry import PROBE_OMEGAS, Planar, for_dimension, nearest_omega, not_finite_at
from cdus.core.paths.circle import Circle
from cdus.core.paths.ellipse import Ellipse
from cdus.core.paths.lissajous import RETRACE_TURNS, Lissajous, turning_point
from cdus.core.paths.self_intersecting import self_intersecting
from cdus.core.paths.trefoil import Trefoil
from cdus.core.paths.line import Line
from cdus.core.paths.spline import Spline, spline

__all__ = ["FAMILIES", "REGISTRY", "TAU", "Family", "Param", "Path", "PathError", "Vec", "register",
           "PROBE_OMEGAS", "Planar", "for_dimension", "nearest_omega", "not_finite_at",
           "Circle", "Ellipse", "RETRACE_TURNS", "Lissajous", "turning_point", "self_intersecting", "Trefoil",
           "Line", "Spline", "spline"]
