"""Fixtures of the archive tests."""

import pytest
import zarr


@pytest.fixture(scope="session", autouse=True)
def zarr_runtime():
    """Start zarr's process-wide I/O thread and its one-worker pool once.

    zarr keeps an event-loop thread and a thread pool alive for the life of
    the process; started here, before the per-test leak check takes its
    snapshot, they are not reported as leaks of the first test that uses zarr.
    """
    zarr.config.set({"threading.max_workers": 1})
    zarr.create_array(store={}, shape=(1,), dtype="uint8")[:] = 1
