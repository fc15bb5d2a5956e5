"""The README's test command and CI's (.ci/run) stay in step, and the README says, next to the
command, which system packages the tests need (issue 27: the screenshot tests were skipped
without mesa-vulkan-drivers, which only a paragraph far below the command named)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COMMAND = "python3 -m pip install -e '.[test]' && python3 tests/run.py"


def test_the_readme_names_the_packages_ci_installs_next_to_its_test_command():
    readme, ci = (ROOT / "README.md").read_text(), (ROOT / ".ci" / "run").read_text()
    assert COMMAND.replace("-e", "--quiet -e") in ci  # CI runs the README's command
    packages = re.search(r"apt-get install -y -qq ([a-z0-9 .-]+)", ci)[1].split()
    assert "mesa-vulkan-drivers" in packages
    at = readme.index(COMMAND)
    after = readme[at:readme.index("\n## ", at)]  # the rest of the section the command is in
    assert all(p in after for p in packages), (packages, after)
    assert ".ci/run" in after
