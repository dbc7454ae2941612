"""What the README's commands write into the checkout is ignored by git, so a new
user following it word for word leaves `git status` clean."""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
# the options of `rig …` commands that name a file or folder to write
_WRITES = re.compile(r"--(?:out|config-out|archive)\s+(\S+)")


def _written_by_readme() -> list[str]:
    blocks = re.findall(r"```sh\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
    return sorted({path for block in blocks for path in _WRITES.findall(block)})


def test_the_readme_names_what_it_writes():
    assert "sim-rig.toml" in _written_by_readme()


@pytest.mark.parametrize("path", _written_by_readme())
def test_what_the_readme_writes_is_ignored(path):
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    ignored = subprocess.run(
        ["git", "-C", str(ROOT), "check-ignore", "--quiet", "--no-index", path], check=False
    )
    assert ignored.returncode == 0, f"{path}, written by a README command, is not ignored"
