"""How do the tests install the example plug-in package? With pip, as a user would, into a
directory of its own (``pip install --no-deps --no-build-isolation --target DIR``), never the shared
environment: the test extra brings a setuptools that builds wheels itself (>= 70.1), so nothing is
fetched. The first install of a test session is copied for the others (pip takes about 2.5 s).
"""

from __future__ import annotations

import atexit
import functools
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "cdus_plugin_example"


def _pip_install(source: Path, target: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                           "--no-index", "--target", str(target), str(source)], capture_output=True, text=True)
    assert proc.returncode == 0, f"pip could not install {source}: {proc.stderr}"


@functools.cache
def _installed(source: Path) -> Path:
    target = Path(tempfile.mkdtemp(prefix="cdus-plugin-site-"))
    atexit.register(shutil.rmtree, target, True)
    # from a copy: setuptools builds in the source tree (build/, *.egg-info), which would leave an
    # installed-looking package in examples/ for every test that puts the example on sys.path
    shutil.copytree(source, target / "src", ignore=shutil.ignore_patterns("__pycache__", "build", "*.egg-info"))
    _pip_install(target / "src", target / "site")
    return target / "site"


def install_example(target: Path, source: Path = EXAMPLE) -> Path:
    """The package at ``source`` installed by pip into ``target`` (created): a copy of this session's install."""
    shutil.copytree(_installed(source.resolve()), target, dirs_exist_ok=True)
    return target
