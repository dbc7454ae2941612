"""Hypothesis budgets: one profile per test tier, and the tests' budgets derived from it.

``HYPOTHESIS_PROFILE`` picks the profile (``make test`` sets ``ci``, ``make quick`` sets
``quick``); without it, ``ci`` where the ``CI`` variable is set and ``dev`` elsewhere. A test
never writes a number of examples: it asks for the profile's budget (``scaled``) or for the
fuzz budget, which is what docs/reliability.md promises ("1,000 messages") under ``ci``.
"""

import os

from hypothesis import HealthCheck, settings

_COMMON = {"deadline": None, "suppress_health_check": [HealthCheck.too_slow]}
settings.register_profile("ci", max_examples=60, derandomize=True, **_COMMON)
settings.register_profile("dev", max_examples=30, **_COMMON)
settings.register_profile("quick", max_examples=10, **_COMMON)

#: Examples of a fuzz test (control messages, plan files, plans) under each profile.
_FUZZ = {"ci": 1000, "dev": 200, "quick": 40}


def load() -> str:
    """Load the profile this run asks for, and return its name."""
    name = os.environ.get("HYPOTHESIS_PROFILE") or ("ci" if os.environ.get("CI") else "dev")
    if name not in _FUZZ:
        raise ValueError(f"HYPOTHESIS_PROFILE={name!r}: valid profiles are {sorted(_FUZZ)}")
    settings.load_profile(name)
    return name


def scaled(fraction: float) -> settings:
    """The loaded profile's budget times ``fraction`` (a test whose examples cost more)."""
    return settings(max_examples=max(1, round(settings.default.max_examples * fraction)))


def fuzz(**overrides) -> settings:
    """The fuzz budget of the loaded profile."""
    return settings(max_examples=_FUZZ[settings.get_current_profile_name()], **overrides)
