"""The point-light renderer: a measured material under point and directional lights.

:class:`Renderer` (:mod:`render.points.renderer`) with its macro shadow maps
(``_shadows``) and, where the material holds an MDF (seed 001 §4), its
mesostructure silhouettes by depth peeling (:mod:`render.points.peel`), the MDF
on the GPU (:mod:`render.points.mdf`) and the ambient term of shadowed points
(:mod:`render.points.ambient`).
"""

from render.points.peel import MAX_PEEL
from render.points.renderer import Renderer

__all__ = ["MAX_PEEL", "Renderer"]
