"""A square cloth dropped over a sphere resting on a table, settled by position-based dynamics.

The cloth is a grid of particles held by distance constraints to its rest
lengths: structural (grid edges), shear (cell diagonals) and, weaker, bending
(every second particle). Each time step moves the particles by their velocity
and gravity, then projects the constraints a few times, Gauss–Seidel in groups
of constraints that share no particle, and pushes particles out of the sphere
and the table (with friction, so the cloth does not slide off). Everything is
fixed-order numpy arithmetic: the same arguments give the same cloth.

The folds come from the drape itself: the hanging skirt is longer around than
the circle it hangs on, so it buckles. A last relaxation without gravity brings
every edge back close to its rest length, so the rest grid is a faithful UV map.

References
----------
M. Müller, B. Heidelberger, M. Hennix, J. Ratcliff, "Position based dynamics",
J. Vis. Commun. Image Represent. 18 (2007) 109–118.
"""

from __future__ import annotations

import numpy as np

__all__ = ["drape"]

_GRAVITY_MM_S2 = 9810.0
_DAMPING_PER_S = 0.03  # fraction of the velocity a free particle keeps after one second
_FRICTION = 0.6  # fraction of a step's sliding that a contact removes
_BENDING_STIFFNESS = 0.1

# One constraint group: a stride k along the grid's second axis (1 structural, 2 bending),
# or a diagonal (+1 or −1 columns per row), and a colour: groups of one colour share no particle.
_Group = tuple[str, int, int, float]


def _groups() -> list[_Group]:
    groups: list[_Group] = []
    for stride, stiffness in ((1, 1.0), (2, _BENDING_STIFFNESS)):
        for axis in ("rows", "columns"):
            groups += [(axis, stride, colour, stiffness) for colour in range(2 * stride)]
    groups += [(diagonal, 1, colour, 1.0) for diagonal in ("down", "up") for colour in range(2)]
    return groups


def _pairs(grid: np.ndarray, group: _Group) -> tuple[np.ndarray, np.ndarray, float]:
    """Views of the group's first and second particles, and their rest distance in cells."""
    kind, stride, colour, _ = group
    n = grid.shape[0]
    if kind in ("rows", "columns"):
        lines = grid if kind == "columns" else grid.swapaxes(0, 1)
        step = 2 * stride
        return lines[:, colour : n - stride : step], lines[:, colour + stride : n : step], stride
    first_rows, second_rows = grid[colour : n - 1 : 2], grid[colour + 1 : n : 2]
    if kind == "down":
        return first_rows[:, :-1], second_rows[:, 1:], np.sqrt(2.0)
    return first_rows[:, 1:], second_rows[:, :-1], np.sqrt(2.0)


def _project(grid: np.ndarray, groups: list[_Group], spacing: float, boost: float) -> None:
    """One Gauss–Seidel sweep over every group, in place (``boost`` > 1 over-relaxes)."""
    for group in groups:
        first, second, cells = _pairs(grid, group)
        delta = second - first
        length = np.sqrt(np.sum(delta * delta, axis=-1, keepdims=True))
        scale = boost * group[3] * 0.5 * (length - cells * spacing) / np.maximum(length, 1e-9)
        first += scale * delta
        second -= scale * delta


def _collide(
    positions: np.ndarray, previous: np.ndarray, radius_mm: float, floor_mm: float
) -> None:
    """Push particles out of the sphere (centre at the origin) and above the floor, in place.

    A contact also removes part of the step's sliding along the surface (friction),
    so the cloth rests on the sphere instead of slipping off it.
    """
    distance = np.sqrt(np.sum(positions * positions, axis=1))
    inside = distance < radius_mm
    if inside.any():
        outward = positions[inside] / np.maximum(distance[inside], 1e-9)[:, None]
        step = outward * radius_mm - previous[inside]
        sliding = step - outward * np.sum(step * outward, axis=1, keepdims=True)
        positions[inside] = outward * radius_mm - _FRICTION * sliding
    below = positions[:, 2] < floor_mm
    if below.any():
        positions[below, 2] = floor_mm
        positions[below, :2] -= _FRICTION * (positions[below, :2] - previous[below, :2])


def drape(
    *,
    size_mm: float,
    sphere_radius_mm: float,
    segments: int,
    settle_s: float = 1.5,
    steps_per_s: int = 960,
) -> np.ndarray:
    """Settle a flat square cloth dropped onto a sphere that rests on a table.

    Parameters
    ----------
    size_mm : side of the square cloth
    sphere_radius_mm : the sphere's radius; its centre is the origin, the table is z = −r
    segments : grid cells per side; (segments + 1)² particles
    settle_s : simulated time from the drop
    steps_per_s : time steps per simulated second, one constraint sweep each

    Returns
    -------
    positions : ((segments + 1)², 3) float64, mm
        Row-major over the rest grid: particle (row j, column i) at index
        j·(segments + 1) + i, at rest (i·h − size/2, j·h − size/2) with h = size/segments.
        Every particle lies on or outside the sphere and on or above the table.
    """
    n = segments + 1
    spacing = size_mm / segments
    column, row = np.meshgrid(np.arange(n), np.arange(n))
    rest = np.stack([column * spacing - size_mm / 2, row * spacing - size_mm / 2], -1)
    grid = np.concatenate([rest, np.full((n, n, 1), sphere_radius_mm + spacing)], axis=-1)
    # A slight deterministic skew, so the drape does not balance on a symmetric fold pattern.
    grid[..., :2] += 0.05 * spacing * np.sin(rest[..., ::-1] / (7.3 * spacing))
    positions = grid.reshape(-1, 3)  # a view: the groups and the contacts edit the same array

    groups = _groups()
    dt = 1.0 / steps_per_s
    keep = _DAMPING_PER_S**dt
    fall = np.array([0.0, 0.0, -_GRAVITY_MM_S2 * dt * dt])
    floor_mm = -sphere_radius_mm
    previous = positions.copy()
    for _ in range(round(settle_s * steps_per_s)):
        velocity = keep * (positions - previous)
        previous[:] = positions
        positions += velocity + fall
        _project(grid, groups, spacing, 1.0)
        _collide(positions, previous, sphere_radius_mm, floor_mm)
    # Relax without gravity: the grid's edges return close to their rest lengths. Bending and
    # shear constraints are left out here, as in a fold they pull against the edges.
    structural = [group for group in groups if group[0] in ("rows", "columns") and group[1] == 1]
    for _ in range(steps_per_s // 4):
        _project(grid, structural, spacing, 1.0)
        _collide(positions, positions.copy(), sphere_radius_mm, floor_mm)  # no friction
    return positions.copy()
