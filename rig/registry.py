"""A registry of callables by (role, kind), filled by the modules that serve them.

The drivers (``drivers.registry``: who opens a device) and the simulator
(``sim.peers.registry``: who answers as one) both map a role's configured
``kind`` to the code that serves it. Each family registers itself at import;
the first lookup of an unknown pair imports every public module of the
package, so a new family is found without being listed anywhere.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Iterable
from typing import Any

__all__ = ["KindRegistry"]


class KindRegistry:
    """Callables by (role, kind) for the modules of ``package``.

    Parameters
    ----------
    package : the dotted name of the package whose modules register
    roles : the roles a registration may name
    """

    def __init__(self, package: str, roles: Iterable[str]) -> None:
        self.package = package
        self.roles = tuple(roles)
        self._entries: dict[tuple[str, str], Callable[..., Any]] = {}
        self._discovered = False

    def register(self, role: str, kind: str) -> Callable[[Callable], Callable]:
        """Decorator: the function serves ``kind`` in ``role``."""
        if role not in self.roles:
            raise ValueError(
                f"{self.package}: unknown role {role!r}; valid are {list(self.roles)}"
            )

        def add(entry: Callable) -> Callable:
            existing = self._entries.get((role, kind))
            if existing is not None and existing is not entry:
                raise ValueError(f"{self.package}: {role}/{kind} is registered twice")
            self._entries[(role, kind)] = entry
            return entry

        return add

    def unregister(self, role: str, kind: str) -> None:
        """Forget what serves ``kind`` in ``role`` (a family added for a while, e.g. a test's)."""
        self._entries.pop((role, kind), None)

    def lookup(self, role: str, kind: str) -> Callable[..., Any] | None:
        """What serves ``kind`` in ``role``, or None (then see :meth:`served`)."""
        if (role, kind) not in self._entries:
            self._discover()
        return self._entries.get((role, kind))

    def served(self, role: str) -> list[str]:
        """The kinds registered for ``role`` (every module of the package imported first)."""
        self._discover()
        return sorted(k for r, k in self._entries if r == role)

    def _discover(self) -> None:
        if self._discovered:
            return
        package = importlib.import_module(self.package)
        for module in pkgutil.iter_modules(package.__path__):
            if not module.name.startswith("_"):
                importlib.import_module(f"{self.package}.{module.name}")
        self._discovered = True
