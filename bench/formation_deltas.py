"""Recorder.deltas with many formation changes (a ground station that sends thousands):
the newest row (the world's status, every second) and every row (the summary). Prints ms."""

import time
from cdus.core.formation import FormationSchedule
from cdus.core.metrics import MetricEdge, Recorder
class R:
    def __init__(s): s.q, s.heading, s.omega, s.omega_rate, s.path_error = (0.0, 0.0), 0.0, 0.0, -1.0, 0.0
for U in (2000, 20000):
    rec = Recorder(["a","b"],[2,2],[MetricEdge(0,1,1.0,"a__b")]); f = FormationSchedule([1.0,0.0]); rec.set_formation(f, 0.1)
    for n in range(U):
        f.add(n, {1: float(n)}); rec.record(n*0.1, [R(), R()])
    t0=time.perf_counter(); rec.deltas(U-1, U); t1=time.perf_counter(); rec.deltas(); t2=time.perf_counter()
    print(U, f"newest row {1e3*(t1-t0):.1f} ms, all rows {1e3*(t2-t1):.0f} ms")
