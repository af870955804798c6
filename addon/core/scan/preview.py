"""The scan's picture: the cloud over the workpiece, each point coloured by its error; and a
strip of pictures of a scan growing view by view (``growth_strip``, for adaptive scans).

An orthographic view from above and in front; the workpiece mesh is drawn in grey
(faces shaded by their angle to the view, back to front), then the points that the
mesh does not hide, coloured by |error| on a fixed scale shown in a colour bar.
Table points are drawn small and grey. The title gives the numbers.
"""

from __future__ import annotations

import cv2
import numpy as np
import trimesh

VIEW = np.array([0.55, -0.75, 0.65])  # direction from the part towards the viewer (table frame)


def _view_basis(view: np.ndarray) -> np.ndarray:
    back = view / np.linalg.norm(view)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    return np.stack([right, up, back])  # rows: screen x, screen y, towards the viewer


def _canvas(mesh, pts: np.ndarray, W: int, H: int, bar_w: int):
    """(white image with the mesh drawn, shaded, back to front; screen coordinates and depth of
    points (n, 3); visible (n,): inside the picture and not behind the mesh's front faces)."""
    img = np.full((H, W, 3), 255, np.uint8)
    B = _view_basis(VIEW)
    ref = np.asarray(mesh.vertices) if mesh is not None and len(mesh.vertices) else pts
    lo, hi = ref.min(axis=0), ref.max(axis=0)
    centre = (lo + hi) / 2
    span = np.linalg.norm(hi - lo) * 1.15 + 1e-9
    px = min(W - bar_w - 20, H - 60) / span
    offset = np.array([(W - bar_w) / 2, (H + 30) / 2])

    def to_screen(P):
        q = (P - centre) @ B.T
        return np.column_stack([offset[0] + q[:, 0] * px, offset[1] - q[:, 1] * px]), q[:, 2]

    depth_map = np.full((H, W), -np.inf, np.float32)
    if mesh is not None and len(mesh.faces):
        v2, vz = to_screen(np.asarray(mesh.vertices))
        faces = np.asarray(mesh.faces)
        normals = np.asarray(mesh.face_normals) @ B.T
        shade = np.clip(0.35 + 0.6 * normals[:, 2], 0.2, 0.95)
        fz = vz[faces].mean(axis=1)
        for f in np.argsort(fz):  # back to front
            if normals[f, 2] <= 0:
                continue
            poly = np.round(v2[faces[f]]).astype(np.int32)
            g = int(255 * shade[f])
            cv2.fillConvexPoly(img, poly, (g, g, g), cv2.LINE_AA)
            cv2.fillConvexPoly(depth_map, poly, float(fz[f]))
    p2, pz = to_screen(pts)
    ij = np.round(p2).astype(int)
    inside = (ij[:, 0] >= 0) & (ij[:, 0] < W) & (ij[:, 1] >= 0) & (ij[:, 1] < H)
    visible = inside.copy()
    # Points hidden behind the part's front faces are not drawn (2 mm slack).
    visible[inside] = pz[inside] >= depth_map[ij[inside, 1], ij[inside, 0]] - 2.0
    return img, ij, pz, visible


FIXTURE_BGR = (150, 110, 60)  # points on the table's fixtures: a muted blue apart from the table's grey
BEYOND_BGR = (230, 0, 230)  # points far beyond the colour scale's top: magenta, drawn last and larger
BEYOND_SCALE = 3.0  # "far beyond": more than this many times the scale's top


def render_preview(mesh: trimesh.Trimesh | None, points: np.ndarray, error_um: np.ndarray | None,
                   on_part: np.ndarray, title: str, size=(900, 640), scale_um: float | None = None,
                   on_fixture: np.ndarray | None = None) -> np.ndarray:
    """BGR uint8 image. points (n, 3) mm table frame; error_um (n,) or None; on_part (n,) bool;
    on_fixture (n,) bool or None: points on the table's fixtures, drawn in their own colour."""
    W, H = size
    bar_w = 90
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if (mesh is None or not len(mesh.vertices)) and len(pts) == 0:
        img = np.full((H, W, 3), 255, np.uint8)
        put_title(img, title + " (no points)", 0.6)
        return img
    img, ij, pz, visible = _canvas(mesh, pts, W, H, bar_w)
    # The colour scale ends at the 95th percentile: a few edge outliers saturate at the
    # top instead of washing every other point out.
    top = scale_um if scale_um else (float(np.percentile(error_um[on_part], 95)) if error_um is not None
                                     and on_part.any() else 1.0)
    top = max(top, 1e-6)
    far = on_part & (error_um > BEYOND_SCALE * top) if error_um is not None else np.zeros(len(pts), bool)
    order = np.argsort(pz)
    for k in order:
        if not visible[k]:
            continue
        x, y = ij[k]
        if not on_part[k] or error_um is None:
            img[y, x] = FIXTURE_BGR if on_fixture is not None and on_fixture[k] else (150, 150, 150)
            continue
        if far[k]:  # drawn after the rest
            continue
        c = _colour(min(error_um[k] / top, 1.0))
        cv2.circle(img, (int(x), int(y)), 1, c, -1)
    # The scale ends at the 95th percentile, so a rim's 130 µm would read as its top: points far
    # beyond it are drawn over the rest in their own colour, and the bar says how many.
    for k in order[far[order] & visible[order]]:
        cv2.circle(img, (int(ij[k, 0]), int(ij[k, 1])), 2, BEYOND_BGR, -1)
    _colour_bar(img, W - bar_w + 10, 60, 22, H - 120, top)
    if far.any():
        x0, y0 = W - bar_w + 4, H - 44
        cv2.circle(img, (x0 + 4, y0 - 4), 3, BEYOND_BGR, -1)
        cv2.putText(img, f"> {bar_label(BEYOND_SCALE * top, BEYOND_SCALE * top)}", (x0 + 12, y0),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.4, (30, 30, 30), 1, cv2.LINE_AA)
        cv2.putText(img, f"{int(far.sum())} pts, max {error_um[far].max():.0f}", (x0 - 2, y0 + 16),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.35, (30, 30, 30), 1, cv2.LINE_AA)
    put_title(img, title, 0.55)
    return img


