"""What a scanner has learnt about the space around a part it cannot see in advance: a voxel
grid whose cells are unknown, free (a laser ray passed through) or surface (a measured point).

This is the model an adaptive planner reasons on (it never reads the part's mesh): every
profile adds its points, each with the laser origin it was measured from; the ray from
the origin to the point crossed free space, and the point's cell holds surface. A cell
once seen as surface stays surface (a grazing ray may pass a hair through a surface cell
of a neighbouring profile). The grid covers a bounding volume given by the user (a box on
the table), in the table frame, mm.

``first_hits`` casts rays through the model, as a candidate view would see it: each ray
runs through free cells until the first cell that is not free, which is unknown (that
view would learn something there) or surface (seen before); rays that leave the grid hit
nothing. ``frontier`` lists the unknown cells next to free ones, where the unknown begins.
``coverage_estimate`` weighs the surface found against that frontier: the planner's own
guess of how much of the part it has seen, from the model alone.

Rays are walked in steps of half a cell (cheap and vectorised; a cell only clipped at a
corner by a ray can be missed, which the next profile's rays fill in).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from ..errors import InputError

UNKNOWN, FREE, SURFACE = 0, 1, 2
STEP_SHARE = 0.5   # ray samples per cell size
CHUNK_SAMPLES = 4_000_000  # ray samples handled at once (memory)
MAX_CELLS = 200_000_000    # the model's cells at most (a byte each)


class KnownSpace:
    """Cells of ``voxel_mm`` over the box [lo, hi] (table frame, mm), all unknown at first."""

    def __init__(self, lo, hi, voxel_mm: float):
        lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
        if lo.shape != (3,) or hi.shape != (3,) or not (np.isfinite(lo).all() and np.isfinite(hi).all()):
            raise InputError(f"the known-space box needs two finite 3-vectors, got {lo!r} and {hi!r}")
        if isinstance(voxel_mm, bool) or not isinstance(voxel_mm, numbers.Real) or not (
                math.isfinite(voxel_mm) and voxel_mm > 0) or not (hi > lo).all():
            raise InputError(f"the known-space box must have positive size and cells (a positive number of mm), "
                             f"got lo {lo.tolist()}, hi {hi.tolist()}, cell {voxel_mm!r} mm")
        counts = np.ceil((hi - lo) / float(voxel_mm))  # floats: a huge box must not wrap an integer
        if float(np.prod(counts)) > MAX_CELLS:
            raise InputError(f"{' x '.join(f'{c:.3g}' for c in counts)} cells of {voxel_mm} mm is too many for the "
                             f"model of what is known (at most {MAX_CELLS:,}): use larger cells ([adaptive] voxel_mm) "
                             f"or a smaller box")
        shape = counts.astype(int)
        self.lo, self.voxel = lo, float(voxel_mm)
        self.hi = lo + shape * self.voxel
        self.state = np.zeros(tuple(shape), dtype=np.uint8)

    # -- cells ----------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int, int]:
        return self.state.shape

    def cell_of(self, points) -> tuple[np.ndarray, np.ndarray]:
        """(cell indices (n, 3), inside the grid (n,)) of points (n, 3)."""
        idx = np.floor((np.asarray(points, dtype=np.float64) - self.lo) / self.voxel).astype(np.int64)
        inside = np.all((idx >= 0) & (idx < np.array(self.shape)), axis=-1)
        return idx, inside

    def centres(self, idx) -> np.ndarray:
        return self.lo + (np.asarray(idx) + 0.5) * self.voxel

    def counts(self) -> dict[str, int]:
        values = np.bincount(self.state.ravel(), minlength=3)
        return {"unknown": int(values[UNKNOWN]), "free": int(values[FREE]), "surface": int(values[SURFACE])}

    # -- learning ---------------------------------------------------------------------
    def add_points(self, origins, points) -> int:
        """Learn from measured points (n, 3) seen along rays from ``origins`` (n, 3) or one (3,):
        free cells along each ray, surface where it ends. Returns the cells newly known."""
        P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        O = np.broadcast_to(np.asarray(origins, dtype=np.float64), P.shape)
        ok = np.isfinite(P).all(axis=1) & np.isfinite(O).all(axis=1)
        P, O = P[ok], O[ok]
        before = int(np.count_nonzero(self.state))
        if len(P):
            d = P - O
            length = np.linalg.norm(d, axis=1)
            u = d / np.maximum(length, 1e-12)[:, None]
            # Free up to half a cell short of the point, so that the point's own cell is spared.
            self._walk(O, u, np.maximum(length - 0.5 * self.voxel, 0.0), mark=FREE)
            idx, inside = self.cell_of(P)
            i = idx[inside]
            self.state[i[:, 0], i[:, 1], i[:, 2]] = SURFACE
        return int(np.count_nonzero(self.state)) - before

    def _walk(self, origins, dirs, lengths, mark: int | None = None):
        """Visit each ray's cells from its origin up to ``lengths`` (inside the grid only):
        with ``mark``, set them (surface cells kept); else return, per ray, the distance to the
        first cell that is not free (inf: none before ``lengths``) and that cell's state."""
        n = len(origins)
        t0, t1 = self._clip(origins, dirs, lengths)
        crosses = np.isfinite(t0) & np.isfinite(t1) & (t1 > t0)
        t0, t1 = np.where(crosses, t0, 0.0), np.where(crosses, t1, 0.0)  # rays that miss: no samples
        step = STEP_SHARE * self.voxel
        steps = np.where(crosses, np.ceil((t1 - t0) / step).astype(np.int64) + 1, 0)
        first = np.full(n, np.inf)
        what = np.full(n, FREE, dtype=np.uint8)
        if not steps.any():
            return first, what
        per_chunk = max(1, CHUNK_SAMPLES // max(int(steps.max()), 1))
        shape = np.array(self.shape)
        for a in range(0, n, per_chunk):
            s = slice(a, min(a + per_chunk, n))
            k = np.arange(int(steps[s].max()))
            t = t0[s, None] + k[None, :] * step
            valid = (k[None, :] < steps[s, None]) & (t <= t1[s, None])
            t = np.minimum(t, t1[s, None])
            pts = origins[s, None, :] + t[..., None] * dirs[s, None, :]
            idx = np.clip(np.floor((pts - self.lo) / self.voxel).astype(np.int64), 0, shape - 1)
            if mark is not None:
                cells = idx[valid]
                current = self.state[cells[:, 0], cells[:, 1], cells[:, 2]]
                keep = current != SURFACE
                cells = cells[keep]
                self.state[cells[:, 0], cells[:, 1], cells[:, 2]] = mark
                continue
            state = self.state[idx[..., 0], idx[..., 1], idx[..., 2]]
            blocked = valid & (state != FREE)
            hit = blocked.any(axis=1)
            j = np.argmax(blocked, axis=1)
            rows = np.arange(len(j))
            first[s] = np.where(hit, t[rows, j], np.inf)
            what[s] = np.where(hit, state[rows, j], FREE)
        return first, what

    def _clip(self, origins, dirs, lengths):
        """Ray parameters (t0, t1) of each ray's part inside the grid box, within [0, length]
        (t1 ≤ t0: the ray misses the box)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / dirs
            a = (self.lo - origins) * inv
            b = (self.hi - origins) * inv
        with np.errstate(invalid="ignore"):
            lo_t, hi_t = np.minimum(a, b), np.maximum(a, b)
        # NaN (a ray in a face's plane, 0·inf) and ±inf (parallel) put no bound on that axis.
        near = np.max(np.where(np.isfinite(lo_t), lo_t, -np.inf), axis=1)
        far = np.min(np.where(np.isfinite(hi_t), hi_t, np.inf), axis=1)
        # A ray parallel to a pair of faces lies between them or misses the box.
        parallel = dirs == 0
        outside = parallel & ((origins < self.lo) | (origins > self.hi))
        far = np.where(outside.any(axis=1), -np.inf, far)
        return np.maximum(near, 0.0), np.minimum(far, lengths)

    # -- asking -------------------------------------------------------------------------
    def first_hits(self, origins, dirs, max_range_mm: float) -> tuple[np.ndarray, np.ndarray]:
        """Per ray (n): the distance to the first cell that is not free within ``max_range_mm``
        (inf: none) and its state (UNKNOWN or SURFACE; FREE where none)."""
        D = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
        O = np.broadcast_to(np.asarray(origins, dtype=np.float64), D.shape)
        D = D / np.linalg.norm(D, axis=1, keepdims=True)
        return self._walk(np.ascontiguousarray(O), D, np.full(len(D), float(max_range_mm)))

    def frontier(self) -> np.ndarray:
        """Indices (m, 3) of unknown cells with a free cell among their six neighbours."""
        return np.argwhere(self._frontier_mask())

    def _frontier_mask(self) -> np.ndarray:
        return _beside(self.state == FREE) & (self.state == UNKNOWN)

    def coverage_estimate(self, lo, hi) -> float:
        """The share of the part's surface seen so far, as the model alone can tell it: surface
        cells against surface plus frontier cells, counting the cells whose centres lie in the
        part's box [lo, hi] above its bottom layer (the table top, where the part stands).

        A guide, not a measurement: the frontier only marks where the unknown begins. A
        large hidden region seen through a small opening counts as small (a sphere seen
        from one side, 35 % of it, reads about 0.54), and the edge of space no ray has
        crossed counts as unseen surface (the same sphere seen whole from six sides reads
        about 0.60; from 26 directions, 1). Pockets no laser ray enters (the part's
        underside on the table) have no frontier and do not count. ``bench adaptive``
        shows it beside the true coverage.
        0 before anything is known."""
        lo, hi = box_arrays(lo, hi, "coverage_estimate: the part's box")
        bottom = lo.copy()
        bottom[2] += self.voxel
        ranges = [_cell_range(self.lo[a], self.voxel, self.shape[a], bottom[a], hi[a]) for a in range(3)]
        if ranges[2][0] >= ranges[2][1]:  # a part thinner than a cell and a half: the layer holding its top
            top = min(max(int(np.floor((hi[2] - self.lo[2]) / self.voxel)), 0), self.shape[2] - 1)
            ranges[2] = (top, top + 1)
        keep = tuple(slice(*r) for r in ranges)
        surface = int(np.count_nonzero(self.state[keep] == SURFACE))
        frontier = int(np.count_nonzero(self._frontier_mask()[keep]))
        return surface / (surface + frontier) if surface else 0.0


def box_arrays(lo, hi, what: str) -> tuple[np.ndarray, np.ndarray]:
    """A box (mm) as two float arrays, or InputError: ``what`` needs three finite numbers each,
    lo < hi."""
    try:
        lo_a, hi_a = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    except (TypeError, ValueError):
        lo_a = hi_a = np.full(0, np.nan)
    if lo_a.shape != (3,) or hi_a.shape != (3,) or not (np.isfinite(lo_a).all() and np.isfinite(hi_a).all()
                                                        and (hi_a > lo_a).all()):
        def shown(v):
            return v.tolist() if isinstance(v, np.ndarray) else v

        raise InputError(f"{what} needs lo < hi in x, y and z, three finite numbers (mm) each, got "
                         f"{shown(lo)!r} .. {shown(hi)!r}")
    return lo_a, hi_a


def _cell_range(grid_lo: float, voxel: float, n: int, lo: float, hi: float) -> tuple[int, int]:
    """(first, end) indices of the cells along one axis whose centres lie in [lo, hi]."""
    first = int(np.ceil((lo - grid_lo) / voxel - 0.5))
    end = int(np.floor((hi - grid_lo) / voxel - 0.5)) + 1
    return min(max(first, 0), n), min(max(end, 0), n)


def _beside(mask: np.ndarray) -> np.ndarray:
    """Cells with a ``mask`` cell among their six neighbours."""
    near = np.zeros_like(mask)
    for axis in range(3):
        for shift in (1, -1):
            rolled = np.roll(mask, shift, axis=axis)
            edge = [slice(None)] * 3
            edge[axis] = 0 if shift == 1 else -1
            rolled[tuple(edge)] = False
            near |= rolled
    return near
