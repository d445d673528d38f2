"""Top-down pictures of a track for people to look at, drawn the way VIA's minimap is: north up,
the map's grid centred on the world origin at 25 pixels a cell, grey road, white kerbs, the
ground of its bg_id; optionally signs and a driven path on top."""
from __future__ import annotations

import cv2
import numpy as np

from signlane.world.art import SIGN_NAMES
from signlane.world.scene import ASPHALT, KERB, SHADOW, Scene

SIGN_BGR = {"stop": (40, 40, 220), "left": (200, 120, 0), "right": (200, 120, 0), "straight": (200, 120, 0),
            "no_left": (200, 60, 200), "no_right": (200, 60, 200)}
# VIA's minimap colours (BGR), read off its renders (../shared/via/minimaps)
MINIMAP_ROAD = (73, 71, 70)
MINIMAP_GROUND = {"grass": (41, 83, 58), "ground": (24, 37, 51), "none": (110, 108, 106)}
PX_PER_CELL = 25
MARK_BGR = (0, 230, 255)  # yellow crosses: where something happened (e.g. the car left the road)


def minimap_frame(track, px_per_cell: float = PX_PER_CELL, margin_cells: float = 0.0):
    """(x0, y1, px_per_m, width, height): the picture covers the grid, centred on the world
    origin as VIA's minimap is, plus a margin (and any tile that reaches beyond the grid)."""
    k = px_per_cell / track.cell_m
    half_w, half_h = track.cols / 2 * track.cell_m, track.rows / 2 * track.cell_m
    cells = np.array([c for t in track.tiles for c in t.footprint], float) + np.array(track.grid_origin)
    (bx0, by0), (bx1, by1) = (cells.min(axis=0) - 0.5) * track.cell_m, (cells.max(axis=0) + 0.5) * track.cell_m
    m = margin_cells * track.cell_m
    x0, x1 = min(-half_w, bx0) - m, max(half_w, bx1) + m
    y0, y1 = min(-half_h, by0) - m, max(half_h, by1) + m
    return x0, y1, k, int(round((x1 - x0) * k)), int(round((y1 - y0) * k))


def road_mask(track, scene: Scene, px_per_cell: float = PX_PER_CELL) -> np.ndarray:
    """uint8 0/255 mask of the road surface in the minimap frame (kerbs and paint excluded)."""
    x0, y1, k, w, h = minimap_frame(track, px_per_cell)
    mask = np.zeros((h, w), np.uint8)
    p = scene.paint
    for i in np.nonzero(p.layers == ASPHALT)[0]:
        poly = p.verts[p.starts[i]:p.starts[i + 1]]
        pix = np.column_stack([(poly[:, 0] - x0) * k, (y1 - poly[:, 1]) * k])
        cv2.fillPoly(mask, [np.round(pix * 16).astype(np.int32)], 255, cv2.LINE_8, 4)
    return mask


def draw_topdown(scene: Scene, px_per_cell: float = PX_PER_CELL, path_xy: np.ndarray | None = None,
                 marks: list[tuple[float, float]] | None = None, marks_label: str = "mark",
                 signs: bool = True, legend: str | None = None, start_xy: np.ndarray | None = None) -> np.ndarray:
    """uint8 BGR picture of the scene from above (see the module docstring); path_xy (N,2) world
    metres is drawn in red, marks (world metres) as yellow crosses, called `marks_label` in the
    legend. With `legend` (what the red path is, e.g. "driven
    path"), a strip below the map says what each colour is, with a 10 m scale bar; the map
    itself stays VIA's minimap, pixel for pixel. The green start dot is start_xy (world metres),
    by default the path's first point."""
    track = scene.track
    x0, y1, k, w, h = minimap_frame(track, px_per_cell)
    img = np.full((h, w, 3), MINIMAP_GROUND.get(track.background, MINIMAP_GROUND["none"]), np.uint8)

    def to_px(xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, float).reshape(-1, 2)
        return np.column_stack([(xy[:, 0] - x0) * k, (y1 - xy[:, 1]) * k])

    p = scene.paint
    lk = scene.looks
    colour = {ASPHALT: MINIMAP_ROAD, KERB: (245, 245, 245), 1: lk.white, 2: lk.yellow}
    order = np.argsort([{ASPHALT: 0, SHADOW: 9}.get(int(layer), 1) for layer in p.layers], kind="stable")
    for i in order:
        layer = int(p.layers[i])
        if layer == SHADOW:
            continue
        poly = np.round(to_px(p.verts[p.starts[i]:p.starts[i + 1]]) * 16).astype(np.int32)
        cv2.fillPoly(img, [poly], colour.get(layer, lk.white), cv2.LINE_AA, 4)
    # the path under the signs, so that their labels stay readable
    if path_xy is not None and len(path_xy) > 1:
        pts = np.round(to_px(path_xy) * 16).astype(np.int32)
        cv2.polylines(img, [pts], False, (0, 0, 255), 2, cv2.LINE_AA, 4)
        start = path_xy[:1] if start_xy is None else start_xy
        cv2.circle(img, tuple(int(v) for v in to_px(start)[0]), 4, (0, 255, 0), -1)
    px_per_m = k
    for obj in scene.objects if signs else []:
        c = to_px([[obj.x, obj.y]])[0]
        is_sign = obj.kind in SIGN_NAMES
        col = SIGN_BGR.get(obj.kind, (0, 200, 255)) if is_sign else (160, 160, 160)
        r = max(3, int(0.6 * px_per_m)) if is_sign else max(1, int(0.3 * px_per_m))
        cv2.circle(img, tuple(int(v) for v in c), r, col, -1, cv2.LINE_AA)
        if is_sign:
            tip = c + 2.0 * px_per_m * np.array([np.cos(obj.facing), -np.sin(obj.facing)])
            cv2.line(img, tuple(int(v) for v in c), tuple(int(v) for v in tip), col, 1, cv2.LINE_AA)
            tw = cv2.getTextSize(obj.kind, cv2.FONT_HERSHEY_SIMPLEX, 0.35, 1)[0][0]
            tx = int(c[0]) + r + 1 if int(c[0]) + r + 1 + tw < w else int(c[0]) - r - 1 - tw  # inside the picture
            cv2.putText(img, obj.kind, (max(0, tx), max(10, int(c[1]) - r)), cv2.FONT_HERSHEY_SIMPLEX,
                        0.35, (255, 255, 255), 1, cv2.LINE_AA)
    for x, y in marks or []:
        cv2.drawMarker(img, tuple(int(v) for v in to_px([[x, y]])[0]), MARK_BGR, cv2.MARKER_TILTED_CROSS, 12, 2)
    if legend is None:
        return img
    kinds = {o.kind for o in scene.objects if o.kind in SIGN_NAMES} if signs else set()
    return np.vstack([img, _legend_strip(img.shape[1], k, legend if path_xy is not None else None, kinds,
                                         MINIMAP_GROUND.get(track.background, MINIMAP_GROUND["none"]),
                                         marks_label if marks else None)])