def put_title(img: np.ndarray, title: str, scale: float) -> None:
    """The title at the image's top left, broken after a comma onto a second line (and more)
    where one line would run off the image."""
    width = img.shape[1] - 114  # clear of the colour bar's label
    lines, line = [], ""
    for piece in title.split(", "):
        trial = piece if not line else f"{line}, {piece}"
        if line and cv2.getTextSize(trial, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)[0][0] > width:
            lines.append(line + ",")
            trial = piece
        line = trial
    for k, text in enumerate(lines + [line]):
        cv2.putText(img, text, (12, 28 + 22 * k), cv2.FONT_HERSHEY_SIMPLEX, scale, (20, 20, 20), 1, cv2.LINE_AA)


NEW_BGR, EARLIER_BGR = (20, 90, 240), (190, 120, 40)  # the latest view's points orange, earlier ones blue


def growth_strip(mesh: trimesh.Trimesh | None, points: np.ndarray, view: np.ndarray, titles: list[str],
                 size=(420, 330)) -> np.ndarray:
    """BGR uint8 picture strip of a scan growing view by view: panel k shows the points
    (n, 3) mm, table frame, whose ``view`` (n,) index is ≤ k over the mesh, those of view k
    in orange and the earlier ones in blue, under ``titles[k]``."""
    W, H = size
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    view = np.asarray(view)
    panels = []
    for k, title in enumerate(titles):
        img, ij, pz, visible = _canvas(mesh, pts if len(pts) else np.zeros((1, 3)), W, H, 0)
        if len(pts):
            for i in np.argsort(pz):
                if visible[i] and view[i] <= k:
                    cv2.circle(img, (int(ij[i, 0]), int(ij[i, 1])), 1, NEW_BGR if view[i] == k else EARLIER_BGR, -1)
        cv2.putText(img, title, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (20, 20, 20), 1, cv2.LINE_AA)
        cv2.rectangle(img, (0, 0), (W - 1, H - 1), (200, 200, 200), 1)
        panels.append(img)
    return cv2.hconcat(panels) if panels else np.full((H, W, 3), 255, np.uint8)


_LUT = cv2.applyColorMap(np.arange(256, dtype=np.uint8).reshape(-1, 1), cv2.COLORMAP_TURBO).reshape(256, 3)


def _colour(t: float) -> tuple[int, int, int]:
    b, g, r = _LUT[int(round(t * 255))]
    return int(b), int(g), int(r)


def bar_label(value_um: float, top_um: float) -> str:
    """A colour-bar label: as many decimals as the bar's top needs to keep two figures
    (top 55 µm: "28"; 2.3 µm: "1.2"; 0.4 µm: "0.20"), so a small scale does not read 1, 1, 0."""
    if not (np.isfinite(top_um) and top_um > 0):
        return f"{value_um:g}"
    decimals = min(3, max(0, 1 - int(np.floor(np.log10(top_um)))))
    return f"{value_um:.{decimals}f}"


def _colour_bar(img, x, y, w, h, top_um: float) -> None:
    for i in range(h):
        img[y + i, x:x + w] = _colour(1.0 - i / max(h - 1, 1))
    cv2.rectangle(img, (x, y), (x + w, y + h), (60, 60, 60), 1)
    for frac in (0.0, 0.5, 1.0):
        yy = int(y + (1 - frac) * h)
        cv2.putText(img, bar_label(frac * top_um, top_um), (x + w + 4, yy + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                    (30, 30, 30), 1,
                    cv2.LINE_AA)
    cv2.putText(img, "|error| um", (x - 14, y - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (30, 30, 30), 1, cv2.LINE_AA)
