"""docs/screenshot.py's command line, without a viewer (tests/e2e/test_screenshot.py renders,
where a Vulkan driver is installed): `--rrd PATH` shoots a recording one has."""

from __future__ import annotations

import importlib.util
import io
from pathlib import Path

import pytest
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def screenshot(monkeypatch):
    """The module, with record() and shoot() replaced by recorders of their calls."""
    spec = importlib.util.spec_from_file_location("docs_screenshot", ROOT / "docs" / "screenshot.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    calls: list[tuple] = []
    png = io.BytesIO()
    Image.new("RGB", (4, 4), (10, 200, 30)).save(png, format="PNG")
    monkeypatch.setattr(module, "record", lambda path, duration: calls.append(("record", path, duration)))
    monkeypatch.setattr(module, "shoot", lambda rrd, size, timeout: calls.append(("shoot", rrd)) or png.getvalue())
    return module, calls


def test_a_given_recording_is_shot_as_it_is_not_recorded_again(screenshot, tmp_path):
    module, calls = screenshot
    rrd, out = tmp_path / "run.rrd", tmp_path / "shots" / "run.png"
    rrd.write_bytes(b"an rrd")
    module.main(["--rrd", str(rrd), "--out", str(out)])
    assert calls == [("shoot", rrd)]
    assert Image.open(out).size == (4, 4)
    module.main(["--out", str(out), "--duration", "5"])  # without --rrd: lake_circle recorded, then shot
    assert [c[0] for c in calls[1:]] == ["record", "shoot"] and calls[1][2] == 5.0 and calls[1][1] == calls[2][1]


def test_a_missing_recording_or_recording_flags_with_it_are_refused_by_name(screenshot, tmp_path, capsys):
    module, calls = screenshot
    with pytest.raises(SystemExit) as e:
        module.main(["--rrd", str(tmp_path / "nowhere.rrd")])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "--rrd " in err and "nowhere.rrd: no such file" in err, err
    rrd = tmp_path / "run.rrd"
    rrd.write_bytes(b"x")
    with pytest.raises(SystemExit) as e:
        module.main(["--rrd", str(rrd), "--duration", "60"])
    assert e.value.code == 2 and "--duration and --keep-rrd are for recording" in capsys.readouterr().err
    assert calls == []
