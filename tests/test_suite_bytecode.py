"""tests/run.py keeps compiled bytecode for both phases, outside the tree: PYTHONDONTWRITEBYTECODE
(set on this machine) made every process a test starts compile cdus again."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tests.run import bytecode_env

ROOT = Path(__file__).resolve().parents[1]


def test_bytecode_is_kept_in_a_cache_of_the_temporary_directory_unless_the_caller_chose_one(tmp_path):
    env = bytecode_env({"PYTHONDONTWRITEBYTECODE": "1", "HOME": "/root"})
    assert "PYTHONDONTWRITEBYTECODE" not in env and env["HOME"] == "/root"
    prefix = Path(env["PYTHONPYCACHEPREFIX"])
    assert prefix.is_absolute() and ROOT not in prefix.parents
    assert bytecode_env({"PYTHONPYCACHEPREFIX": str(tmp_path)})["PYTHONPYCACHEPREFIX"] == str(tmp_path)


def test_a_process_started_with_it_writes_its_bytecode_there_and_nothing_into_the_tree(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    (src / "mod.py").write_text("X = 1\n")
    env = bytecode_env({**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "PYTHONPYCACHEPREFIX": str(tmp_path / "cache")})
    subprocess.run([sys.executable, "-c", "import mod"], cwd=src, env=env, check=True)
    assert not (src / "__pycache__").exists()
    assert list((tmp_path / "cache").rglob("mod.*.pyc")), list(tmp_path.rglob("*"))
