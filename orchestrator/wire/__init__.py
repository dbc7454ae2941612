"""The wire between the daemon, its clients and its workers: messages, endpoints, limits.

``protocol``: control requests and replies, events, frame and result headers, and the
size and number limits every socket enforces; ``endpoints``: where the daemon listens and
the rule that remote use needs CURVE keys. The daemon, the client and the workers all
import this package and none of each other. See ``docs/daemon.md``.
"""
