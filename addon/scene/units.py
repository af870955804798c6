"""The one place where millimetres (core) become metres (Blender) and back."""

from __future__ import annotations

import numpy as np
from mathutils import Matrix

M_PER_MM = 1e-3
# OpenCV camera axes (x right, y down, z forward) -> Blender camera axes (x right, y up, looking along −z).
CV_TO_BLENDER_CAMERA = np.diag([1.0, -1.0, -1.0, 1.0])


def to_blender(T_mm: np.ndarray) -> Matrix:
    """(4, 4) transform with translation in mm -> mathutils.Matrix in metres."""
    T = np.array(T_mm, dtype=np.float64)
    T[:3, 3] *= M_PER_MM
    return Matrix(T.tolist())


def from_blender(M) -> np.ndarray:
    """mathutils.Matrix (metres) -> (4, 4) float64 with translation in mm."""
    T = np.array(M, dtype=np.float64)
    T[:3, 3] /= M_PER_MM
    return T


def points_to_blender(P_mm: np.ndarray) -> np.ndarray:
    """Points (n, 3) mm -> metres, Blender's unit (locations, keyframed translations)."""
    return np.asarray(P_mm, dtype=np.float64) * M_PER_MM
