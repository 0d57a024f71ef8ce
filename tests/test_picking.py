"""Projection and picking maths of the 3D view (isochor.app.view.picking): numpy only, headless.

The cameras are written out by hand (OpenGL look-at, orthographic and perspective
matrices), so these tests need neither VTK nor Qt.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from isochor.app.view.picking import PICK_RADIUS, PICK_TIE, Projection, drag_delta, in_rect, nearest
from tests.fresh import run_fresh

ROOT = Path(__file__).resolve().parents[1]

W, H = 640, 480
EYE = np.array([3.0, -4.0, 2.5])
TARGET = np.array([0.2, 0.1, -0.3])
UP = np.array([0.0, 0.0, 1.0])


# -- hand-made cameras ---------------------------------------------------------------------
def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def look_at(eye, target, up) -> np.ndarray:
    """The OpenGL view matrix (gluLookAt): world -> eye coordinates, looking down -z."""
    eye = np.asarray(eye, dtype=np.float64)
    f = _unit(np.asarray(target) - eye)
    s = _unit(np.cross(f, up))
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def perspective(fovy_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    """The OpenGL projection matrix (gluPerspective)."""
    f = 1.0 / np.tan(np.radians(fovy_deg) / 2)
    return np.array(
        [
            [f / aspect, 0.0, 0.0, 0.0],
            [0.0, f, 0.0, 0.0],
            [0.0, 0.0, (far + near) / (near - far), 2 * far * near / (near - far)],
            [0.0, 0.0, -1.0, 0.0],
        ]
    )


def ortho(left, right, bottom, top, near, far) -> np.ndarray:
    """The OpenGL projection matrix (glOrtho)."""
    return np.array(
        [
            [2 / (right - left), 0.0, 0.0, -(right + left) / (right - left)],
            [0.0, 2 / (top - bottom), 0.0, -(top + bottom) / (top - bottom)],
            [0.0, 0.0, -2 / (far - near), -(far + near) / (far - near)],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def camera(kind: str, dpr: float = 1.0, offset=(0.0, 0.0)) -> Projection:
    """A Projection of a W x H (logical pixels) widget, looking from EYE at TARGET."""
    view = look_at(EYE, TARGET, UP)
    aspect = W / H
    if kind == "perspective":
        proj = perspective(35.0, aspect, 0.5, 50.0)
    else:
        half = 2.0
        proj = ortho(-half * aspect, half * aspect, -half, half, 0.5, 50.0)
    x0, y0 = offset
    return Projection(proj @ view, (x0, y0, W * dpr, H * dpr), float(H) + y0 / dpr, dpr)


FORWARD = _unit(TARGET - EYE)
RIGHT = _unit(np.cross(FORWARD, UP))
CAM_UP = np.cross(RIGHT, FORWARD)

KINDS = ["orthographic", "perspective"]
CAMERAS = [(k, d) for k in KINDS for d in (1.0, 2.0)]


@pytest.fixture(params=CAMERAS, ids=[f"{k}-dpr{d:g}" for k, d in CAMERAS])
def proj(request) -> Projection:
    return camera(*request.param)


def cloud(n: int = 50, seed: int = 1) -> np.ndarray:
    """Points around the target, all in front of the camera."""
    rng = np.random.default_rng(seed)
    return TARGET + rng.uniform(-1.5, 1.5, (n, 3))


# -- Projection ----------------------------------------------------------------------------
def test_project_then_unproject_round_trips(proj):
    pts = cloud()
    xy, depth, visible = proj.project(pts)
    assert xy.shape == (len(pts), 2) and depth.shape == (len(pts),)
    assert visible.all()
    assert np.all((depth > -1) & (depth < 1))
    back = np.array([proj.unproject(x, y, z) for (x, y), z in zip(xy, depth)])
    np.testing.assert_allclose(back, pts, rtol=0, atol=1e-9)


def test_unproject_then_project_round_trips(proj):
    for x, y, z in [(0.0, 0.0, -0.3), (W - 1.0, H - 1.0, 0.7), (123.25, 77.5, 0.0)]:
        xy, depth, visible = proj.project(proj.unproject(x, y, z))
        np.testing.assert_allclose(xy[0], [x, y], atol=1e-9)
        assert depth[0] == pytest.approx(z, abs=1e-9)
        assert visible[0]


def test_a_single_point_is_accepted_as_a_row():
    proj = camera("perspective")
    xy, depth, visible = proj.project(TARGET)
    assert xy.shape == (1, 2) and depth.shape == (1,) and visible.shape == (1,)


def test_camera_target_projects_to_the_widget_centre(proj):
    xy, _, visible = proj.project(TARGET)
    assert visible[0]
    # Widget pixels count rows from the top (0 .. H - 1), device pixels from the bottom, so
    # the centre row is H / 2 - 1. The target is on the view axis: its NDC is 0 up to the
    # rounding of the view and projection products (under 20 eps), W / 2 pixels per unit.
    tol = 10 * np.finfo(np.float64).eps * W
    assert xy[0, 0] == pytest.approx(W / 2, abs=tol)
    assert xy[0, 1] == pytest.approx(H / 2 - 1, abs=tol)


def test_viewport_offset_round_trips():
    proj = camera("perspective", dpr=2.0, offset=(40.0, 30.0))
    pts = cloud(10)
    xy, depth, _ = proj.project(pts)
    back = np.array([proj.unproject(x, y, z) for (x, y), z in zip(xy, depth)])
    np.testing.assert_allclose(back, pts, atol=1e-9)


def test_widget_y_grows_downward_and_x_to_the_right(proj):
    xy, _, _ = proj.project([TARGET, TARGET + 0.5 * CAM_UP, TARGET + 0.5 * RIGHT])
    centre, above, right = xy
    assert above[1] < centre[1] - 10  # up in the world is up on screen: smaller y
    assert above[0] == pytest.approx(centre[0], abs=1e-6)
    assert right[0] > centre[0] + 10
    assert right[1] == pytest.approx(centre[1], abs=1e-6)


def test_logical_pixels_do_not_depend_on_the_device_pixel_ratio():
    pts = cloud(20)
    for kind in KINDS:
        a = camera(kind, dpr=1.0).project(pts)
        b = camera(kind, dpr=2.0).project(pts)
        np.testing.assert_allclose(b[0], a[0], atol=1e-9)
        np.testing.assert_allclose(b[1], a[1], atol=1e-12)


def test_points_behind_a_perspective_camera_are_not_visible():
    proj = camera("perspective")
    behind = [EYE - 2.0 * FORWARD, EYE - 5.0 * FORWARD + 0.3 * RIGHT]
    _, _, visible = proj.project([TARGET, *behind])
    assert visible.tolist() == [True, False, False]


def test_ray_runs_along_the_line_of_sight(proj):
    x, y = 200.0, 310.0
    origin, direction = proj.ray(x, y)
    assert np.linalg.norm(direction) == pytest.approx(1.0)
    assert direction @ FORWARD > 0  # away from the camera
    # The origin is on the near plane, and every point of the ray draws under (x, y).
    np.testing.assert_allclose(origin, proj.unproject(x, y, -1.0), atol=1e-9)
    for t in (0.5, 3.0, 8.0):
        xy, _, visible = proj.project(origin + t * direction)
        assert visible[0]
        np.testing.assert_allclose(xy[0], [x, y], atol=1e-7)


def test_orthographic_rays_are_parallel_to_the_view_direction():
    proj = camera("orthographic")
    for x, y in [(0.0, 0.0), (W / 2, H / 2), (600.0, 20.0)]:
        _, d = proj.ray(x, y)
        np.testing.assert_allclose(d, FORWARD, atol=1e-12)


# -- nearest -------------------------------------------------------------------------------
def at(proj: Projection, x: float, y: float, depth: float = 0.0) -> np.ndarray:
    """The world point drawn at widget pixel (x, y)."""
    return proj.unproject(x, y, depth)


def test_nearest_picks_within_the_radius_only(proj):
    x, y = 300.0, 200.0
    pts = [at(proj, x + PICK_RADIUS - 0.5, y), at(proj, x + 60, y + 60)]
    assert nearest(proj, pts, x, y) == 0
    assert nearest(proj, pts, x - 1.0, y) == -1  # 12.5 px away
    assert nearest(proj, pts, x + 61, y + 60) == 1
    assert nearest(proj, pts, x, y, radius=5.0) == -1
    assert nearest(proj, pts, x + PICK_RADIUS - 0.5, y + 3.0, radius=3.5) == 0


def test_nearest_picks_the_closest_on_screen(proj):
    x, y = 100.0, 400.0
    pts = [at(proj, x + 8, y), at(proj, x, y + 3), at(proj, x - 6, y - 6)]
    assert nearest(proj, pts, x, y) == 1


def test_a_visible_node_wins_over_a_hidden_one_and_placing_skips_hidden_ones(proj):
    from isochor.app.view.picking import occluded

    x, y = 250.0, 180.0
    hidden_near = at(proj, x, y, 0.6)  # right under the cursor, behind the wall
    visible_aside = at(proj, x + 8, y, -0.5)  # 8 px off, in front of the wall
    # a wall (two triangles) drawn over the cursor at depth 0.2
    corners = np.array(
        [at(proj, x + dx, y + dy, 0.2) for dx, dy in [(-5, -5), (5, -5), (5, 5), (-5, 5)]]
    )
    faces = np.array([[0, 1, 2], [0, 2, 3]])

    def hidden(points):
        return occluded(proj, points, corners, faces)

    pts = [hidden_near, visible_aside]
    assert hidden(np.array(pts)).tolist() == [True, False]
    assert nearest(proj, pts, x, y) == 0  # without the model: the nearest on screen
    assert nearest(proj, pts, x, y, hidden=hidden) == 1  # the visible one wins
    assert nearest(proj, [hidden_near], x, y, hidden=hidden) == 0  # only hidden: picked
    assert nearest(proj, [hidden_near], x, y, hidden=hidden, skip_hidden=True) == -1


def test_nearest_prefers_the_front_one_of_two_at_the_same_pixel(proj):
    x, y = 250.0, 180.0
    front, back = at(proj, x, y, -0.2), at(proj, x, y, 0.6)
    assert nearest(proj, [back, front], x, y) == 1
    assert nearest(proj, [front, back], x, y) == 0
    # About equally near (within PICK_TIE pixels): the front one still wins.
    behind_exact = at(proj, x, y, 0.6)
    front_aside = at(proj, x + PICK_TIE - 0.5, y, -0.2)
    assert nearest(proj, [behind_exact, front_aside], x, y) == 1
    # Clearly nearer on screen: the nearer wins even behind.
    front_far = at(proj, x + PICK_TIE + 4, y, -0.2)
    assert nearest(proj, [behind_exact, front_far], x, y) == 0


def test_nearest_of_no_points_is_minus_one(proj):
    assert nearest(proj, np.zeros((0, 3)), 10.0, 10.0) == -1
    assert nearest(proj, [], 10.0, 10.0) == -1


def test_nearest_ignores_points_behind_the_camera():
    proj = camera("perspective")
    behind = EYE - 3.0 * FORWARD  # projects through the eye onto the centre, mirrored
    xy, _, visible = proj.project(behind)
    assert not visible[0]
    assert nearest(proj, [behind], *xy[0]) == -1
    assert nearest(proj, [behind, TARGET], *proj.project(TARGET)[0][0]) == 1


# -- in_rect -------------------------------------------------------------------------------
def test_in_rect_selects_exactly_the_points_inside(proj):
    pts = cloud(200, seed=3)
    xy, _, _ = proj.project(pts)
    left, top, right, bottom = 150.0, 100.0, 420.0, 330.0
    inside = in_rect(proj, pts, left, top, right, bottom)
    expect = np.flatnonzero(
        (xy[:, 0] >= left) & (xy[:, 0] <= right) & (xy[:, 1] >= top) & (xy[:, 1] <= bottom)
    )
    assert 0 < len(expect) < len(pts)
    np.testing.assert_array_equal(inside, expect)


def test_in_rect_includes_the_edges_and_excludes_hidden_points():
    proj = camera("perspective")
    pts = [
        at(proj, 100.0, 50.0),
        at(proj, 200.0, 150.0),
        at(proj, 150.0, 100.0),
        at(proj, 201.0, 100.0),
        EYE - 3.0 * FORWARD,
    ]
    # A point exactly on an edge can land a hair outside after the round trip.
    got = in_rect(proj, pts, 100.0 - 1e-6, 50.0 - 1e-6, 200.0 + 1e-6, 150.0 + 1e-6)
    assert got.tolist() == [0, 1, 2]
    # The point behind the camera is not selected even by a rectangle around its image.
    xy, _, _ = proj.project(pts[4])
    x, y = xy[0]
    assert in_rect(proj, pts[4:], x - 50, y - 50, x + 50, y + 50).tolist() == []
    assert in_rect(proj, np.zeros((0, 3)), 0, 0, W, H).tolist() == []


# -- drag_delta ----------------------------------------------------------------------------
def test_drag_in_the_view_plane_keeps_the_point_under_the_cursor(proj):
    anchor = TARGET + np.array([0.3, -0.2, 0.1])
    (press,), (depth,), _ = proj.project(anchor)
    for pos in [(press[0] + 40, press[1] - 25), (10.0, 470.0), tuple(press)]:
        delta = drag_delta(proj, tuple(press), pos, anchor, depth)
        xy, d2, _ = proj.project(anchor + delta)
        np.testing.assert_allclose(xy[0], pos, atol=1e-7)
        assert d2[0] == pytest.approx(depth, abs=1e-9)
        assert delta @ FORWARD == pytest.approx(0.0, abs=1e-9)  # stays at its depth
    assert np.allclose(drag_delta(proj, tuple(press), tuple(press), anchor, depth), 0)


def test_drag_in_the_view_plane_does_not_depend_on_where_the_press_was(proj):
    anchor = TARGET.copy()
    (p,), (depth,), _ = proj.project(anchor)
    a = drag_delta(proj, (p[0], p[1]), (p[0] + 30, p[1] + 10), anchor, depth)
    b = drag_delta(proj, (p[0] + 5, p[1] - 3), (p[0] + 35, p[1] + 7), anchor, depth)
    np.testing.assert_allclose(a, b, atol=1e-9)


def closest_parameter(proj: Projection, pixel, anchor, axis) -> float:
    """t of the point of the line anchor + t axis nearest to the line of sight at pixel:
    the least-squares solution of anchor + t axis = o + s d."""
    o, d = proj.ray(*pixel)
    a = np.c_[axis, -d]
    (t, _), *_ = np.linalg.lstsq(a, o - anchor, rcond=None)
    return float(t)


@pytest.mark.parametrize(
    "axis", [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), tuple(_unit([1.0, 2.0, -0.5]))]
)
def test_drag_along_an_axis(proj, axis):
    axis = np.array(axis)
    anchor = TARGET + np.array([0.2, 0.1, -0.1])
    (press,), (depth,), _ = proj.project(anchor)
    press = tuple(press)
    # The cursor on the image of anchor + 0.7 axis: the delta is exactly 0.7 axis.
    (pos,), _, _ = proj.project(anchor + 0.7 * axis)
    delta = drag_delta(proj, press, tuple(pos), anchor, depth, axis=axis)
    np.testing.assert_allclose(delta, 0.7 * axis, atol=1e-7)
    # Anywhere else: parallel to the axis, by the closest-point construction.
    for pos in [(press[0] + 37, press[1] + 11), (5.0, 5.0), (600.0, 420.0)]:
        delta = drag_delta(proj, press, pos, anchor, depth, axis=axis)
        assert np.linalg.norm(np.cross(delta, axis)) < 1e-9
        t = closest_parameter(proj, pos, anchor, axis) - closest_parameter(
            proj, press, anchor, axis
        )
        np.testing.assert_allclose(delta, t * axis, atol=1e-7)


def test_drag_along_the_line_of_sight_is_undefined():
    proj = camera("orthographic")
    anchor = TARGET.copy()
    (press,), (depth,), _ = proj.project(anchor)
    for axis in (FORWARD, -FORWARD):
        assert (
            drag_delta(proj, tuple(press), (press[0] + 20, press[1]), anchor, depth, axis=axis)
            is None
        )
    # Perspective: the ray through the centre runs straight down the axis.
    proj = camera("perspective")
    (press,), (depth,), _ = proj.project(anchor)
    assert (
        drag_delta(proj, tuple(press), (press[0] + 20, press[1]), anchor, depth, axis=FORWARD)
        is None
    )


@pytest.mark.parametrize(
    "normal", [(0.0, 0.0, 1.0), (1.0, 0.0, 0.0), tuple(_unit([0.3, -1.0, 0.4]))]
)
def test_drag_in_a_plane_stays_in_the_plane(proj, normal):
    normal = np.array(normal)
    anchor = TARGET + np.array([-0.1, 0.2, 0.0])
    (press,), (depth,), _ = proj.project(anchor)
    press = tuple(press)
    for pos in [(press[0] + 50, press[1] - 20), (30.0, 400.0)]:
        delta = drag_delta(proj, press, pos, anchor, depth, axis=normal, plane=True)
        assert delta is not None
        assert delta @ normal == pytest.approx(0.0, abs=1e-9)
        # The grabbed point is on the plane, under the cursor.
        xy, _, _ = proj.project(anchor + delta)
        np.testing.assert_allclose(xy[0], pos, atol=1e-6)


def test_drag_in_a_plane_seen_edge_on_is_undefined():
    proj = camera("orthographic")
    anchor = TARGET.copy()
    (press,), (depth,), _ = proj.project(anchor)
    for normal in (RIGHT, CAM_UP, _unit(RIGHT + CAM_UP)):
        assert (
            drag_delta(
                proj,
                tuple(press),
                (press[0] + 20, press[1] + 5),
                anchor,
                depth,
                axis=normal,
                plane=True,
            )
            is None
        )


def test_picking_imports_no_qt():
    """The module and its maths run in a fresh interpreter without Qt or VTK."""
    code = (
        "import isochor.app.view.picking as p\n"
        "import numpy as np\n"
        "proj = p.Projection(np.eye(4), (0, 0, 100, 100), 100.0)\n"
        "assert p.nearest(proj, [[0, 0, 0]], 50, 49) == 0\n"
    )
    out, gui = run_fresh(code, cwd=ROOT, timeout=60)
    assert out.returncode == 0, out.stderr
    assert gui == []
