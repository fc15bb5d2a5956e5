"""How is a run drawn in Rerun: the colours, markers, trails and the Arrow columns it takes?

The pure drawing of world_sim.rerun_sink (which streams and files what is drawn here): a
vehicle's colour by kind and rank, the size of its marker, its yaw, the trail's rows, the
safety and radio colours, the obstacles' outlines, and the columnar batches (one Arrow column per
entity) that make a run's many rows one send."""

from __future__ import annotations

from typing import Any, Iterable, Sequence

import numpy as np
import pyarrow as pa
import rerun as rr

from world_sim import blueprint as bp


APP_ID = "cdus"
TRAIL_SECONDS = 10.0  # length of a trail
TRAIL_POINTS_EVERY = 10  # ticks between trail points (5 Hz at 50 Hz control)
USV_COLOURS = ((31, 119, 180), (0, 170, 220), (70, 90, 220), (40, 150, 170), (110, 150, 255), (20, 80, 150))
UAV_COLOURS = ((255, 127, 14), (230, 85, 13), (250, 175, 40), (215, 110, 60), (255, 150, 90), (190, 95, 0))
EDGE_COLOURS = ((44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75), (227, 119, 194),
                (127, 127, 127), (188, 189, 34), (23, 190, 207), (100, 60, 160), (60, 120, 60))


STATE_COLOURS = {"up": (76, 175, 80), "lossy": (255, 193, 7), "down": (239, 83, 80)}
LEVELS = {"info": rr.TextLogLevel.INFO, "warn": rr.TextLogLevel.WARN, "error": rr.TextLogLevel.ERROR}  # by severity
INTERVENTION_COLOUR = (230, 30, 30)
NEAR_COLOUR, CLOSEST_COLOUR = (230, 30, 30), (255, 193, 7)  # a closest approach below R / at or above it


def colour(kind: str, rank: int) -> tuple[int, int, int]:
    """The colour of the ``rank``-th vehicle of its kind."""
    palette = USV_COLOURS if kind == "usv" else UAV_COLOURS
    return palette[rank % len(palette)]


def marker_size(lines: Sequence[np.ndarray]) -> float:
    """A length for the vehicle markers: 1 for the lake's 20 m circle, more for bigger scenes."""
    if not lines:
        return 1.0
    pts = np.concatenate(lines)
    extent = float(max(np.ptp(pts[:, 0]), np.ptp(pts[:, 1]), 1.0))
    return min(25.0, max(0.5, extent / 20.0))


def yaw_quaternions(heading: np.ndarray) -> np.ndarray:
    """[n] yaw angles -> [n, 4] quaternions (x, y, z, w) about +z."""
    half = 0.5 * np.asarray(heading, dtype=float)
    q = np.zeros((len(half), 4))
    q[:, 2] = np.sin(half)
    q[:, 3] = np.cos(half)
    return q


def trail_indices(i: int, window: int, stride: int) -> np.ndarray:
    """Rows of the trail ending at row ``i``: every ``stride``-th row back to ``i - window``,
    aligned on ``i`` so consecutive trails share their points."""
    return np.arange(i, max(-1, i - window - 1), -stride)[::-1]


def _template(columns: Iterable[Any]) -> tuple[Any, pa.DataType]:
    col = next(iter(columns))
    return col.component_descriptor(), col.as_arrow_array().type


_SCALAR = _template(rr.Scalars.columns(scalars=[0.0]))
_STRIPS = _template(rr.LineStrips3D.columns(strips=[[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]]))
# --------------------------------------------------------------------------- Arrow columns
_TRANSLATION, _QUATERNION = (_template([c]) for c in rr.Transform3D.columns(translation=[[0.0, 0.0, 0.0]],
                                                                            quaternion=[[0.0, 0.0, 0.0, 1.0]]))
_POSITIONS, _LABELS = (_template([c]) for c in rr.Points3D.columns(positions=[[0.0, 0.0, 0.0]], labels=["a"]))


def _field(entity: str, template: tuple[Any, pa.DataType]) -> pa.Field:
    """A component column of ``entity``, tagged so Rerun files it under that entity."""
    desc, typ = template
    meta = {b"rerun:entity_path": entity, b"rerun:component": desc.component}
    if desc.archetype:
        meta[b"rerun:archetype"] = desc.archetype
    if desc.component_type:
        meta[b"rerun:component_type"] = desc.component_type
    return pa.field(f"/{entity}:{desc.component}", typ, metadata=meta)


def _rows(n: int) -> pa.Array:
    return pa.array(np.arange(n + 1, dtype=np.int32))


def _lists(template: tuple[Any, pa.DataType], values: pa.Array, offsets: pa.Array, parts: int) -> list[pa.Array]:
    """One list column holding ``parts`` entities' rows back to back, cut into one column each
    (one Arrow call per family instead of one per entity)."""
    big = pa.ListArray.from_arrays(offsets, values, type=template[1])
    n = len(big) // parts
    return [big.slice(j * n, n) for j in range(parts)]


def _vec_lists(template: tuple[Any, pa.DataType], values: np.ndarray) -> list[pa.Array]:
    """[parts, n, k] vectors -> one column per part, one k-vector per row."""
    parts, n, _ = values.shape
    flat = pa.array(np.ascontiguousarray(values, dtype=np.float32).ravel())
    inner = pa.FixedSizeListArray.from_arrays(flat, type=template[1].value_type)
    return _lists(template, inner, _rows(parts * n), parts)


