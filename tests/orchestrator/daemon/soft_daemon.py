"""A daemon with soft devices in its own process, for the kill -9 tests.

Run as ``python -m tests.orchestrator.daemon.soft_daemon [--delay SECONDS]``:
binds free loopback ports,
prints one JSON line with its endpoints, and serves until ``shutdown`` (or a
signal). ``--delay`` makes each camera read take that long in real time, so a
test can kill the process in the middle of a session.
"""

import argparse
import dataclasses
import json

from orchestrator.daemon import Daemon
from orchestrator.wire.endpoints import DaemonSettings
from rig.clock import VirtualClock
from rig.config import default_rig_config
from tests.orchestrator.daemon.soft import SoftRig, soft_devices


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--delay", type=float, default=0.0)
    args = parser.parse_args()
    config = default_rig_config()
    rig = SoftRig(config, VirtualClock(), real_delay_s=args.delay)
    daemon = Daemon(
        config,
        settings=DaemonSettings(port=0, status_interval_s=0.2, drain_timeout_s=2.0),
        devices=soft_devices(rig),
        clock=rig.clock,
    )
    endpoints = daemon.bind()
    print(json.dumps(dataclasses.asdict(endpoints)), flush=True)
    daemon.serve()


if __name__ == "__main__":
    main()
