"""The proximity sensor: same-domain contacts within range, UAVs seeing boats, the schedule."""

import math
import random

import pytest

from cdus.core.proximity import Body, is_sample_tick, sample_every, sense
from cdus.core.safety import Contact


def _brute(bodies, rng_m, cross):
    out = {b.id: [] for b in bodies}
    for a in bodies:
        for b in bodies:
            if a.id == b.id:
                continue
            if a.domain == b.domain and math.dist(a.q, b.q) <= rng_m:
                out[a.id].append(Contact(tuple(b.q), b.id, 0.5))
            elif cross and a.domain == "uav" and b.domain == "usv":
                seen = (b.q[0], b.q[1], 0.0)
                if math.dist(a.q, seen) <= rng_m:
                    out[a.id].append(Contact(seen, b.id, 1.0))
    return {k: tuple(sorted(v, key=lambda c: c.id)) for k, v in out.items()}


def _fleet(rng, n):
    bodies = []
    for i in range(n):
        if rng.random() < 0.5:
            bodies.append(Body(f"usv{i}", "usv", (rng.uniform(-50, 50), rng.uniform(-50, 50))))
        else:
            bodies.append(Body(f"uav{i}", "uav", (rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(0, 25))))
    return bodies


@pytest.mark.parametrize("sensing_range", [3.0, 15.0, 60.0, math.inf])
@pytest.mark.parametrize("cross", [False, True])
def test_sense_equals_brute_force(sensing_range, cross):
    rng = random.Random(4)
    for _ in range(20):
        bodies = _fleet(rng, rng.randint(0, 40))
        assert sense(bodies, sensing_range, cross) == _brute(bodies, sensing_range, cross)


def test_order_of_input_does_not_matter():
    rng = random.Random(8)
    bodies = _fleet(rng, 30)
    shuffled = list(bodies)
    rng.shuffle(shuffled)
    assert sense(bodies, 20.0) == sense(shuffled, 20.0)


def test_domains():
    bodies = [
        Body("usv1", "usv", (0.0, 0.0)),
        Body("usv2", "usv", (4.0, 0.0)),
        Body("usv3", "usv", (40.0, 0.0)),          # out of range
        Body("uav1", "uav", (0.0, 0.0, 20.0)),     # at altitude over usv1: sees nothing on the water
        Body("uav2", "uav", (0.0, 3.0, 20.0)),
        Body("uav3", "uav", (4.0, 1.0, 2.0)),      # low, next to usv2
    ]
    seen = sense(bodies, 10.0)
    assert seen["usv1"] == (Contact((4.0, 0.0), "usv2", 0.5),)
    assert seen["usv3"] == ()
    assert seen["uav1"] == (Contact((0.0, 3.0, 20.0), "uav2", 0.5),)
    # uav3: usv1 at 4.6 m, usv2 at 2.2 m, both on the surface, taken whole; no UAV in range
    assert seen["uav3"] == (Contact((0.0, 0.0, 0.0), "usv1", 1.0), Contact((4.0, 0.0, 0.0), "usv2", 1.0))
    assert all(c.id.startswith("usv") for c in seen["usv2"])  # boats never see drones
    assert sense(bodies, 10.0, cross_domain=False)["uav3"] == ()


def test_a_vehicle_that_is_not_live_is_an_obstacle_taken_whole_and_sees_nothing():
    bodies = [
        Body("usv1", "usv", (0.0, 0.0)),
        Body("usv2", "usv", (4.0, 0.0), live=False),   # killed here
        Body("usv3", "usv", (6.0, 0.0), live=False),   # two dead ones do not see each other
        Body("uav1", "uav", (4.0, 1.0, 2.0)),
        Body("uav2", "uav", (5.0, 1.0, 2.0), live=False),
    ]
    seen = sense(bodies, 10.0)
    assert set(seen) == {"usv1", "uav1"}
    assert seen["usv1"] == (Contact((4.0, 0.0), "usv2", 1.0), Contact((6.0, 0.0), "usv3", 1.0))
    assert seen["uav1"] == (Contact((5.0, 1.0, 2.0), "uav2", 1.0), Contact((0.0, 0.0, 0.0), "usv1", 1.0),
                            Contact((4.0, 0.0, 0.0), "usv2", 1.0), Contact((6.0, 0.0, 0.0), "usv3", 1.0))


def test_bad_input_names_the_problem():
    with pytest.raises(ValueError, match="unknown domain 'ugv'"):
        Body("x", "ugv", (0.0, 0.0))
    with pytest.raises(ValueError, match="usv position has 2 coordinates, got 3"):
        Body("x", "usv", (0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="sensing range"):
        sense([], 0.0)
    with pytest.raises(ValueError, match="unique"):
        sense([Body("a", "usv", (0.0, 0.0)), Body("a", "usv", (1.0, 0.0))], 5.0)


def test_schedule():
    assert sample_every(10.0, 50.0) == 5
    assert sample_every(50.0, 50.0) == 1
    assert sample_every(200.0, 50.0) == 1   # faster than control: every tick
    assert sample_every(15.0, 50.0) == 3    # 16.7 Hz: the nearest whole number of ticks
    ticks = [t for t in range(20) if is_sample_tick(t, sample_every(10.0, 50.0))]
    assert ticks == [0, 5, 10, 15]
    with pytest.raises(ValueError, match="sensing rate"):
        sample_every(0.0, 50.0)
    with pytest.raises(ValueError, match="control rate"):
        sample_every(10.0, -1.0)
