"""Reply faults a peer injects on the wire: a reply that never comes, a garbled one, a
late one.

Two ways to ask, and both can be combined: counts (``drop_next(2)``: the next
two replies are not sent) for tests that must know exactly which request
fails, and rates (``no_reply_rate=0.01``, seeded) for long simulated sessions.
"""

from __future__ import annotations

import random
import threading
from collections.abc import Mapping
from typing import Any, Literal

from rig.errors import ConfigError

__all__ = ["ReplyFaults", "check_fault_keys"]

Decision = Literal["send", "drop", "garble", "late"]


def check_fault_keys(peer: str, faults: Mapping[str, Any], valid: set[str]) -> None:
    """Raise ``ConfigError`` naming any key of ``faults`` a peer does not know."""
    unknown = sorted(set(faults) - valid)
    if unknown:
        raise ConfigError(f"{peer}: unknown fault(s) {unknown}; valid are {sorted(valid)}")


class ReplyFaults:
    """Thread-safe decisions, one per reply: send it, drop it, or garble it.

    Parameters
    ----------
    no_reply : int
        Drop this many replies from now on.
    garbled : int
        Then garble this many (after the dropped ones).
    late : int
        Then hold this many back and send each just before the next reply: it arrives
        after the client gave up on it, when it is waiting for the answer to another
        request (a reply past the master's timeout on a serial line).
    no_reply_rate, garbled_rate : float
        Probability that any other reply is dropped / garbled.
    seed : int
        Seed of the rates' random generator (reproducible sessions).
    """

    KEYS = frozenset({"no_reply", "garbled", "late", "no_reply_rate", "garbled_rate", "seed"})

    def __init__(
        self,
        *,
        no_reply: int = 0,
        garbled: int = 0,
        late: int = 0,
        no_reply_rate: float = 0.0,
        garbled_rate: float = 0.0,
        seed: int = 0,
    ):
        for name, value in (("no_reply", no_reply), ("garbled", garbled), ("late", late)):
            if int(value) != value or value < 0:
                raise ConfigError(f"fault {name}={value!r} must be a count ≥ 0")
        for name, value in (("no_reply_rate", no_reply_rate), ("garbled_rate", garbled_rate)):
            if not 0.0 <= value <= 1.0:
                raise ConfigError(f"fault {name}={value!r} must be a probability in [0, 1]")
        if no_reply_rate + garbled_rate > 1.0:
            raise ConfigError(
                f"no_reply_rate + garbled_rate = {no_reply_rate + garbled_rate} exceeds 1"
            )
        self._lock = threading.Lock()
        self._drop = int(no_reply)
        self._garble = int(garbled)
        self._late = int(late)
        self._rates = (float(no_reply_rate), float(garbled_rate))
        self._rng = random.Random(seed)
        self.dropped = 0
        self.garbled = 0
        self.late = 0

    @classmethod
    def from_dict(cls, faults: Mapping[str, Any]) -> ReplyFaults:
        """Build from the reply-fault keys of a peer's fault table (others ignored)."""
        return cls(**{k: v for k, v in faults.items() if k in cls.KEYS})

    def drop_next(self, count: int = 1) -> None:
        """Send no reply to the next ``count`` requests."""
        with self._lock:
            self._drop += count

    def garble_next(self, count: int = 1) -> None:
        """Garble the next ``count`` replies (after any pending drops)."""
        with self._lock:
            self._garble += count

    def late_next(self, count: int = 1) -> None:
        """Hold the next ``count`` replies back until the reply after each (after any
        pending drops and garbles)."""
        with self._lock:
            self._late += count

    def clear(self) -> None:
        """Forget pending counts and rates: every reply is sent intact."""
        with self._lock:
            self._drop = self._garble = self._late = 0
            self._rates = (0.0, 0.0)

    def decide(self) -> Decision:
        """What to do with the reply about to be sent (counts it)."""
        with self._lock:
            if self._drop:
                self._drop -= 1
                decision: Decision = "drop"
            elif self._garble:
                self._garble -= 1
                decision = "garble"
            elif self._late:
                self._late -= 1
                decision = "late"
            else:
                draw = self._rng.random() if any(self._rates) else 1.0
                p_drop, p_garble = self._rates
                decision = (
                    "drop" if draw < p_drop else "garble" if draw < p_drop + p_garble else "send"
                )
            if decision == "drop":
                self.dropped += 1
            elif decision == "garble":
                self.garbled += 1
            elif decision == "late":
                self.late += 1
            return decision
