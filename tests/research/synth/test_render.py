"""Tests of the OBJ reader and the depth rasteriser on procedural meshes (no shared data)."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.research.synth.mesh import load_obj, parse_obj
from upsr.research.synth.render import (
    PinholeCamera,
    fit_camera_to_bounds,
    look_at,
    mesh_bounds,
    render_depth,
    render_mesh_sequence,
    samba_camera_and_pose,
)

# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------


def _plane_quad(camera: PinholeCamera, normal, offset_mm, pad: float = 0.1):
    """Two triangles (camera frame, metres) covering the whole image on the plane n·X = d (mm).

    The quad's corners are the intersections of the plane with the rays through points ``pad``
    image sizes beyond the image corners, so every pixel centre is inside.
    """
    n = np.asarray(normal, dtype=np.float64)
    us = np.array([-pad * camera.width, (1 + pad) * camera.width])
    vs = np.array([-pad * camera.height, (1 + pad) * camera.height])
    corners = []
    for u, v in [(us[0], vs[0]), (us[1], vs[0]), (us[1], vs[1]), (us[0], vs[1])]:
        ray = np.array([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0])
        z = offset_mm / (n @ ray)
        assert z > 0
        corners.append(ray * z / 1000.0)
    return np.array(corners), np.array([[0, 1, 2], [0, 2, 3]])


def _plane_depth(camera: PinholeCamera, normal, offset_mm, us, vs):
    """Analytic depth (mm) of the plane n·X = d at image coordinates (us, vs)."""
    n = np.asarray(normal, dtype=np.float64)
    rx = (us - camera.cx) / camera.fx
    ry = (vs - camera.cy) / camera.fy
    return offset_mm / (n[0] * rx + n[1] * ry + n[2])


def _uv_sphere(centre, radius, n_lat=40, n_lon=80):
    """Closed triangulated sphere (metres)."""
    theta = np.linspace(0, np.pi, n_lat + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    tt, pp = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(tt) * np.cos(pp), np.cos(tt), np.sin(tt) * np.sin(pp)], -1)
    verts = np.concatenate([[[0, 1, 0]], ring.reshape(-1, 3), [[0, -1, 0]]])
    verts = verts * radius + np.asarray(centre)
    faces = []
    rows = n_lat - 1
    for k in range(n_lon):
        k2 = (k + 1) % n_lon
        faces.append([0, 1 + k, 1 + k2])
        last = 1 + (rows - 1) * n_lon
        faces.append([len(verts) - 1, last + k2, last + k])
        for r in range(rows - 1):
            a, b = 1 + r * n_lon + k, 1 + r * n_lon + k2
            c, d = a + n_lon, b + n_lon
            faces += [[a, c, b], [b, c, d]]
    return verts, np.array(faces)


SLANT_NORMAL = (0.35, -0.5, 1.0)  # strongly slanted: depth varies by a factor > 2 over the image
SLANT_OFFSET_MM = 2500.0


# --------------------------------------------------------------------------------------------
# camera
# --------------------------------------------------------------------------------------------


def test_from_fov_principal_point_and_focal():
    cam = PinholeCamera.from_fov(640, 480, 90.0)
    assert cam.cx == pytest.approx(319.5) and cam.cy == pytest.approx(239.5)
    assert cam.fx == pytest.approx(320.0) and cam.fy == pytest.approx(320.0)
    assert cam.shape == (480, 640)
    np.testing.assert_allclose(cam.K, [[320, 0, 319.5], [0, 320, 239.5], [0, 0, 1]])


def test_scaled_follows_pixel_geometry():
    lr = PinholeCamera(200.0, 210.0, 120.3, 70.7, 256, 147)
    hr = lr.scaled(4)
    assert (hr.width, hr.height) == (1024, 588)
    assert hr.fx == pytest.approx(800.0) and hr.fy == pytest.approx(840.0)
    assert hr.cx == pytest.approx(4 * (120.3 + 0.5) - 0.5)
    assert hr.cy == pytest.approx(4 * (70.7 + 0.5) - 0.5)
    back = hr.scaled(0.25)
    for name in ("fx", "fy", "cx", "cy"):
        assert getattr(back, name) == pytest.approx(getattr(lr, name))
    assert back.shape == lr.shape
    # A 3-D point seen at low-res coordinate u is seen at high-res (u + 0.5)·r − 0.5.
    x, y, z = 0.31, -0.2, 2.7
    u_lr, v_lr = lr.fx * x / z + lr.cx, lr.fy * y / z + lr.cy
    u_hr, v_hr = hr.fx * x / z + hr.cx, hr.fy * y / z + hr.cy
    assert u_hr == pytest.approx((u_lr + 0.5) * 4 - 0.5)
    assert v_hr == pytest.approx((v_lr + 0.5) * 4 - 0.5)
    # Same field of view: from_fov commutes with scaling.
    a = PinholeCamera.from_fov(256, 147, 60.0).scaled(4)
    b = PinholeCamera.from_fov(1024, 588, 60.0)
    for name in ("fx", "fy", "cx", "cy"):
        assert getattr(a, name) == pytest.approx(getattr(b, name))


@pytest.mark.parametrize("factor", [0.3, 1 / 3, -1.0, 0.0])
def test_scaled_rejects_fractional_sizes(factor):
    cam = PinholeCamera.from_fov(1024, 588, 60.0)
    with pytest.raises(InputError):
        cam.scaled(factor)


def test_camera_validation():
    with pytest.raises(InputError):
        PinholeCamera(0.0, 1.0, 0.0, 0.0, 10, 10)
    with pytest.raises(InputError):
        PinholeCamera(1.0, 1.0, 0.0, 0.0, 10, 0)
    with pytest.raises(InputError):
        PinholeCamera.from_fov(10, 10, 180.0)


# --------------------------------------------------------------------------------------------
# rasteriser
# --------------------------------------------------------------------------------------------


def test_fronto_parallel_square_exact_depth_and_coverage():
    cam = PinholeCamera.from_fov(64, 48, 50.0)
    half_x, half_y, z_m = 0.5, 0.3, 2.0
    verts = np.array(
        [
            [-half_x, -half_y, z_m],
            [half_x, -half_y, z_m],
            [half_x, half_y, z_m],
            [-half_x, half_y, z_m],
        ]
    )
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    depth = render_depth(verts, faces, cam)
    assert depth.dtype == np.float32 and depth.shape == (48, 64)
    xs = (np.arange(64) - cam.cx) / cam.fx * z_m
    ys = (np.arange(48) - cam.cy) / cam.fy * z_m
    # No pixel centre lies on the square's border: coverage is unambiguous.
    assert np.min(np.abs(np.abs(xs) - half_x)) > 1e-3
    assert np.min(np.abs(np.abs(ys) - half_y)) > 1e-3
    inside = (np.abs(ys)[:, None] < half_y) & (np.abs(xs)[None, :] < half_x)
    assert inside.sum() > 100 and (~inside).sum() > 100
    assert np.all(depth[inside] == 2000.0)
    assert np.all(depth[~inside] == 0.0)


def test_shared_edge_through_pixel_centres_has_no_crack():
    # The diagonal of the square passes exactly through pixel centres.
    cam = PinholeCamera(10.0, 10.0, 10.0, 10.0, 21, 21)
    verts = np.array(
        [[-0.55, -0.55, 1.0], [0.55, -0.55, 1.0], [0.55, 0.55, 1.0], [-0.55, 0.55, 1.0]]
    )
    for faces in ([[0, 1, 2], [0, 2, 3]], [[0, 2, 1], [3, 2, 0]]):
        depth = render_depth(verts, np.array(faces), cam)
        assert np.all(depth[5:16, 5:16] == 1000.0)
        assert (depth > 0).sum() == 11 * 11


def test_top_left_rule_on_grid_through_pixel_centres():
    # Vertices project exactly onto pixel centres (dyadic coordinates), every cell is split
    # along a random diagonal, so many edges pass through pixel centres: each centre of the
    # half-open square [0, 16)² must be covered (no crack), none outside.
    rng = np.random.default_rng(0)
    cam = PinholeCamera(16.0, 16.0, 8.0, 8.0, 20, 20)
    uu, vv = np.meshgrid(np.arange(17.0), np.arange(17.0))
    verts = np.stack([(uu - 8) / 16, (vv - 8) / 16, np.ones_like(uu)], -1).reshape(-1, 3)
    faces = []
    for i in range(16):
        for j in range(16):
            a, b, c, d = i * 17 + j, i * 17 + j + 1, (i + 1) * 17 + j, (i + 1) * 17 + j + 1
            tris = [[a, b, d], [a, d, c]] if rng.random() < 0.5 else [[a, b, c], [b, d, c]]
            faces += [t[::-1] if rng.random() < 0.5 else t for t in tris]
    depth = render_depth(verts, np.array(faces), cam)
    expected = np.zeros((20, 20), dtype=bool)
    expected[:16, :16] = True
    np.testing.assert_array_equal(depth > 0, expected)
    assert np.all(depth[expected] == 1000.0)


def test_slanted_plane_is_perspective_correct():
    cam = PinholeCamera.from_fov(96, 64, 70.0)
    verts, faces = _plane_quad(cam, SLANT_NORMAL, SLANT_OFFSET_MM)
    depth = render_depth(verts, faces, cam)
    jj, ii = np.meshgrid(np.arange(cam.width), np.arange(cam.height))
    truth = _plane_depth(cam, SLANT_NORMAL, SLANT_OFFSET_MM, jj, ii)
    assert truth.max() / truth.min() > 2
    np.testing.assert_allclose(depth, truth, rtol=1e-6)
    # The same plane rendered from a moved camera (pose given as (R, t) and as 4×4).
    pose = look_at((0.2, -0.1, -0.3), (0.0, 0.0, 2.0), up=(0.0, -1.0, 0.0))
    rot, t = pose[:3, :3], pose[:3, 3]
    world_verts = (verts - t) @ rot  # inverse transform: these map back to ``verts``
    np.testing.assert_allclose(
        render_depth(world_verts, faces, cam, world_to_camera=(rot, t)), depth, rtol=1e-6
    )
    np.testing.assert_allclose(
        render_depth(world_verts, faces, cam, world_to_camera=pose), depth, rtol=1e-6
    )


@pytest.mark.parametrize("flip", [False, True])
def test_zbuffer_nearest_surface_wins(flip):
    cam = PinholeCamera(40.0, 40.0, 15.5, 15.5, 32, 32)
    near = [[-0.5, -0.5, 1.0], [0.3, -0.5, 1.0], [-0.5, 0.3, 1.0]]  # at 1 m, upper left
    far = [[-0.9, 0.9, 2.0], [0.9, 0.9, 2.0], [0.0, -0.9, 2.0]]  # at 2 m, bigger, central
    verts = np.array(near + far)
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    if flip:
        faces = faces[::-1].copy()
    depth = render_depth(verts, faces, cam)
    # Masks of each triangle rendered alone.
    m_near = render_depth(verts, faces[[0 if not flip else 1]], cam) > 0
    m_far = render_depth(verts, faces[[1 if not flip else 0]], cam) > 0
    both = m_near & m_far
    assert both.sum() > 20 and (m_far & ~m_near).sum() > 20
    assert np.all(depth[m_near] == 1000.0)
    assert np.all(depth[m_far & ~m_near] == 2000.0)
    assert np.all(depth[~m_near & ~m_far] == 0.0)


def test_background_plane_behind_mesh():
    cam = PinholeCamera(40.0, 40.0, 15.5, 15.5, 32, 32)
    verts = np.array(
        [
            [-0.2, -0.2, 1.0],
            [0.2, -0.2, 1.0],
            [0.0, 0.2, 1.0],
            [-5, -5, 6.0],
            [5, -5, 6.0],
            [0, 5, 6.0],
        ]
    )
    tri = np.array([[0, 1, 2]])
    mask = render_depth(verts, tri, cam) > 0
    depth = render_depth(verts, tri, cam, background_mm=3000.0)
    assert np.all(depth[mask] == 1000.0) and np.all(depth[~mask] == 3000.0)
    # A triangle behind the wall is hidden.
    hidden = render_depth(verts, np.array([[3, 4, 5]]), cam, background_mm=3000.0)
    assert np.all(hidden == 3000.0)
    # A tilted wall given as (normal, offset) in camera coordinates (mm).
    wall = render_depth(verts, tri, cam, background_mm=(SLANT_NORMAL, SLANT_OFFSET_MM))
    jj, ii = np.meshgrid(np.arange(32), np.arange(32))
    truth = _plane_depth(cam, SLANT_NORMAL, SLANT_OFFSET_MM, jj, ii)
    np.testing.assert_allclose(wall[~mask], truth[~mask], rtol=1e-6)
    assert np.all(wall[mask] == 1000.0)


def test_triangle_crossing_near_plane_is_clipped():
    # A floor Y = +1 m (camera y points down) from 5 m behind to 30 m in front of the camera.
    cam = PinholeCamera(50.0, 50.0, 31.5, 23.5, 64, 48)
    verts = np.array([[-100.0, 1.0, -5.0], [100.0, 1.0, -5.0], [0.0, 1.0, 30.0]])
    depth = render_depth(verts, np.array([[0, 1, 2]]), cam)
    jj, ii = np.meshgrid(np.arange(64), np.arange(48))
    truth = _plane_depth(cam, (0.0, 1.0, 0.0), 1000.0, jj, ii)
    rows_below = ii > cam.cy
    assert np.all(depth[~rows_below] == 0)
    sure = rows_below & (truth < 20000.0)
    assert sure.sum() > 500
    np.testing.assert_allclose(depth[sure], truth[sure], rtol=1e-6)


def test_scaled_camera_samples_highres_geometry():
    r = 4
    hr = PinholeCamera.from_fov(96, 72, 65.0)
    lr = hr.scaled(1 / r)
    assert lr.shape == (18, 24)
    verts, faces = _plane_quad(lr, SLANT_NORMAL, SLANT_OFFSET_MM)
    depth_lr = render_depth(verts, faces, lr)
    ii, jj = np.meshgrid(np.arange(lr.height), np.arange(lr.width), indexing="ij")
    truth = _plane_depth(
        hr, SLANT_NORMAL, SLANT_OFFSET_MM, (jj + 0.5) * r - 0.5, (ii + 0.5) * r - 0.5
    )
    np.testing.assert_allclose(depth_lr, truth, rtol=1e-6)


def test_odd_scale_lowres_equals_highres_subsampling_on_curved_mesh():
    # For odd r the low-res pixel centre (i+0.5)·r−0.5 = r·i + (r−1)/2 is a high-res centre.
    r = 3
    hr = PinholeCamera.from_fov(90, 60, 55.0)
    lr = hr.scaled(1 / r)
    verts, faces = _uv_sphere((0.05, -0.02, 1.5), 0.45)
    depth_hr = render_depth(verts, faces, hr)
    depth_lr = render_depth(verts, faces, lr)
    assert (depth_lr > 0).sum() > 100 and (depth_lr == 0).sum() > 50
    np.testing.assert_allclose(depth_lr, depth_hr[1::r, 1::r], rtol=1e-6, atol=0)
    valid = depth_hr > 0
    assert 1050.0 < depth_hr[valid].min() and depth_hr[valid].max() < 1950.0


def test_render_input_validation():
    cam = PinholeCamera.from_fov(8, 8, 60.0)
    verts = np.zeros((3, 3))
    with pytest.raises(InputError):
        render_depth(verts, np.array([[0, 1, 3]]), cam)
    with pytest.raises(InputError):
        render_depth(np.zeros((3, 2)), np.array([[0, 1, 2]]), cam)
    with pytest.raises(InputError):
        render_depth(verts, np.array([[0.0, 1.0, 2.0]]), cam)
    with pytest.raises(InputError):
        render_depth(verts, np.array([[0, 1, 2]]), cam, world_to_camera=np.eye(3))
    with pytest.raises(InputError):
        render_depth(verts, np.array([[0, 1, 2]]), cam, background_mm=-1.0)
    empty = render_depth(verts, np.zeros((0, 3), dtype=np.int32), cam)
    assert empty.shape == (8, 8) and not empty.any()


# --------------------------------------------------------------------------------------------
# poses and camera placement
# --------------------------------------------------------------------------------------------


def test_look_at_is_a_right_handed_opencv_frame():
    pose = look_at((0.0, 1.0, 5.0), (0.0, 1.0, 0.0), up=(0.0, 1.0, 0.0))
    rot, t = pose[:3, :3], pose[:3, 3]
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(rot) == pytest.approx(1.0)
    np.testing.assert_allclose(rot @ np.array([0.0, 1.0, 0.0]) + t, [0, 0, 5], atol=1e-12)
    assert (rot @ np.array([0.0, 1.0, 0.0]))[1] < 0  # world up is image up (y down)
    assert (rot @ np.array([1.0, 0.0, 0.0]))[0] > 0  # looking along −Z, +X is to the right


def test_fit_camera_to_bounds_frames_the_box():
    lo, hi = np.array([-0.3, 0.0, -0.2]), np.array([0.4, 1.8, 0.3])
    cam, pose = fit_camera_to_bounds(
        lo, hi, width=128, height=72, fov_x_deg=60.0, view_dir=(-1.0, 0.0, 0.0), margin=0.1
    )
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    pc = corners @ pose[:3, :3].T + pose[:3, 3]
    assert np.all(pc[:, 2] > 0)
    u = cam.fx * pc[:, 0] / pc[:, 2] + cam.cx
    v = cam.fy * pc[:, 1] / pc[:, 2] + cam.cy
    assert u.min() >= 0 and u.max() <= 127 and v.min() >= 0 and v.max() <= 71
    # Tight: the extreme corner touches the margin (vertical is the binding direction).
    v_free = 0.1 * (cam.height / 2 - 0.5)
    assert min(v.min(), 71 - v.max()) == pytest.approx(v_free, abs=1e-6)


def test_samba_camera_default_size():
    cam, pose = samba_camera_and_pose()
    assert cam.shape == (588, 1024)
    assert cam.scaled(1 / 4).shape == (147, 256)
    assert pose.shape == (4, 4)


# --------------------------------------------------------------------------------------------
# OBJ reading
# --------------------------------------------------------------------------------------------

OBJ_TEXT = """\
# a small test file
mtllib nothing.mtl
o thing
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0 1.0
vt 0 0
vt 1 0
vn 0 0 1
g faces
usemtl none
s off
f 1/1/1 2/2/1 3/1/1
f 1//1 3//1 4//1
f 1 2 3 4
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
v 0.5 0.5 1.5
f -5 -4 -3 -2 -1
  f 5/1 6/2 7/1