def _strip_lists(points: np.ndarray, lengths: np.ndarray) -> list[pa.Array]:
    """[parts, P, 3] points, cut into strips of ``lengths`` (the same for every part), one
    strip per row -> one LineStrips3D column per part."""
    parts, total, _ = points.shape
    strip_type = _STRIPS[1].value_type  # list<fixed_size_list<float32, 3>>
    flat = pa.array(np.ascontiguousarray(points, dtype=np.float32).ravel())
    xyz = pa.FixedSizeListArray.from_arrays(flat, type=strip_type.value_type)
    starts = np.concatenate(([0], np.cumsum(lengths)[:-1]))
    offsets = np.concatenate([starts + j * total for j in range(parts)] + [[parts * total]]).astype(np.int32)
    strips = pa.ListArray.from_arrays(pa.array(offsets), xyz, type=strip_type)
    return _lists(_STRIPS, strips, _rows(parts * len(lengths)), parts)


def _time(t: np.ndarray) -> pa.Array:
    ns = np.round(np.asarray(t, dtype=float) * 1e9).astype(np.int64)  # exact ticks (a float cast truncates)
    return pa.array(ns.astype("timedelta64[ns]"), pa.duration("ns"))


class _Layout:
    """The columns of the per-tick batch and of the trail batch, fixed for a run: built
    once from the Recorder's vehicles and edges."""

    def __init__(self, ids: Sequence[str], uav: Sequence[bool], edges: Sequence[Any]):
        self.uav = np.nonzero(np.asarray(uav, dtype=bool))[0]
        t = pa.field(bp.TIMELINE, pa.duration("ns"))
        vehicles = [f"{bp.VEHICLES}/{v}" for v in ids]
        scalars = ([f"{bp.PATH_ERROR}/{v}" for v in ids] + [f"{bp.OMEGA_RATE}/{v}" for v in ids]
                   + [f"{bp.COORD_ERROR}/{e.name}" for e in edges])
        self.ticks = pa.schema([t] + [_field(e, _TRANSLATION) for e in vehicles]
                               + [_field(e, _QUATERNION) for e in vehicles]
                               + [_field(vehicles[j], _STRIPS) for j in self.uav]
                               + [_field(e, _SCALAR) for e in scalars])
        self.trails = pa.schema([t] + [_field(f"{bp.TRAILS}/{v}", _STRIPS) for v in ids])
        self.interventions = pa.schema([t, _field(INTERVENTIONS, _POSITIONS), _field(INTERVENTIONS, _LABELS)])


INTERVENTIONS = f"{bp.WORLD}/safety/interventions"
CLOSEST = f"{bp.WORLD}/safety/closest"


def intervened(counts: np.ndarray, before: np.ndarray | None) -> np.ndarray:
    """[n, N] cumulative intervention counts (and the row before them, None: zeros) -> [n, N]
    booleans: the vehicle's count went up at that row (a restart's reset is not an intervention)."""
    prev = np.zeros(counts.shape[1], dtype=counts.dtype) if before is None else before
    return np.diff(np.vstack([prev[None, :], counts]), axis=0) > 0


UTILISATION_COLOUR = (90, 90, 220)
STATION_COLOUR = (40, 40, 40)


def probability_colour(p: float) -> tuple[int, int, int]:
    """A delivery probability as a colour: red (0), yellow (0.5), green (1)."""
    p = min(1.0, max(0.0, float(p)))
    if p < 0.5:
        return (220, int(round(440 * p)), 40)
    return (int(round(220 * (2.0 - 2.0 * p))), 200, 40)


def _fade(rgb: tuple[int, int, int], amount: float = 0.45) -> tuple[int, int, int]:
    """``rgb`` mixed towards white (path lines and rotors, lighter than the vehicle)."""
    return tuple(int(round(c + (255 - c) * amount)) for c in rgb)  # type: ignore[return-value]


OBSTACLES = f"{bp.WORLD}/obstacles"  # + /<j>: the j-th [[obstacle]], static line strips
OBSTACLE_COLOUR = (120, 90, 60)  # earth brown: islands, piers, masts and no-fly zones alike
CIRCLE_SEGMENTS = 64


def obstacle_strips(o: Any) -> list[np.ndarray]:
    """An [[obstacle]]'s outline as line strips in 3-D (cdus.core.obstacles shapes): a circle or a
    polygon a closed loop on the water (z = 0); a cylinder its floor and ceiling rings and four
    vertical lines; a box its bottom and top rectangles and four vertical edges."""
    if o.shape in ("circle", "cylinder"):
        a = np.linspace(0.0, 2.0 * np.pi, CIRCLE_SEGMENTS + 1)
        ring = np.stack([o.center[0] + o.radius * np.cos(a), o.center[1] + o.radius * np.sin(a)], axis=1)
    elif o.shape == "polygon":
        ring = np.array(o.vertices + o.vertices[:1], dtype=float)
    else:
        (x0, y0, _), (x1, y1, _) = o.lo, o.hi
        ring = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]], dtype=float)
    if o.shape in ("circle", "polygon"):
        return [np.column_stack([ring, np.zeros(len(ring))])]
    lo, hi = o.z if o.shape == "cylinder" else (o.lo[2], o.hi[2])
    loops = [np.column_stack([ring, np.full(len(ring), z)]) for z in (lo, hi)]
    step = max(1, (len(ring) - 1) // 4)
    posts = [np.array([[*ring[k], lo], [*ring[k], hi]]) for k in range(0, len(ring) - 1, step)][:4]
    return loops + posts
