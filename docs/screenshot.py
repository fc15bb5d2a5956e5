"""Make docs/lake_circle.png: lake_circle recorded to Rerun, then shown by a headless viewer.

    python docs/screenshot.py                       # 150 simulated s -> docs/lake_circle.png
    python docs/screenshot.py --duration 60 --out /tmp/shot.png --keep-rrd /tmp/lake.rrd
    python docs/screenshot.py --rrd runs/<run>/recording.rrd --out /tmp/run.png   # a recording you have

Needs a Vulkan driver; on Debian/Ubuntu ``apt-get install -y mesa-vulkan-drivers`` gives
lavapipe (CPU rendering, no GPU, no X server). The viewer runs headless on 127.0.0.1 in
its own process group and is killed at the end. ``rerun --headless --screenshot-to FILE``
shoots after a fixed few frames, while the viewer is still loading the file's chunks (often
nothing but the layout is drawn yet); so the viewer is driven with
``rerun.experimental.ViewerClient`` instead, and the picture is taken once three frames a
second apart come out identical (loaded and still). tests/e2e/test_screenshot.py uses both.
"""

from __future__ import annotations

import argparse
import io
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def record(path: Path, duration: float) -> None:
    from cdus.scenario.config import load_scenario
    from cdus.sim.fleet import InProcessFleet
    from world_sim.sinks import make_sink

    sc = load_scenario(ROOT / "configs" / "lake_circle.toml", {"scenario.duration": duration})
    sink = make_sink(f"save:{path}")
    try:
        InProcessFleet(sc, sink=sink).run()
    finally:
        sink.close()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def shoot(rrd: Path, size: str = "1280x720", timeout: float = 120.0, port: int | None = None) -> bytes:
    """A PNG of ``rrd`` in a headless viewer (127.0.0.1, own process group, killed on return)."""
    import numpy as np
    import rerun_cli
    from PIL import Image
    from rerun.experimental import ViewerClient

    port = port or free_port()
    viewer = subprocess.Popen(
        [os.path.join(os.path.dirname(rerun_cli.__file__), "rerun"), "--headless", "--bind", "127.0.0.1",
         "--port", str(port), "--window-size", size, "--hide-welcome-screen"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
        env={**os.environ, "RUST_LOG": "error"})  # errors only: no notification toasts over the views
    try:
        deadline = time.monotonic() + timeout
        while True:  # until the viewer accepts connections
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
                break
            except OSError:
                if viewer.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"the headless viewer did not come up (rc {viewer.poll()}); "
                                     f"is a Vulkan driver installed (mesa-vulkan-drivers)?")
                time.sleep(0.05)
        client = ViewerClient.connect(f"rerun+http://127.0.0.1:{port}/proxy")
        client.open(str(rrd.resolve()))
        same, last, png = 0, None, b""
        while same < 2:  # three identical frames in a row: everything loaded and drawn
            if time.monotonic() > deadline:
                raise RuntimeError(f"the picture did not settle within {timeout:g} s")
            time.sleep(1.0)
            png = client.take_screenshot()
            frame = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
            same = same + 1 if last is not None and np.array_equal(frame, last) else 0
            last = frame
        return png
    finally:
        os.killpg(viewer.pid, signal.SIGTERM)
        try:
            viewer.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(viewer.pid, signal.SIGKILL)
            viewer.wait()


def main(argv: list[str] | None = None) -> None:
    from PIL import Image

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rrd", type=Path, help="shoot this recording (a run's recording.rrd, `--rerun save:PATH`) "
                    "instead of recording lake_circle")
    ap.add_argument("--duration", type=float, help="simulated seconds of lake_circle to record (default 150: "
                    "coordination settles at ~124 s)")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "lake_circle.png")
    ap.add_argument("--size", default="1280x720", help="viewer window, logical points")
    ap.add_argument("--keep-rrd", type=Path, help="keep the recording of lake_circle here")
    ap.add_argument("--timeout", type=float, default=120.0)
    args = ap.parse_args(argv)
    if args.rrd is not None:
        if args.duration is not None or args.keep_rrd is not None:
            ap.error("--rrd shoots a recording you have: --duration and --keep-rrd are for recording lake_circle")
        if not args.rrd.is_file():
            ap.error(f"--rrd {args.rrd}: no such file (a run's recording is <run dir>/recording.rrd)")
    with tempfile.TemporaryDirectory() as tmp:
        rrd = args.rrd or args.keep_rrd or Path(tmp) / "lake_circle.rrd"
        if args.rrd is None:
            record(rrd, 150.0 if args.duration is None else args.duration)
        png = shoot(rrd, args.size, args.timeout)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    # 256 colours are plenty for a flat UI and make the file ~4x smaller
    Image.open(io.BytesIO(png)).convert("RGB").quantize(256, dither=Image.Dither.NONE).save(args.out, optimize=True)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    sys.exit(main())
