"""Open3D hand-off (issue 15): OUTPUT.intrinsics.json is an Open3D PinholeCameraIntrinsic, its
back-projection of an output frame equals upsr's (PLY included) within 0.01 mm, and the colour
resampled to the output grid makes an RGB-D image, a point cloud and a TSDF volume."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import upsr.io as uio
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.intrinsics import write_intrinsics
from upsr.io.pointcloud import backproject, write_ply

o3d = pytest.importorskip("open3d")
cv2 = pytest.importorskip("cv2")


def _output(tmp_path: Path) -> tuple[Path, PinholeCamera, PinholeCamera]:
    src = PinholeCamera(50.5, 51.25, 31.7, 23.2, 64, 48)
    cam = src.scaled(2)
    y, x = np.mgrid[0:96, 0:128]
    depth = (900.0 + 7.0 * x + 3.0 * y).astype(np.float32)
    depth[40:50, 60:80] = 0
    out = uio.write_video(tmp_path / "sr", depth[None], frame_names=["1305031102.175304"])
    write_intrinsics(uio.intrinsics_path(out), cam, source=src, scale=2, timestamps_ns=[7])
    return out, cam, src


def test_open3d_reads_intrinsics_and_backprojects_like_upsr(tmp_path: Path) -> None:
    out, cam, _ = _output(tmp_path)
    intr = o3d.io.read_pinhole_camera_intrinsic(str(uio.intrinsics_path(out)))
    assert (intr.width, intr.height) == (cam.width, cam.height)
    np.testing.assert_allclose(np.asarray(intr.intrinsic_matrix), cam.K)
    frame = out / "1305031102.175304.png"
    depth_o3d = o3d.io.read_image(str(frame))
    pcd = o3d.geometry.PointCloud.create_from_depth_image(
        depth_o3d, intr, depth_scale=1000.0, depth_trunc=1000.0
    )
    ours, _ = backproject(uio.read_video(out)[0], cam)
    theirs = np.asarray(pcd.points)
    assert theirs.shape == ours.shape
    np.testing.assert_allclose(theirs, ours, atol=1e-5)  # 0.01 mm
    ply = write_ply(tmp_path / "sr.ply", uio.read_video(out)[0], cam)
    np.testing.assert_allclose(
        np.asarray(o3d.io.read_point_cloud(str(ply)).points), theirs, atol=1e-5
    )


def test_open3d_rgbd_recipe(tmp_path: Path) -> None:
    """The README recipe: colour on the output grid, RGB-D image, point cloud, TSDF."""
    out, cam, _ = _output(tmp_path)
    colour_in = tmp_path / "rgb"
    colour_in.mkdir()
    cv2.imwrite(str(colour_in / "1305031102.175304.png"), np.full((48, 64, 3), 90, np.uint8))
    colour = uio.write_color(colour_in, tmp_path / "sr.color", (cam.height, cam.width), n_frames=1)
    intr = o3d.io.read_pinhole_camera_intrinsic(str(uio.intrinsics_path(out)))
    rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
        o3d.io.read_image(str(colour / "1305031102.175304.png")),
        o3d.io.read_image(str(out / "1305031102.175304.png")),
        depth_scale=1000.0,
        depth_trunc=10.0,
        convert_rgb_to_intensity=False,
    )
    pcd = o3d.geometry.PointCloud.create_from_rgbd_image(rgbd, intr)
    assert len(pcd.points) == int((uio.read_video(out)[0] > 0).sum())
    volume = o3d.pipelines.integration.UniformTSDFVolume(
        length=4.0,
        resolution=128,
        sdf_trunc=0.1,
        color_type=o3d.pipelines.integration.TSDFVolumeColorType.RGB8,
    )
    volume.integrate(rgbd, intr, np.eye(4))
    assert len(volume.extract_point_cloud().points) > 0
