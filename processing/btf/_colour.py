"""Normtextures between their stored colour space and linear values.

A measured BTF from elsewhere often comes as 8-bit sRGB images; PCA, light
interpolation and rendering need values proportional to radiance. Integer
values are first taken as a fraction of their type's full scale (uint8: /255),
then the colour space's transfer curve is undone (sRGB: IEC 61966-2-1,
``rig.interchange.srgb_decode``). :func:`from_linear` goes back, for images
to show or export. The material's ``units`` say which values it holds
(:func:`linear_units`).
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from processing.btf._errors import BtfError
from rig.interchange import srgb_decode, srgb_encode

__all__ = ["COLOUR_SPACES", "ColourSpace", "from_linear", "linear_units", "to_linear"]

ColourSpace = Literal["linear", "srgb"]
COLOUR_SPACES = ("linear", "srgb")
_INTEGERS = ("uint8", "uint16")


def _check_space(colour_space: str) -> None:
    if colour_space not in COLOUR_SPACES:
        raise BtfError(f"colour_space = {colour_space!r}: valid are {COLOUR_SPACES}")


def to_linear(values, *, colour_space: ColourSpace) -> np.ndarray:
    """Linear values of normtextures stored in ``colour_space``.

    Parameters
    ----------
    values : array, uint8 or uint16 (full scale = the type's maximum) or float in [0, 1]
    colour_space : {"linear", "srgb"}

    Returns
    -------
    float32 array of the same shape, linear, 1 at full scale

    Examples
    --------
    >>> to_linear(np.array([0, 188, 255], np.uint8), colour_space="srgb").round(2).tolist()
    [0.0, 0.5, 1.0]
    """
    _check_space(colour_space)
    array = np.asarray(values)
    if array.dtype.name in _INTEGERS:
        encoded = array / float(np.iinfo(array.dtype).max)
    elif np.issubdtype(array.dtype, np.floating):
        if not np.all(np.isfinite(array)):
            raise BtfError("values contain NaN or inf; mask or repair those texels first")
        encoded = array.astype(np.float64)
    else:
        raise BtfError(f"values of dtype {array.dtype}: expected uint8, uint16 or float")
    linear = srgb_decode(np.clip(encoded, 0.0, 1.0)) if colour_space == "srgb" else encoded
    return linear.astype(np.float32)


def from_linear(linear, *, colour_space: ColourSpace, dtype: str = "uint8") -> np.ndarray:
    """Linear values (1 at full scale, clipped to [0, 1]) encoded in ``colour_space``
    as ``dtype``: ``"uint8"``/``"uint16"`` (rounded) or ``"float32"``."""
    _check_space(colour_space)
    if dtype not in (*_INTEGERS, "float32"):
        raise BtfError(f"dtype = {dtype!r}: valid are uint8, uint16, float32")
    values = np.clip(np.nan_to_num(np.asarray(linear, np.float64), nan=0.0), 0.0, 1.0)
    encoded = srgb_encode(values) if colour_space == "srgb" else values
    if dtype == "float32":
        return encoded.astype(np.float32)
    return np.round(encoded * np.iinfo(dtype).max).astype(dtype)


def linear_units(colour_space: ColourSpace, dtype) -> str:
    """The material's ``units`` for normtextures decoded by :func:`to_linear`."""
    _check_space(colour_space)
    source = np.dtype(dtype).name
    stored = "sRGB" if colour_space == "srgb" else "linear"
    return f"linear relative radiance, 1 at full scale (decoded from {stored} {source})"
