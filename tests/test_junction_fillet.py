"""A side road's corner fillet is not its end: in a bird's-eye road mask of a kerbed carriageway,
the rows of an opening that meet only the fillet beside a T's branch (road 1.8 m past the edge:
VIA's 1.6 m read a little wide; verge beyond) must not make the branch a dead end while the
branch's own rows cannot tell (its road runs into ground of neither colour: a planter, or where a
road model's mask frays); a branch whose road does end with verge beyond, 4 m past the edge as a
VIA T's branch that leads nowhere, still is one."""
from dataclasses import replace

import cv2
import numpy as np

from signlane.camera import via_camera
from signlane.junction import view_from_scan
from signlane.lanes.road_edges import RoadEdgesParams, RoadEdgesState, _bev, scan_edges

ROAD_BGR, VERGE_BGR, GRASS_BGR = (95, 95, 95), (40, 70, 105), (60, 170, 60)  # asphalt, brown ground, a planter


def _scan(branch_end_m: float, beyond_bgr=VERGE_BGR, fillet_m: float = 1.8):
    """The scan of a straight 4 m carriageway with a branch on the right from 13 to 17 m ahead,
    whose road runs branch_end_m past the edge with ground of beyond_bgr after it, and a fillet in
    the corner before it (fillet_m of road past the edge from 12 to 13 m ahead)."""
    p = RoadEdgesParams()
    bev = _bev(via_camera(320, 240), p, RoadEdgesState())
    h, w = bev.seen.shape
    img = np.zeros((h, w, 3), np.uint8)
    img[:] = VERGE_BGR

    def fill(x0, x1, y0, y1, bgr=ROAD_BGR):
        (u0, v1), (u1, v0) = np.rint(bev.ground_to_bev(np.array([[x0, y0], [x1, y1]]))).astype(int)
        img[max(v0, 0):max(v1, 0), max(u0, 0):max(u1, 0)] = bgr

    fill(-2.0, 2.0, 0.0, 40.0)
    fill(2.0 + branch_end_m, 40.0, 13.0, 17.0, beyond_bgr)
    fill(2.0, 2.0 + branch_end_m, 13.0, 17.0)
    fill(2.0, 2.0 + fillet_m, 12.0, 13.0)
    road = np.all(img == ROAD_BGR, axis=2) & bev.seen
    lab = cv2.cvtColor(img, cv2.COLOR_BGR2LAB).astype(np.int16)
    return replace(scan_edges(road, bev.seen, bev, p, 4.0), lab=lab)


def test_a_branch_that_goes_on_is_not_made_dead_by_its_fillet():
    # the branch's own rows see its road run into a planter: only the fillet rows see an end
    view = view_from_scan(_scan(branch_end_m=5.0, beyond_bgr=GRASS_BGR))
    assert view.right is not None and view.right.dead is not True
    assert 11.5 < view.right.near_m < 13.5


def test_a_branch_that_ends_is_still_a_dead_end():
    view = view_from_scan(_scan(branch_end_m=4.0))
    assert view.right is not None and view.right.dead is True
