"""Probe optics: the probe's geometry (two cameras about the laser plane, Eq. 7), the sensor
model (ideal or realistic), laser-line detection, triangulation (Eq. 6, exact or the
paper's) and the profile filter."""

from .detect import DetectParams, LineCode, LineDetection, detect_line
from .probe import Probe, angles_from_range
from .profile_filter import ProfileFilter, filter_profile
from .sensor import SensorModel
from .triangulate import Profile, fuse_profiles, triangulate_profile

__all__ = ["DetectParams", "LineCode", "LineDetection", "Probe", "Profile", "ProfileFilter", "SensorModel",
           "angles_from_range", "detect_line", "filter_profile", "fuse_profiles", "triangulate_profile"]
