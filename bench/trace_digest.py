"""Does a change leave every `cdus sim` run as it was, to the bit?

    python bench/trace_digest.py --out before.json      # at the base commit
    python bench/trace_digest.py --compare before.json  # after the change: same digests?

Runs `cdus sim` (the interpreter's, this checkout's packages through PYTHONPATH) on every
config in configs/ and a few variants that reach the other plant, regulator and
stale-neighbour choices (the paper's USV regulator, the timeout and extrapolate policies),
and prints the SHA-256 of each trace (every array of --trace-out, in key order, as its raw
bytes) with the wall time of each run. With --compare, each digest is checked against the
file's and the differing cases listed; the exit status is 1 if any differs.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

VARIANTS = {
    "lake_circle_dynamic+paper": ("lake_circle_dynamic.toml",
                                  ["--set", "vehicle.usv1.regulator=paper", "--set", "vehicle.usv2.regulator=paper",
                                   "--set", "vehicle.usv3.regulator=paper", "--duration", "60"]),
    "lake_circle+extrapolate": ("lake_circle.toml", ["--policy", "extrapolate", "--set", "link.delay.base=0.1"]),
    "range_out+hold": ("range_out.toml", ["--policy", "hold"]),
    "lake_windy+extrapolate": ("lake_windy.toml", ["--policy", "extrapolate", "--duration", "60"]),
}


def digest(npz: Path) -> str:
    h = hashlib.sha256()
    with np.load(npz, allow_pickle=False) as z:
        for key in sorted(z.files):
            a = np.ascontiguousarray(z[key])
            h.update(key.encode() + str(a.dtype).encode() + str(a.shape).encode())
            h.update(a.tobytes())
    return h.hexdigest()


def run(config: str, extra: list[str], tmp: Path) -> tuple[str, float]:
    out = tmp / "trace.npz"
    cmd = [sys.executable, "-m", "cdus", "sim", str(ROOT / "configs" / config), "-q", "--rerun", "off",
           "--runs-dir", str(tmp / "runs"), "--trace-out", str(out), *extra]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, env=dict(os.environ))
    return digest(out), time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", help="write the digests here (JSON)")
    ap.add_argument("--compare", help="compare with the digests in this file (JSON)")
    args = ap.parse_args()
    cases = {c.name.removesuffix(".toml"): (c.name, []) for c in sorted((ROOT / "configs").glob("*.toml"))
             if 'plant = "ros2"' not in c.read_text()}  # a real robot: `cdus sim` refuses it (launch --clock realtime)
    cases.update(VARIANTS)
    got = {}
    with tempfile.TemporaryDirectory() as d:
        for name, (config, extra) in cases.items():
            got[name], wall = run(config, extra, Path(d))
            print(f"{name:<30} {got[name][:16]}  {wall:6.2f} s", flush=True)
    if args.out:
        Path(args.out).write_text(json.dumps(got, indent=1) + "\n")
    if args.compare:
        want = json.loads(Path(args.compare).read_text())
        diff = [n for n in sorted(set(want) | set(got)) if want.get(n) != got.get(n)]
        print(f"{len(got) - len(diff)}/{len(got)} traces equal to the bit" + (f"; differ: {', '.join(diff)}" if diff else ""))
        return 1 if diff else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
