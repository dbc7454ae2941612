"""A stats worker in its own process, for the worker-kill test.

Run as ``python -m tests.orchestrator.daemon.worker_proc ENDPOINTS_JSON NAME [--die-after N]``: with
``--die-after`` it SIGKILLs itself on receiving its N-th frame, before the
result leaves, with more frames queued in its socket.
"""

import argparse
import json
import os
import signal

from orchestrator.wire.endpoints import Endpoints
from orchestrator.worker import STAGES, frame_stats, run_worker


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("endpoints")
    parser.add_argument("name")
    parser.add_argument("--die-after", type=int, default=None)
    args = parser.parse_args()
    endpoints = Endpoints(**json.loads(args.endpoints))
    if args.die_after is not None:
        seen = 0

        def dying(image, header):
            nonlocal seen
            seen += 1
            if seen >= args.die_after:
                os.kill(os.getpid(), signal.SIGKILL)
            return frame_stats(image)

        STAGES["stats"] = dying
    run_worker("stats", endpoints, name=args.name, heartbeat_s=0.1)


if __name__ == "__main__":
    main()
