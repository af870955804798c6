"""Project exceptions.

Every error a user can cause (a malformed rig file, a NaN joint angle, an
unreachable pose) is one of these, with a message that names what was wrong and
what is allowed. The command line prints the message on one line and exits
non-zero; the Blender panel shows it in the status bar.
"""

import numbers


class ScannerError(Exception):
    """Base class of all errors the simulator raises on purpose."""


class ConfigError(ScannerError):
    """A rig, probe or scene file is missing, malformed or out of range.

    The message starts with the file path and names the key and the allowed values.
    """


class InputError(ScannerError, ValueError):
    """A value passed to a function is malformed (wrong shape, non-finite, non-rigid)."""


class TemporaryFailure(ScannerError):
    """Nothing is wrong with the input: something the command needs is not there for now
    (another scan's output folder, a cluster that went away), and the same command may work
    later (the command line exits 75, sysexits' EX_TEMPFAIL, for it)."""


class FolderBusy(TemporaryFailure):
    """Another scan holds the output folder."""


class CollisionError(ScannerError):
    """A pose or a motion would bring the robot or the probe into (or too near) something."""


class CalibrationError(ScannerError):
    """A calibration cannot be made from these images and poses (board not found, too few
    or degenerate poses, no laser line); the message says what to change."""


class UnreachablePose(ScannerError):
    """Inverse kinematics found no joint vector within limits for a target pose.

    ``result`` carries the solver's best attempt (an ``IKResult``) for diagnosis.
    """

    def __init__(self, message: str, result=None):
        super().__init__(message)
        self.result = result


def is_whole(value) -> bool:
    """Whether ``value`` is a whole number: Python's or numpy's (a loop's np.int64), not a bool."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def check_whole(value, what: str, lo: int, hi: int) -> int:
    """``value`` as an int when it is a whole number (:func:`is_whole`) in [lo, hi]; otherwise
    an InputError that names ``what`` and the allowed range."""
    if not is_whole(value) or not lo <= value <= hi:
        raise InputError(f"{what} must be a whole number in [{lo}, {hi}], got {value!r}")
    return int(value)


def check_number(value, what: str, lo: float, hi: float) -> float:
    """``value`` as a float when it is a real number (Python's or numpy's, not a bool or a
    string) in [lo, hi] (NaN never is); otherwise an InputError that names ``what`` and the range."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not lo <= value <= hi:
        raise InputError(f"{what} must be a number in [{lo:g}, {hi:g}], got {value!r}")
    return float(value)
