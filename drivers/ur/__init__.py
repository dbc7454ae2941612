"""Universal Robots arms (CB3 3.10+, e-Series 5.4–5.8) over the controller's TCP interfaces.

URScript and the real-time state stream on port 30003, the dashboard server
on port 29999; ``UrArm`` is the driver (its docstring lists the API), opened
in the ``arm`` role for a ``kind = "ur"`` device section.
"""

from drivers.ur.arm import ArmStatus, UrArm

__all__ = ["ArmStatus", "UrArm"]
