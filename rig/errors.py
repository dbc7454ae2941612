"""The domain exceptions every btfrig package raises.

Each carries a message a lab user can act on: what was wrong, where, and what
would be valid.
"""


class RigError(Exception):
    """Base class of every btfrig error."""


class ConfigError(RigError):
    """A rig config, scene or calibration file is invalid."""


class PlanError(RigError):
    """A measurement plan is invalid; ``problems`` lists one message per field."""

    def __init__(self, source: str, problems: list[str]):
        self.source = source
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"{source}: {len(self.problems)} problem(s)\n{lines}")


class KinematicsError(RigError):
    """A wanted direction or actuator position lies outside what the rig can do."""
