"""Camera model: projections, round trips and the bird's-eye warp."""
import numpy as np
import pytest

from signlane.camera import Camera

CAMERAS = [Camera(), Camera(640, 480, hfov_deg=70, height_m=1.6, pitch_deg=6),
           Camera(320, 240, pitch_deg=15, roll_deg=3, yaw_deg=-4), Camera(320, 160, hfov_deg=100, height_m=0.9)]


@pytest.mark.parametrize("cam", CAMERAS)
def test_image_ground_image_round_trip_within_half_pixel(cam):
    rng = np.random.default_rng(0)
    ground = cam.ground_mask(margin_px=3.0)
    ys, xs = np.nonzero(ground)
    pick = rng.choice(len(xs), 500, replace=False)
    pix = np.column_stack([xs[pick], ys[pick]]).astype(float) + rng.uniform(0, 1, (500, 2))
    back = cam.ground_to_image(cam.image_to_ground(pix))
    assert np.max(np.abs(back - pix)) < 0.5


@pytest.mark.parametrize("cam", CAMERAS)
def test_ground_points_ahead_project_below_horizon_and_in_order(cam):
    pts = np.array([[0.0, d] for d in (3, 5, 10, 20, 40)])
    pix = cam.ground_to_image(pts)
    # farther points are higher in the image (smaller y), all below the horizon
    assert np.all(np.diff(pix[:, 1]) < 0)
    n, c = cam.horizon()
    assert np.all(pix @ n + c > 0)


def test_axes_and_signs():
    cam = Camera()
    centre, right = cam.ground_to_image(np.array([[0.0, 10.0], [2.0, 10.0]]))
    assert right[0] > centre[0]  # ground x (right) maps to image x (right)
    assert abs(centre[0] - cam.width / 2) < 1e-6
    # tilting the camera further down moves a fixed ground point up the image
    tilted = Camera(pitch_deg=cam.pitch_deg + 5).ground_to_image(np.array([[0.0, 10.0]]))[0]
    assert tilted[1] < centre[1]
    # yaw right moves straight-ahead points to the left of the image
    yawed = Camera(yaw_deg=5).ground_to_image(np.array([[0.0, 10.0]]))[0]
    assert yawed[0] < cam.width / 2


def test_pixels_above_horizon_have_no_ground_point():
    cam = Camera()
    g = cam.image_to_ground(np.array([[160.0, 0.0], [160.0, 239.0]]))
    assert np.isnan(g[0]).all() and np.isfinite(g[1]).all()


def test_birdseye_maps_ground_metres_to_its_pixels():
    cam = Camera(640, 480)
    bev = cam.birdseye((200, 400), (-5.0, 5.0), (2.0, 22.0))
    pts = np.array([[-5.0, 22.0], [5.0, 2.0], [0.0, 12.0]])
    uv = bev.ground_to_bev(pts)
    assert np.allclose(uv, [[0, 0], [200, 400], [100, 200]])
    # image -> bird's-eye homography agrees with image -> ground -> bird's-eye
    pix = cam.ground_to_image(pts)
    h = bev.image_to_bev_h()
    p = np.column_stack([pix, np.ones(3)]) @ h.T
    assert np.allclose(p[:, :2] / p[:, 2:], uv, atol=1e-6)


def test_a_birdseye_views_rows_each_see_one_span_and_a_holed_mask_does_not():
    from signlane.camera import row_spans, via_camera
    bev = via_camera(320, 240).birdseye((224, 152), (-14.0, 14.0), (3.0, 22.0))
    any_seen, first, last, spans = bev.seen_rows
    assert spans and sum(any_seen) > 100
    row = max(i for i, a in enumerate(any_seen) if a)  # the nearest seen row: the frustum is narrower there
    assert first[row] > 0 and last[row] < 223 and bev.seen[row, first[row]:last[row] + 1].all()
    seen = bev.seen.copy()
    seen[row, (first[row] + last[row]) // 2] = False
    assert not row_spans(seen)[3]
    with pytest.raises(ValueError):
        bev.seen[0, 0] = False  # shared by every caller: read-only
