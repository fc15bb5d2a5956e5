"""tests/run.py keeps compiled bytecode for both phases, outside the tree: PYTHONDONTWRITEBYTECODE
(set on this machine) made every process a test starts compile cdus again."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tests.run import bytecode_env

ROOT = Path(__file__).resolve().parents[1]


def test_bytecode_is_kept_in_the_users_cache_directory_unless_the_caller_chose_a_place(tmp_path):
    env = bytecode_env({"PYTHONDONTWRITEBYTECODE": "1", "HOME": "/home/ann"})
    assert "PYTHONDONTWRITEBYTECODE" not in env and env["HOME"] == "/home/ann"
    assert env["PYTHONPYCACHEPREFIX"] == "/home/ann/.cache/cdus/pycache"  # the user's own, not a shared /tmp name
    xdg = bytecode_env({"HOME": "/home/ann", "XDG_CACHE_HOME": str(tmp_path)})["PYTHONPYCACHEPREFIX"]
    assert xdg == str(tmp_path / "cdus" / "pycache") and ROOT not in Path(xdg).parents
    assert bytecode_env({"PYTHONPYCACHEPREFIX": str(tmp_path)})["PYTHONPYCACHEPREFIX"] == str(tmp_path)


def test_a_process_started_with_it_writes_its_bytecode_there_and_nothing_into_the_tree(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    (src / "mod.py").write_text("X = 1\n")
    env = bytecode_env({**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "PYTHONPYCACHEPREFIX": str(tmp_path / "cache")})
    subprocess.run([sys.executable, "-c", "import mod"], cwd=src, env=env, check=True)
    assert not (src / "__pycache__").exists()
    assert list((tmp_path / "cache").rglob("mod.*.pyc")), list(tmp_path.rglob("*"))