def _legend_strip(width: int, px_per_m: float, path_label: str | None, sign_kinds: set[str], ground,
                  marks_label: str | None = None) -> np.ndarray:
    """Rows of swatches and labels under a map: road, kerb, the path, its start, the marks,
    each sign colour present, and a 10 m scale bar; wrapped to the map's width."""
    items = [("road", "box", MINIMAP_ROAD), ("kerb", "box", (245, 245, 245))]
    if path_label:
        items += [(path_label, "line", (0, 0, 255)), ("start", "dot", (0, 255, 0))]
    if marks_label:
        items.append((marks_label, "cross", MARK_BGR))
    groups = [("stop sign", {"stop"}), ("turn / straight sign", {"left", "right", "straight"}),
              ("no-turn sign", {"no_left", "no_right"})]
    items += [(name, "dot", SIGN_BGR[sorted(ks & sign_kinds)[0]]) for name, ks in groups if ks & sign_kinds]
    if sign_kinds:
        items.append(("(a sign's tick: the way it faces)", "text", None))
    items.append(("10 m", "scale", (255, 255, 255)))
    font, scale, row_h = cv2.FONT_HERSHEY_SIMPLEX, 0.4, 20
    widths = [{"scale": int(10 * px_per_m), "text": -6}.get(kind, 16) + 6 + cv2.getTextSize(t, font, scale, 1)[0][0] + 14
              for t, kind, _ in items]
    rows, x = 1, 6
    for w in widths:  # how many rows the items wrap to
        if x + w > width and x > 6:
            rows, x = rows + 1, 6
        x += w
    strip = np.full((rows * row_h + 6, width, 3), 30, np.uint8)
    x, y = 6, 4
    for (text, kind, col), w in zip(items, widths):
        if x + w > width and x > 6:
            x, y = 6, y + row_h
        cy = y + row_h // 2
        if kind == "box":
            cv2.rectangle(strip, (x, cy - 6), (x + 16, cy + 6), ground, -1)
            cv2.rectangle(strip, (x + 2, cy - 4), (x + 14, cy + 4), col, -1)
            sw = 16
        elif kind == "line":
            cv2.line(strip, (x, cy), (x + 16, cy), col, 2, cv2.LINE_AA)
            sw = 16
        elif kind == "dot":
            cv2.circle(strip, (x + 8, cy), 5, col, -1, cv2.LINE_AA)
            sw = 16
        elif kind == "cross":
            cv2.drawMarker(strip, (x + 8, cy), col, cv2.MARKER_TILTED_CROSS, 12, 2)
            sw = 16
        elif kind == "text":
            sw = -6
        else:  # the scale bar, 10 m long at the map's scale
            sw = int(10 * px_per_m)
            cv2.line(strip, (x, cy), (x + sw, cy), col, 2)
            for end in (x, x + sw):
                cv2.line(strip, (end, cy - 4), (end, cy + 4), col, 2)
        cv2.putText(strip, text, (x + sw + 6, cy + 5), font, scale, (235, 235, 235), 1, cv2.LINE_AA)
        x += w
    return strip
