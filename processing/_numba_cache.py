"""The compiled kernels' disk cache, keyed to every source file a kernel is built from.

numba stamps a cached kernel with its own file's modification time and size only. A
kernel compiled together with helpers or constants from another module (an inlined sum,
a jitted callee, a reason code) would load stale machine code after that module changed.
:func:`keep_fresh`, called at the end of a kernel module, stamps the cache with a hash of
all those sources and empties the module's cache indexes when the hash is new, so the next
call compiles again.
"""

from __future__ import annotations

import contextlib
import hashlib
import sys
from pathlib import Path
from types import ModuleType

from numba.core.dispatcher import Dispatcher


def keep_fresh(module_name: str, *sources: ModuleType) -> bool:
    """Drop the cached machine code of ``module_name``'s kernels if any source changed.

    Parameters
    ----------
    module_name : str
        The kernel module (pass ``__name__``); its ``cache=True`` kernels are checked.
    *sources : module
        The modules its kernels compile from, besides itself.

    Returns
    -------
    bool
        True when the cache was emptied (the sources differ from the stamp, or there was
        no stamp yet).
    """
    module = sys.modules[module_name]
    kernels = [
        obj
        for obj in vars(module).values()
        if isinstance(obj, Dispatcher)
        and obj.py_func.__module__ == module_name
        and getattr(obj._cache, "cache_path", None)  # only cache=True kernels have one
    ]
    if not kernels:
        return False
    digest = hashlib.sha256()
    for path in sorted({module.__file__, *(m.__file__ for m in sources)}):
        digest.update(Path(path).read_bytes())
    # numba's private handle on the cache: the public API has no way to empty it.
    cache_dir = Path(kernels[0]._cache.cache_path)
    stamp = cache_dir / f"{Path(module.__file__).stem}.sources.sha256"
    with contextlib.suppress(OSError):
        if stamp.read_text() == digest.hexdigest():
            return False
    for kernel in kernels:
        kernel._cache.flush()
    # A cache folder numba cannot write to either is refreshed on every import: still correct.
    with contextlib.suppress(OSError):
        cache_dir.mkdir(parents=True, exist_ok=True)
        stamp.write_text(digest.hexdigest())
    return True
