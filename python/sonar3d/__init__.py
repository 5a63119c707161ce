"""sonar3d: 3D maps from 2D imaging-sonar images.

Simulate sonar datasets, import recordings (HoloOcean/neusis pickles, frames + navigation logs),
denoise, reconstruct and evaluate against CAD ground truth. Everything is SI (metres, seconds,
radians); images are float32 arrays of range bins x beams (row 0 nearest), poses 4x4 float64
arrays T_world_sonar (sonar frame: +x boresight, +y left, +z up), clouds N x 3 float32 arrays.

Errors raise ``sonar3d.Error`` (a RuntimeError) whose message names the file, line or frame.

    >>> import sonar3d
    >>> ds = sonar3d.read_dataset("dataset")
    >>> image, pose = ds.frame(0), ds.pose(0)
"""
import numpy as _np

from ._sonar3d import *  # noqa: F401,F403
from ._sonar3d import Error, _polar_to_sonar, _sonar_to_polar, __version__  # noqa: F401
from . import _sonar3d

__all__ = [name for name in dir(_sonar3d) if not name.startswith("_")] + [
    "polar_to_sonar",
    "sonar_to_polar",
    "pixel_to_world",
]


def polar_to_sonar(r, bearing, elevation):
    """Sonar-frame points r*(cos(el)cos(b), cos(el)sin(b), sin(el)) for broadcastable arrays of
    range (m), bearing and elevation (rad); shape (..., 3)."""
    r, b, e = _np.broadcast_arrays(_np.asarray(r, _np.float64), _np.asarray(bearing, _np.float64),
                                   _np.asarray(elevation, _np.float64))
    out = _polar_to_sonar(r.ravel(), b.ravel(), e.ravel())
    return out.reshape(r.shape + (3,))


def sonar_to_polar(points):
    """(range, bearing, elevation) of sonar-frame points (..., 3) as an array (..., 3)."""
    p = _np.asarray(points, _np.float64)
    out = _sonar_to_polar(p.reshape(-1, 3))
    return out.reshape(p.shape)


def pixel_to_world(spec, T_world_sonar, rows, cols, elevation=0.0):
    """World points of image pixels: the centre range of each row, the bearing of each column,
    at the given elevation (rad; a pixel does not know its elevation, the aperture spans
    +-spec.vertical_aperture/2). rows, cols, elevation broadcast; returns (..., 3)."""
    rows = _np.asarray(rows)
    cols = _np.asarray(cols)
    r = spec.r_min + (rows + 0.5) * spec.range_resolution
    b = _np.asarray(spec.bearings)[cols]
    p = polar_to_sonar(r, b, elevation)
    T = _np.asarray(T_world_sonar, _np.float64)
    return p @ T[:3, :3].T + T[:3, 3]
