"""A compiled kernel's disk cache follows the helpers it is compiled from."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]

KERNEL = """
from numba import njit

from processing._numba_cache import keep_fresh
from shop import helper


@njit(cache=True)
def compute():
    return helper.value()


flushed = keep_fresh(__name__, helper)
"""

HELPER = """
from numba import njit


@njit(inline="always")
def value():
    return {value}
"""


def _run(root: Path) -> tuple[int, bool]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), str(REPO)])}
    env.pop("NUMBA_CACHE_DIR", None)
    out = subprocess.run(
        [sys.executable, "-c", "from shop import kernel; print(kernel.compute(), kernel.flushed)"],
        env=env, capture_output=True, text=True, timeout=120, check=True,
    ).stdout.split()
    return int(out[0]), out[1] == "True"


def test_a_changed_helper_recompiles_the_cached_kernel(tmp_path):
    shop = tmp_path / "shop"
    shop.mkdir()
    (shop / "__init__.py").write_text("")
    (shop / "kernel.py").write_text(KERNEL)
    (shop / "helper.py").write_text(HELPER.format(value=1))

    assert _run(tmp_path) == (1, True)  # first compile: no stamp yet
    assert _run(tmp_path) == (1, False)  # loaded from the cache, nothing dropped
    assert list((shop / "__pycache__").glob("kernel.compute-*.nbc"))

    # Only the helper changes: numba's own stamp (the kernel file's) still matches.
    (shop / "helper.py").write_text(HELPER.format(value=2))
    assert _run(tmp_path) == (2, True)
    assert _run(tmp_path) == (2, False)
