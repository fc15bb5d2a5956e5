"""cdus.core.obstacles: signed distance and normal against brute force, the barrier's sign, the
polygon's refusals, and the safety filter's obstacle rows (cdus.core.safety)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings, strategies as st

from cdus.core.obstacles import Box, Circle, Clearance, Cylinder, Polygon, barrier, clearance, convex_ccw, seen_by
from cdus.core.safety import SafetyParams, dynamic_filter, safety_filter, uav_point

coord = st.floats(-30.0, 30.0, allow_nan=False)
size = st.floats(0.5, 10.0)


def _regular(n: int, cx: float, cy: float, r: float, turn: float) -> list[tuple[float, float]]:
    return [(cx + r * math.cos(turn + 2 * math.pi * k / n), cy + r * math.sin(turn + 2 * math.pi * k / n))
            for k in range(n)]


def _seg(p, a, b):
    """Distance from p to segment ab, by dense sampling (the brute force)."""
    return min(math.dist(p, (a[0] + (b[0] - a[0]) * s / 400, a[1] + (b[1] - a[1]) * s / 400)) for s in range(401))


def _inside_ray(p, vs):
    """Point in polygon by ray casting (independent of the edge-side test)."""
    x, y = p
    inside = False
    for i in range(len(vs)):
        (ax, ay), (bx, by) = vs[i], vs[(i + 1) % len(vs)]
        if (ay > y) != (by > y) and x < ax + (y - ay) * (bx - ax) / (by - ay):
            inside = not inside
    return inside


@settings(max_examples=60, deadline=None)
@given(n=st.integers(3, 8), cx=coord, cy=coord, r=size, turn=st.floats(0, 6.3), px=coord, py=coord,
       cw=st.booleans())
def test_polygon_distance_and_normal_match_brute_force(n, cx, cy, r, turn, px, py, cw):
    vs = _regular(n, cx, cy, r, turn)
    ccw, fault = convex_ccw(vs[::-1] if cw else vs)
    assert fault is None
    poly = Polygon(ccw, margin=0.5)
    c = clearance(poly, (px, py))
    brute = min(_seg((px, py), vs[i], vs[(i + 1) % n]) for i in range(n))
    sign = -1.0 if _inside_ray((px, py), vs) else 1.0
    assert c.distance == pytest.approx(sign * brute, abs=r * 0.01 + 1e-9)
    assert math.hypot(*c.normal) == pytest.approx(1.0)
    if c.distance > 1e-6:  # the nearest point q - d n lies on the boundary
        foot = (px - c.distance * c.normal[0], py - c.distance * c.normal[1])
        assert abs(clearance(poly, foot).distance) < 1e-6 * (1 + r)
    assert (barrier(poly, (px, py)) < 0) == (c.distance < 0.5)


@settings(max_examples=60, deadline=None)
@given(cx=coord, cy=coord, r=size, z0=st.floats(0, 10), hgt=st.floats(1, 30), px=coord, py=coord,
       pz=st.floats(-10, 50))
def test_cylinder_and_box_distance_match_brute_force(cx, cy, r, z0, hgt, px, py, pz):
    q = (px, py, pz)
    cyl = Cylinder((cx, cy), r, (z0, z0 + hgt), 1.0)
    c = clearance(cyl, q)
    dr, dz = math.hypot(px - cx, py - cy) - r, max(z0 - pz, pz - z0 - hgt)
    want = math.hypot(max(dr, 0), max(dz, 0)) + min(max(dr, dz), 0.0)  # the textbook SDF
    assert c.distance == pytest.approx(want, abs=1e-9)
    lo, hi = (cx - r, cy - r, z0), (cx + r, cy + r, z0 + hgt)
    b = clearance(Box(lo, hi, 1.0), q)
    d = [max(lo[j] - q[j], q[j] - hi[j]) for j in range(3)]
    want = math.sqrt(sum(max(x, 0.0) ** 2 for x in d)) + min(max(d), 0.0)
    assert b.distance == pytest.approx(want, abs=1e-9)
    for shape, cl in ((cyl, c), (Box(lo, hi, 1.0), b)):
        assert math.hypot(*cl.normal) == pytest.approx(1.0)
        if cl.distance > 1e-6:
            foot = tuple(x - cl.distance * n for x, n in zip(q, cl.normal))
            assert abs(clearance(shape, foot).distance) < 1e-6 * (1 + r + hgt)


@given(cx=coord, cy=coord, r=size, a=st.floats(0, 6.3), s=st.floats(0.0, 0.999))
def test_a_point_inside_has_negative_barrier(cx, cy, r, a, s):
    q = (cx + s * r * math.cos(a), cy + s * r * math.sin(a))
    assert barrier(Circle((cx, cy), r, 0.0), q) < 0 or s * r >= r - 1e-9
    assert barrier(Circle((cx, cy), r, 0.0), q) == pytest.approx(math.hypot(q[0] - cx, q[1] - cy) - r)


# A vehicle on the special points of each shape (a polygon's vertex and edge, a circle's centre, a
# cylinder's axis and rim, a box's centre, edge and corner), off them by nothing, a subnormal or a
# rounding step: the normal stays finite and of length 1, the filter's input finite.
tiny = st.sampled_from([0.0, 5e-324, -5e-324, 1e-310, -1e-310, 1e-300, 1e-16, -1e-16, 1e-9, -1e-9])
SPECIAL = [
    (Polygon(convex_ccw([(0, 0), (4, 0), (4, 3), (0, 3)])[0], 1.0), [(0, 0), (4, 3), (2, 0), (0, 1.5), (2, 1.5)]),
    (Circle((1.0, -2.0), 3.0, 1.0), [(1.0, -2.0), (4.0, -2.0)]),
    (Cylinder((0.0, 0.0), 2.0, (0.0, 10.0), 1.0), [(0, 0, 5), (0, 0, 10), (2, 0, 10), (2, 0, 0), (-2, 0, 5)]),
    (Cylinder((0.0, 0.0), 5e-324, (0.0, 5e-324), 1.0), [(0, 0, 0), (1e-323, 0, 1e-323)]),
    (Box((0.0, 0.0, 0.0), (2.0, 2.0, 2.0), 1.0), [(1, 1, 1), (0, 0, 0), (2, 2, 2), (0, 1, 2), (2, 0, 1)]),
]


@settings(max_examples=150, deadline=None)
@given(k=st.integers(0, len(SPECIAL) - 1), j=st.integers(0, 4), e=st.lists(tiny, min_size=3, max_size=3),
       u=st.lists(st.sampled_from([-1.0, 0.0, 1.0]), min_size=3, max_size=3))
def test_a_vehicle_on_a_vertex_axis_edge_or_corner_gets_a_unit_normal_and_a_finite_input(k, j, e, u):
    shape, points = SPECIAL[k]
    p = points[j % len(points)]
    q = tuple(float(x) + d for x, d in zip(p, e))
    cl = clearance(shape, q)
    assert math.isfinite(cl.distance) and cl.bend >= 0.0
    assert math.hypot(*cl.normal) == pytest.approx(1.0, abs=1e-12), (q, cl)
    v, _ = safety_filter(tuple(u[:len(q)]), q, [], SafetyParams(radius=2.0, obstacles=(shape,)))
    assert all(math.isfinite(x) for x in v)


@pytest.mark.parametrize("vertices, index, words", [
    ([(0, 0), (1, 0)], 2, "at least 3"),
    ([(0, 0), (2, 0), (2, 2), (2, 0.0)], 3, "repeats vertex 1"),
    ([(0, 0), (1, 0), (2, 0), (1, 1)], 1, "line through its neighbours"),
    ([(0, 0), (4, 0), (1, 1), (0, 4)], 2, "not convex"),
    ([_regular(5, 0, 0, 1, 0)[k] for k in (0, 2, 4, 1, 3)], 0, "winds round 2 times"),
])
def test_a_bad_polygon_names_the_vertex(vertices, index, words):
    got, fault = convex_ccw(vertices)
    assert got is None and fault[0] == index and words in fault[1]


def test_clockwise_vertices_are_turned_counter_clockwise():
    square = [(0, 0), (0, 1), (1, 1), (1, 0)]
    got, fault = convex_ccw(square)
    assert fault is None and got == ((1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.0, 0.0))


def test_boats_see_water_shapes_and_drones_air_shapes():
    shapes = (Circle((0, 0), 1, 1), Cylinder((0, 0), 1, (0, 5), 1), Box((0, 0, 0), (1, 1, 1), 1))
    assert seen_by("usv", shapes) == shapes[:1] and seen_by("uav", shapes) == shapes[1:]


def test_a_drone_above_the_ceiling_is_clear_and_flies_over():
    mast = Cylinder((0.0, 0.0), 1.0, (0.0, 10.0), 1.0)
    assert clearance(mast, (0.0, 0.0, 13.0)).distance == pytest.approx(3.0)
    assert clearance(mast, (0.0, 0.0, 13.0)).normal == (0.0, 0.0, 1.0)
    u, info = safety_filter((1.0, 0.0, 0.0), (0.0, 0.0, 13.0), (), SafetyParams(radius=2.0, obstacles=(mast,)))
    assert u == (1.0, 0.0, 0.0) and not info.intervened


def test_the_velocity_filter_stops_at_the_margin_and_sidesteps_a_head_on_island():
    island = Circle((10.0, 0.0), 2.0, 1.0)
    params = SafetyParams(radius=2.0, gamma=1.0, obstacles=(island,))
    q = (0.0, 0.0)
    for _ in range(4000):  # 40 s at 100 Hz, the reference straight at the island's centre
        u, info = safety_filter((1.0, 0.0), q, (), params)
        q = (q[0] + 0.01 * u[0], q[1] + 0.01 * u[1])
        assert barrier(island, q) > -1e-9
    assert q[0] > 12.0  # went round (the starboard turn breaks the symmetric stall) and on


def test_the_dynamic_filter_brakes_a_drone_before_a_box():
    box = Box((10.0, -5.0, 0.0), (12.0, 5.0, 20.0), 1.0)
    params = SafetyParams(radius=2.0, gamma=1.0, obstacles=(box,))
    q, p = (0.0, 0.0, 10.0), (3.0, 0.0, 0.0)
    h = 0.005
    worst = math.inf
    for _ in range(4000):
        tau, _ = dynamic_filter((2.0, 0.0, 0.0), uav_point(q, p, (0.0, 0.0, 0.0), 6.0), (), params)
        p = tuple(a + h * b for a, b in zip(p, tau))
        q = tuple(a + h * b for a, b in zip(q, p))
        worst = min(worst, barrier(box, q))
    assert -0.01 < worst < 0.1  # braked to the margin (within a physics step's discretisation)


def test_obstacle_rows_report_by_obstacle_only_when_one_binds():
    island = Circle((10.0, 0.0), 2.0, 1.0)
    params = SafetyParams(radius=2.0, obstacles=(island,))
    _, far = safety_filter((1.0, 0.0), (0.0, 0.0), (), params)
    _, near = safety_filter((1.0, 0.0), (6.5, 0.0), (), params)
    assert not far.by_obstacle and near.by_obstacle and near.intervened


def _slide(track_way: bool, y0: float) -> tuple[float, float]:
    """A boat following the line y = 0 eastwards (u_ref = (1, -2 y): the guidance pulls it back onto
    its line) into a square pier across it, 40 s at 100 Hz; where it ends."""
    pier = Polygon(((10.0, -3.0), (14.0, -3.0), (14.0, 3.0), (10.0, 3.0)), 1.0)
    params = SafetyParams(radius=2.0, obstacles=(pier,))
    q, way = (0.0, y0), 0
    for _ in range(4000):
        u, info = safety_filter((1.0, -2.0 * q[1]), q, (), params, None, way if track_way else 0)
        way = info.way
        q = (q[0] + 0.01 * u[0], q[1] + 0.01 * u[1])
        assert barrier(pier, q) > -1e-9
    return q


@pytest.mark.parametrize("y0", [0.0, 0.3, -0.3])
def test_a_blocked_vehicle_commits_to_a_way_round_and_rejoins_its_line(y0):
    x, y = _slide(True, y0)
    assert x > 20.0 and abs(y) < 0.1  # round the pier and back on its line
    # without the commitment it stalls at the pier's face, where the starboard turn and the pull balance
    assert _slide(False, y0)[0] < 10.0


def test_the_centre_of_a_disc_is_pushed_out_along_x_and_every_normal_is_unit():
    c = clearance(Circle((3.0, 4.0), 2.0, 1.0), (3.0, 4.0))
    assert c == Clearance(-2.0, (1.0, 0.0), 2.0)
    axis = clearance(Cylinder((3.0, 4.0), 2.0, (0.0, 10.0), 1.0), (3.0, 4.0, 5.0))
    assert axis.distance == -2.0 and axis.normal == (1.0, 0.0, 0.0)


def test_a_cylinder_seen_from_a_plane_point_is_taken_at_mid_height():
    mast = Cylinder((0.0, 0.0), 1.0, (2.0, 12.0), 1.0)  # mid-height 7
    for x, y in ((3.0, 0.0), (0.0, 0.5), (0.2, -0.1)):
        assert clearance(mast, (x, y)) == clearance(mast, (x, y, 7.0))


def test_bend_is_the_radius_beside_a_round_face_zero_at_a_corner_and_inf_on_a_flat_face():
    mast = Cylinder((0.0, 0.0), 1.5, (0.0, 10.0), 1.0)
    assert clearance(mast, (4.0, 0.0, 5.0)).bend == 1.5  # beside
    assert clearance(mast, (0.5, 0.0, 12.0)).bend == math.inf  # above the ceiling
    assert clearance(mast, (4.0, 0.0, 12.0)).bend == math.inf  # off the rim
    square = Polygon(((0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)), 1.0)
    corner = clearance(square, (3.0, 3.0))
    assert corner.distance == math.sqrt(2.0) and corner.normal == pytest.approx((math.sqrt(0.5),) * 2)
    assert corner.bend == 0.0
    assert clearance(square, (1.0, -1.0)) == Clearance(1.0, (0.0, -1.0), math.inf)
    assert clearance(square, (1.0, 0.5)) == Clearance(-0.5, (0.0, -1.0), math.inf)  # inside: the nearest edge
    assert clearance(square, (-1.0, -1.0)).bend == 0.0  # the first vertex
    assert clearance(Box((0, 0, 0), (1, 1, 1), 1.0), (0.5, 0.5, 3.0)).bend == math.inf
    assert clearance(Box((0, 0, 0), (1, 1, 1), 1.0), (0.5, 0.5, 0.75)) == Clearance(-0.25, (0.0, 0.0, 1.0), math.inf)


@pytest.mark.parametrize("scale", [1e-13, 1.0, 1e6])
def test_a_polygon_is_judged_the_same_at_any_scale(scale):
    def judged(vs):
        return convex_ccw([(x * scale, y * scale) for x, y in vs])

    assert judged([(0, 0), (1, 0), (0, 1)])[1] is None
    assert judged([(0, 0), (2, 0), (2, 2), (2, 1e-13)])[1][:1] == (3,)  # a near-repeat of vertex 1
    assert judged([(0, 0), (0, 0), (1, 0), (0, 1)])[1] == (1, "repeats vertex 0 (every vertex must be a distinct "
                                                             "corner)")
