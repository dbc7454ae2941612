"""Bounded retries with exponential backoff on an injected clock."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TypeVar

from drivers.errors import DeviceError, DeviceTimeout, ProtocolError
from rig.clock import Clock
from rig.devices import Retry

__all__ = ["with_retries"]

log = logging.getLogger(__name__)
T = TypeVar("T")


def with_retries(
    attempt: Callable[[], T],
    *,
    retry: Retry,
    clock: Clock,
    device: str,
    operation: str,
    retry_on: tuple[type[BaseException], ...] = (DeviceTimeout, ProtocolError),
) -> T:
    """Call ``attempt`` until it succeeds or ``retry.retries`` extra tries fail.

    Only ``retry_on`` errors are retried (transient: timeouts, garbled replies);
    anything else propagates at once. After the last failure a ``DeviceError``
    of the last error's class is raised, naming device, operation and tries.
    """
    delay = retry.backoff_s
    for tries in range(1, retry.retries + 2):
        try:
            return attempt()
        except retry_on as err:
            if tries > retry.retries:
                kind = type(err) if isinstance(err, DeviceError) else DeviceTimeout
                detail = err.detail if isinstance(err, DeviceError) else str(err)
                raise kind(device, operation, f"{detail} (gave up after {tries} tries)") from err
            log.warning("%s: %s: %s; retry %d/%d", device, operation, err, tries, retry.retries)
            clock.sleep(delay)
            delay *= 2
    raise AssertionError("unreachable")