"""


def test_parse_obj_forms(tmp_path):
    path = tmp_path / "m.obj"
    path.write_text(OBJ_TEXT)
    verts, faces = load_obj(path)
    assert verts.dtype == np.float32 and verts.shape == (9, 3)
    assert faces.dtype == np.int32
    np.testing.assert_array_equal(verts[3], [0, 1, 0])
    expected = [
        [0, 1, 2],
        [0, 2, 3],
        [0, 1, 2],
        [0, 2, 3],  # quad fan
        [4, 5, 6],
        [4, 6, 7],
        [4, 7, 8],  # pentagon with negative indices
        [4, 5, 6],
    ]
    np.testing.assert_array_equal(faces, expected)


def test_load_obj_then_render(tmp_path):
    path = tmp_path / "square.obj"
    path.write_text("v -1 -1 2\nv 1 -1 2\nv 1 1 2\nv -1 1 2\nf 1 2 3 4\n")
    verts, faces = load_obj(path)
    cam = PinholeCamera.from_fov(8, 6, 60.0)
    depth = render_depth(verts, faces, cam)
    assert np.all(depth[:, 1:-1] == 2000.0) and np.all(depth[:, [0, -1]] == 0.0)
    seq = render_mesh_sequence([path, str(path)], cam)
    assert seq.shape == (2, 6, 8) and seq.dtype == np.float32
    np.testing.assert_array_equal(seq[1], depth)
    lo, hi = mesh_bounds([path])
    np.testing.assert_array_equal(lo, [-1, -1, 2])
    np.testing.assert_array_equal(hi, [1, 1, 2])


def test_obj_without_faces():
    verts, faces = parse_obj("v 1 2 3\n")
    assert verts.shape == (1, 3) and faces.shape == (0, 3)


@pytest.mark.parametrize(
    "text",
    [
        "",
        "# only a comment\nvn 0 0 1\n",
        "v 1 2\n",
        "v 1 2 x\n",
        "v 1 2 nan\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 a 2\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1.5 2 3\n",
        "v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n",  # relative index before definition
    ],
)
def test_malformed_obj_raises(tmp_path, text):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(InputError):
        load_obj(path)


def test_unreadable_obj_raises(tmp_path):
    with pytest.raises(InputError):
        load_obj(tmp_path / "missing.obj")
    binary = tmp_path / "binary.obj"
    binary.write_bytes(b"v 0 0 0\x00\x01\x02")
    with pytest.raises(InputError):
        load_obj(binary)
