"""How do the tests install the example plug-in package? As an installed distribution (a
``.dist-info`` with its METADATA and entry points) in a directory of its own, never the shared
environment.

``pip install --no-deps --no-build-isolation --target DIR examples/cdus_plugin_example`` needs a
setuptools that builds wheels (>= 70.1, or the ``wheel`` package): this machine's setuptools 65.5
fails with "invalid command 'bdist_wheel'", and with build isolation pip fetches a build backend
from an index (6.5 s at load 8.8). So the distribution is written here from the package's own
``pyproject.toml``: its name, version and entry points, exactly what ``importlib.metadata`` (and so
cdus, cdus.scenario.plugins.entry_points) reads of an installed package, and its files copied.
"""

from __future__ import annotations

import shutil
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "cdus_plugin_example"


def install_example(target: Path, source: Path = EXAMPLE) -> Path:
    """The package at ``source`` installed into ``target`` (created), as pip would lay it out."""
    project = tomllib.loads((source / "pyproject.toml").read_text())["project"]
    name, version = project["name"], project["version"]
    target.mkdir(parents=True, exist_ok=True)
    for pkg in tomllib.loads((source / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]:
        shutil.copytree(source / pkg, target / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    info = target / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    groups = project.get("entry-points", {})
    (info / "entry_points.txt").write_text("".join(
        f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in eps.items()) + "\n" for group, eps in groups.items()))
    (info / "INSTALLER").write_text("tests/plugins/install.py\n")
    return target
