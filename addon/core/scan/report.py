"""A scan's report, typed, and its JSON (strict: no NaN or infinity, which JSON does not have).

``report.json`` is written by :func:`report_json` only; :class:`ScanReport` reads the same
content back as dataclasses (``ScanReport.from_dict(json.load(f))``), so a script writes
``report.error_um.rms_um`` rather than dictionary keys.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields

import numpy as np

from ..errors import InputError
from ..geometry.metrics import ErrorStats


def _finite_or_none(value):
    """JSON has no NaN or infinity: such numbers become null, everywhere in a structure."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(v) for v in value]
    return value


def as_json(value, where: str = "extra"):
    """``value`` with numpy's scalars and arrays as Python's numbers and lists (a planner's
    record made with numpy), checked to be JSON: InputError naming what is not."""
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise InputError(f"{where}: the key {k!r} is not a string (a JSON object's keys are)")
            out[k] = as_json(v, f"{where}[{k!r}]")
        return out
    if isinstance(value, (list, tuple)):
        return [as_json(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, np.ndarray):
        return as_json(value.tolist(), where)
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise InputError(f"{where}: {type(value).__name__} {str(value)[:60]!r} is not JSON (numbers, strings, booleans, "
                     f"None, lists and dicts of them join the report)")


def report_json(report) -> str:
    """The one way a report becomes JSON: a ScanReport or its dict, NaN and infinity as null."""
    data = report.to_dict() if isinstance(report, ScanReport) else report
    return json.dumps(_finite_or_none(data), indent=2, allow_nan=False) + "\n"


def _nan(value) -> float:
    return float("nan") if value is None else float(value)


@dataclass(frozen=True)
class ScanReport:
    """What a scan measured and what it cost.

    frames: profiles taken; points: in the cloud (on the part / on the table / on the table's
    fixtures, nearer a fixture than the part and the table top); error_um: of the
    part's points against its exact shape; table_error_um: of the table's points against its
    top; coverage: share of the part's whole surface within coverage_tolerance_mm of a point;
    coverage_measurable: the same share of the surface the path's laser can measure (in range,
    within the incidence limit, seen by a camera), which is measurable_share of the whole;
    column_codes: sensor columns per detection code; points_dropped: columns dropped after
    detection, by reason; points_fused: points both cameras agreed on; time_s: seconds per stage;
    profiles_per_s: frames / (render + detect + triangulate); config: what was scanned;
    clearance: the smallest distance between the robot or the probe and the table, the workpiece
    or a fixture over the motion (``nearest``) and per path entry (``per_path``), each with its
    bodies, frame and point (None where the config turns collision checks off); outliers: the
    part's points farther than 0.2 mm (metrics.OUTLIER_MM) from it; within_2_sigma: the share of
    the part's points within twice their stated σ (the cloud's quality), None without any.
    """

    config: dict
    frames: int
    points: int
    points_on_part: int
    points_on_table: int
    error_um: ErrorStats
    table_error_um: ErrorStats
    coverage: float
    coverage_tolerance_mm: float
    coverage_measurable: float
    measurable_share: float
    valid_fraction: float
    column_codes: dict
    points_dropped: dict
    points_fused: int
    cameras_rendered: list
    frames_rerendered_full: int
    mean_rows_rendered: float
    time_s: dict
    profiles_per_s: float
    warnings: list = field(default_factory=list)
    clearance: dict | None = None
    software: dict = field(default_factory=dict)
    points_on_fixtures: int = 0
    outliers: int = 0
    within_2_sigma: float | None = None
    render_device: str | None = None
    extra: dict = field(default_factory=dict)  # anything else a run adds (a farm's shard counts)
    # The keys in the order the report came in, which to_dict keeps (report.json written again
    # through this class came out in the fields' order, and no longer compared line by line).
    key_order: tuple = field(default=(), repr=False, compare=False)

    @classmethod
    def from_dict(cls, d: dict) -> "ScanReport":
        names = {f.name for f in fields(cls)} - {"extra", "key_order"}
        kwargs = {k: v for k, v in d.items() if k in names}
        kwargs["error_um"] = ErrorStats.from_dict(d["error_um"])
        kwargs["table_error_um"] = ErrorStats.from_dict(d["table_error_um"])
        kwargs["profiles_per_s"] = _nan(d["profiles_per_s"])
        return cls(**kwargs, extra={k: v for k, v in d.items() if k not in names}, key_order=tuple(d))

    def to_dict(self) -> dict:
        d = asdict(self)
        order = d.pop("key_order")
        d.update(d.pop("extra"))
        return {**{k: d[k] for k in order if k in d}, **d}
