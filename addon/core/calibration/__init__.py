"""Calibrating the probe as a real one is calibrated: a ChArUco board on the table, the
robot showing it to the probe cameras, Zhang's intrinsics, hand-eye poses and the laser
plane; and what a calibration's error does to the points."""

from .board import ChArUcoBoard, board_for
from .poses import board2table, board_views, flat_views, load_views
from .solve import BoardView, CameraFit, ProbeFit, calibrate_probe, deviations, triangulation_error

__all__ = ["BoardView", "CameraFit", "ChArUcoBoard", "ProbeFit", "board2table", "board_for", "board_views",
           "calibrate_probe", "deviations", "flat_views", "load_views", "triangulation_error"]
