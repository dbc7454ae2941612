"""btfrig's top layer: the ZeroMQ orchestrator and the ``rig`` command line.

The daemon (session state machine, devices, archive writes), its client, the
workers, replay and the CLI. It may use every package below it; nothing below
imports it.
"""
