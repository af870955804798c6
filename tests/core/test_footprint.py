"""The laser's footprint: which frames put a surface inside the probe's range."""

import numpy as np
import trimesh

from addon.core.config.rigs import load_probe
from addon.core.geometry.footprint import SurfaceCaster, laser_footprint
from addon.core.kinematics.path import DOWN, probe_orientation
from addon.core.kinematics.transforms import make_pose


def test_a_surface_exactly_at_either_range_end_is_in_range_and_a_hair_beyond_is_not():
    """A plate square to the beam lies at one depth for every ray of the fan. A plate at a range
    end, read a rounding error beyond it (a pose from the robot's joints), is in range; 0.01 mm
    beyond either end is out."""
    probe = load_probe("default")
    z0, z1 = probe.z_range_mm
    plate = SurfaceCaster([trimesh.creation.box(extents=[400.0, 400.0, 10.0])])  # top at z = 5
    depths = [z0 - 0.01, z0 - 1e-9, z0 + 0.5, z1 - 0.5, z1 + 1e-9, z1 + 0.01]
    poses = np.stack([make_pose(probe_orientation(DOWN, (0.0, 1.0, 0.0)), [0.0, 0.0, 5.0 + d]) for d in depths])
    foot = laser_footprint(probe, poses, plate)
    assert sorted(foot.empty_frames) == [0, 5], foot.empty_frames
