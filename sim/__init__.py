"""The simulated rig: scenes, image formation, ground truth, world state.

Public API::

    from sim import Simulator, load_scene
    scene = load_scene("examples/scenes/default.toml")
    with Simulator(scene) as sim:
        frame = sim.render_state("cam0", lamps_on=["lamp2"])
        truth = sim.truth("cam0")
"""

from sim.samples import Generator, SampleGeometry, generator_names, register_sample
from sim.scene import EFFECTS, Scene, SceneSpec, load_scene, scene_from_dict
from sim.simulator import Frame, Simulator
from sim.truth import TexelTruth, Truth
from sim.world import World, WorldSnapshot

__all__ = [
    "EFFECTS",
    "Frame",
    "Generator",
    "SampleGeometry",
    "Scene",
    "SceneSpec",
    "Simulator",
    "TexelTruth",
    "Truth",
    "World",
    "WorldSnapshot",
    "generator_names",
    "load_scene",
    "register_sample",
    "scene_from_dict",
]
