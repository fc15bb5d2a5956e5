"""End to end: a lake_circle recording rendered by a headless Rerun viewer.

Needs a Vulkan driver: Debian's mesa-vulkan-drivers (lavapipe, CPU rendering; no GPU, no
X server). Skipped where it is not installed; CI installs it. Every viewer runs on
127.0.0.1 with a free port, in its own process group, with a timeout; teardown kills it.

``rerun --headless --screenshot-to FILE`` shoots after a fixed few frames, while the
viewer may still be loading the file's chunks: that picture only proves the renderer and
the layout work. The fleet itself (paths, vehicles, curves, links) is checked on a picture
taken once the frames settle, the way docs/screenshot.py makes docs/lake_circle.png.
"""

from __future__ import annotations

import importlib.util
import io
import os
import shutil
import subprocess

import numpy as np
import pytest

from cdus.scenario.config import load_scenario
from cdus.wire.transport import free_tcp_port
from cdus.sim.fleet import InProcessFleet
from world_sim.sinks import make_sink

from .conftest import ROOT, kill_group


def _mesa_installed() -> bool:
    if shutil.which("dpkg") is None:
        return False
    r = subprocess.run(["dpkg", "-s", "mesa-vulkan-drivers"], capture_output=True, text=True)
    return r.returncode == 0 and "install ok installed" in r.stdout


pytestmark = pytest.mark.skipif(not _mesa_installed(),
                                reason="needs mesa-vulkan-drivers (apt-get install -y mesa-vulkan-drivers)")


@pytest.fixture(scope="module")
def lake_rrd(tmp_path_factory):
    """lake_circle, 60 simulated s, as an .rrd."""
    rrd = tmp_path_factory.mktemp("screenshot") / "lake.rrd"
    sc = load_scenario(ROOT / "configs" / "lake_circle.toml", {"scenario.duration": 60.0})
    sink = make_sink(f"save:{rrd}")
    InProcessFleet(sc, sink=sink).run()
    sink.close()
    return rrd


@pytest.fixture
def viewers():
    """Start processes in their own groups; kill every group still alive at teardown."""
    started: list[subprocess.Popen] = []

    def start(args: list[str], log) -> subprocess.Popen:
        p = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
                             env={**os.environ, "RUST_LOG": "error"})  # no notification toasts over the views
        started.append(p)
        return p

    yield start
    for p in started:
        kill_group(p)


def _pixels(png: bytes | os.PathLike) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png) if isinstance(png, bytes) else png).convert("RGB")).astype(int)


def _not_blank(img: np.ndarray) -> None:
    h, w, _ = img.shape
    assert w >= 1280 and h >= 720
    assert img.std() > 10, "blank picture"
    assert len(np.unique(img.reshape(-1, 3) // 16, axis=0)) >= 30, "too few colours"


def _picture(viewers, args: list[str], png, timeout: float) -> np.ndarray:
    """Run ``args`` (started by ``viewers``, its output in a log beside ``png``) to its end; the
    pixels of the ``png`` it wrote."""
    log = png.with_suffix(".log")
    with open(log, "w") as out:
        run = viewers(args, out)
        try:
            code = run.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            pytest.fail(f"{args[:2]} took over {timeout:g} s:\n" + log.read_text())
    assert code == 0, log.read_text()
    return _pixels(png)


def test_rerun_screenshot_to_renders_headless(lake_rrd, viewers, tmp_path):
    import rerun_cli

    png = tmp_path / "shot.png"
    binary = os.path.join(os.path.dirname(rerun_cli.__file__), "rerun")  # the viewer itself, not the Python shim
    _not_blank(_picture(viewers, [binary, "--headless", "--bind", "127.0.0.1", "--port", str(free_tcp_port()),
                                  "--screenshot-to", str(png), "--window-size", "1280x720", str(lake_rrd)], png, 120))


def test_the_settled_picture_shows_the_fleet(lake_rrd):
    spec = importlib.util.spec_from_file_location("docs_screenshot", ROOT / "docs" / "screenshot.py")
    docs_screenshot = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(docs_screenshot)
    img = _pixels(docs_screenshot.shoot(lake_rrd, "1280x720", timeout=120, port=free_tcp_port()))
    _not_blank(img)
    h, w, _ = img.shape

    def share(region: np.ndarray, mask) -> float:
        r, g, b = region[..., 0], region[..., 1], region[..., 2]
        return float(mask(r, g, b).mean())

    world = img[int(0.1 * h):int(0.7 * h), : int(0.58 * w)]  # the 3-D view, left
    assert share(world, lambda r, g, b: (b > 180) & (b - r > 50)) > 0.002, "no USV path or hull (blue)"
    assert share(world, lambda r, g, b: (r > 200) & (g > 120) & (r - b > 80)) > 0.002, "no UAV path or drone (orange)"
    plots = img[int(0.08 * h):, int(0.62 * w):]  # the time series, right
    assert share(plots, lambda r, g, b: (np.max([r, g, b], 0) - np.min([r, g, b], 0)) > 80) > 0.005, "no curves"
    links = img[int(0.78 * h):int(0.95 * h), : int(0.35 * w)]  # the link timeline, bottom left
    assert share(links, lambda r, g, b: (g > 120) & (g - r > 40) & (g - b > 40)) > 0.05, "no link states (green)"


def test_docs_screenshot_shoots_a_recording_it_is_given(lake_rrd, viewers, tmp_path):
    """`docs/screenshot.py --rrd PATH`: the picture of a recording one has (issue 27: it could
    only record lake_circle itself)."""
    import sys

    png = tmp_path / "given.png"
    _not_blank(_picture(viewers, [sys.executable, str(ROOT / "docs" / "screenshot.py"), "--rrd", str(lake_rrd),
                                  "--out", str(png)], png, 300))
