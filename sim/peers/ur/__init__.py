"""A simulated Universal Robots controller (dashboard + real-time interface) on loopback."""

from sim.peers.ur._script import ScriptError, parse_program
from sim.peers.ur.controller import UrControllerPeer

__all__ = ["ScriptError", "UrControllerPeer", "parse_program"]
