"""Test-wide policy: hypothesis profiles and a leak check on every test.

A test that leaves a thread, a socket or a child process behind fails: a daemon
that runs for hours cannot afford leaks, and a leaking test hides them.
"""

import contextlib
import threading
import time

import psutil
import pytest

from tests import budgets

budgets.load()

_LEAK_GRACE_S = 3.0


def _live_threads() -> set[threading.Thread]:
    return {t for t in threading.enumerate() if t.is_alive()}


def _sockets(proc: psutil.Process) -> set[tuple]:
    return {(c.fd, c.family, c.type, c.laddr) for c in proc.net_connections(kind="all")}


def _children(proc: psutil.Process) -> set[int]:
    alive = set()
    for child in proc.children(recursive=True):
        try:
            if child.status() != psutil.STATUS_ZOMBIE:
                alive.add(child.pid)
        except psutil.NoSuchProcess:
            continue
    return alive


@pytest.fixture(scope="session", autouse=True)
def process_wide_threads():
    """Start the library threads that live as long as the process, once.

    zarr keeps an event-loop thread and a thread pool; pyzmq starts a garbage
    collector thread on the first zero-copy send of a large frame; distributed
    keeps one offload thread. Started
    here, before the per-test leak check takes its snapshot, they are not
    reported as leaks of the first test that uses them.
    """
    import zarr
    from zmq.utils.garbage import gc as zmq_garbage

    zarr.config.set({"threading.max_workers": 1})
    zarr.create_array(store={}, shape=(1,), dtype="uint8")[:] = 1
    zmq_garbage.start()
    with contextlib.suppress(ImportError):  # the dask extra: its one offload thread
        from distributed.utils import _offload_executor

        _offload_executor.submit(int).result()


@pytest.fixture(autouse=True)
def no_leaks(request):
    """Fail a test that leaves threads, sockets or child processes behind."""
    proc = psutil.Process()
    threads_before = _live_threads()
    sockets_before = _sockets(proc)
    children_before = _children(proc)
    yield
    deadline = time.monotonic() + _LEAK_GRACE_S
    while True:
        threads = [t.name for t in _live_threads() - threads_before]
        sockets = sorted(str(s) for s in _sockets(proc) - sockets_before)
        children = sorted(_children(proc) - children_before)
        if not (threads or sockets or children) or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    problems = []
    if threads:
        problems.append(f"threads {threads}")
    if sockets:
        problems.append(f"sockets {sockets}")
    if children:
        problems.append(f"child processes {children}")
    if problems:
        pytest.fail(f"{request.node.nodeid} left behind: " + "; ".join(problems))
