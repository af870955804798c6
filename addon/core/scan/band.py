"""The band of sensor rows a chunk of frames renders, and when a band frame must be rendered
again at full height.

With ``leave_out.render_band`` only the rows where the line can fall are rendered: the
rows the line held in the previous frames, widened by a margin that follows how fast it
moves, joined with where the plan's ray casts put it; the first frame, and any frame
whose line touched the band's edge or thinned out there, is rendered at full height.
"""

from __future__ import annotations

import math

import numpy as np

from ..optics.detect import LineCode

BAND_FULL_SHARE = 0.75     # a band this tall (share of the rows) is not worth cropping
EDGE_PX = 1.5              # a line this close to the band's edge may run outside it
LOST_COLUMNS = 0.02        # more than this share of a camera's columns lost since the last frame: re-render


class Band:
    """The rows to render next: where the line was in the last frame, widened by a margin that
    follows its motion, joined with where the plan's ray casts put it in the coming frames."""

    def __init__(self, rows_px: int, margin_px: int, chunk: int, predicted: np.ndarray):
        self.H, self.margin, self.chunk = rows_px, margin_px, chunk
        self.predicted = predicted
        self.last: tuple[float, float] | None = None
        self.speed = 0.0

    def rows(self, first: int, count: int) -> tuple[int, int] | None:
        """Band for frames first..first+count−1 (0-based path indices); None: all rows."""
        lo, hi = [], []
        if self.last is not None:
            m = self.margin + self.speed * count
            lo.append(self.last[0] - m)
            hi.append(self.last[1] + m)
        pred = self.predicted[first:first + count]
        if np.isfinite(pred).any():
            lo.append(np.nanmin(pred[:, 0]) - self.margin)
            hi.append(np.nanmax(pred[:, 1]) + self.margin)
        if not lo:
            return None
        r0 = max(0, int(math.floor(min(lo))))
        r1 = min(self.H, int(math.ceil(max(hi))) + 1)
        return None if r1 - r0 >= BAND_FULL_SHARE * self.H else (r0, r1)

    def update(self, extent: tuple[float, float] | None) -> None:
        if extent is None:
            self.last, self.speed = None, 0.0
            return
        if self.last is not None:
            self.speed = max(abs(extent[0] - self.last[0]), abs(extent[1] - self.last[1]))
        self.last = extent


def line_extent(lines) -> tuple[float, float] | None:
    rows = np.concatenate([ln.row[ln.valid] for ln in lines if ln is not None] or [np.zeros(0)])
    return (float(rows.min()), float(rows.max())) if rows.size else None


def needs_full_frame(lines, rows, previous_rows, rows_px: int, margin_px: int) -> bool:
    """Whether a band render may have cut the line: it touches an inner edge of the band, or
    columns lost it whose line, in the previous frame, sat outside or near the band's edge
    (columns that lose the line well inside the band lost it for a real reason)."""
    if rows is None:
        return False
    low_edge, high_edge = rows[0] > 0, rows[1] < rows_px
    for cam, ln in enumerate(lines):
        if ln is None:
            continue
        r = ln.row[ln.valid]
        if r.size and ((low_edge and r.min() < rows[0] + EDGE_PX) or (high_edge and r.max() > rows[1] - 1 - EDGE_PX)):
            return True
        # A peak on the band's first or last row may be the flank of a line the band cut;
        # an edge elsewhere (the line cut by a depth edge of the part) is the scene's own.
        on_band_edge = (low_edge & (ln.peak_row <= rows[0])) | (high_edge & (ln.peak_row >= rows[1] - 1))
        if np.any((ln.code == LineCode.EDGE) & on_band_edge):
            return True
        prev = previous_rows[cam]
        if prev is None:
            continue
        lost = np.isfinite(prev) & ~ln.valid
        near = ((low_edge & (prev < rows[0] + margin_px)) | (high_edge & (prev > rows[1] - 1 - margin_px)))
        if np.sum(lost & near) > max(2, LOST_COLUMNS * len(ln.col)):
            return True
    return False
