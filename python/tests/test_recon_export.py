"""`sage3d recon export` read the way nerfstudio's dataparser reads transforms.json: OpenGL
camera-to-world matrices (x right, y up, z back), shared OPENCV intrinsics. A world point
projected with numpy must land where `sage3d recon project` (our cameras, OpenCV axes) says,
and the images and depth maps must be where the frames say, at the stated size."""

import json

import numpy as np
import pytest
from PIL import Image
from plyfile import PlyData


@pytest.fixture(scope="module")
def recon(tmp_path_factory, sage3d):
    root = tmp_path_factory.mktemp("recon")
    scene = root / "scene"
    sage3d("scene", "synth", "--seed", 5, "--out", scene, "--rooms", 2, "--objects", 15, "--gaussians", 1000)
    out = root / "recon"
    sage3d("recon", "plan", scene, "--policy", "volume", "--budget", 60, "--seed", 1, "--out", out)
    # A handful of views keeps the debug render quick.
    plan = json.loads((out / "plan.json").read_text())
    plan["views"] = plan["views"][:10]
    (out / "plan.json").write_text(json.dumps(plan))
    sage3d("recon", "render", out, "--size", "40x30")
    sage3d("recon", "export", out, "--points", 400)
    return out, plan


def nerfstudio_project(meta, frame, point):
    """Pixel (u, v) and depth of a world point, as a nerfstudio camera sees it."""
    c2w = np.array(frame["transform_matrix"], dtype=np.float64)
    assert c2w.shape == (4, 4)
    np.testing.assert_allclose(c2w[3], [0, 0, 0, 1])
    rot = c2w[:3, :3]
    np.testing.assert_allclose(rot.T @ rot, np.eye(3), atol=1e-5)
    assert np.linalg.det(rot) == pytest.approx(1.0, abs=1e-5)
    p = rot.T @ (np.asarray(point, dtype=np.float64) - c2w[:3, 3])
    depth = -p[2]  # the camera looks down its -z axis
    u = meta["fl_x"] * p[0] / depth + meta["cx"]
    v = meta["fl_y"] * -p[1] / depth + meta["cy"]
    return u, v, depth


def test_projection_matches_our_cameras(recon, sage3d):
    out, plan = recon
    meta = json.loads((out / "transforms.json").read_text())
    assert meta["camera_model"] == "OPENCV" and (meta["w"], meta["h"]) == (40, 30)
    frames = {f["file_path"]: f for f in meta["frames"]}
    # A point 1.5 m ahead of the first view, off its axis.
    v0 = plan["views"][0]
    yaw, pitch = np.radians(v0["yaw_deg"]), np.radians(v0["pitch_deg"])
    forward = np.array([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), np.sin(pitch)])
    point = np.array(v0["position"]) + 1.5 * forward + np.array([0.1, -0.05, 0.08])
    proc = sage3d("recon", "project", out, "--point", ",".join(f"{x:.6f}" for x in point))
    hits = [json.loads(line) for line in proc.stdout.splitlines()]
    assert any(h["view"] == 0 for h in hits)
    for h in hits:
        u, v, depth = nerfstudio_project(meta, frames[h["file_path"]], point)
        assert u == pytest.approx(h["u"], abs=2e-3)
        assert v == pytest.approx(h["v"], abs=2e-3)
        assert depth == pytest.approx(h["depth"], abs=1e-4)


def test_frames_images_depth_and_split(recon):
    out, plan = recon
    meta = json.loads((out / "transforms.json").read_text())
    assert len(meta["frames"]) == len(plan["views"]) == 10
    for i, f in enumerate(meta["frames"]):
        rgb = np.asarray(Image.open(out / f["file_path"]))
        assert rgb.shape == (30, 40, 3) and rgb.dtype == np.uint8
        depth = np.asarray(Image.open(out / f["depth_file_path"]))
        assert depth.shape == (30, 40)
        # Millimetres: inside a room, everything hit is within 20 m and most pixels hit.
        assert depth.max() < 20000 and (depth > 0).mean() > 0.5
        # The camera centre is the plan's position.
        np.testing.assert_allclose(np.array(f["transform_matrix"])[:3, 3], plan["views"][i]["position"], atol=1e-6)
    held = [f["file_path"] for i, f in enumerate(meta["frames"]) if i % 8 == 0]
    assert meta["val_filenames"] == held == meta["test_filenames"]
    assert sorted(meta["train_filenames"] + held) == sorted(f["file_path"] for f in meta["frames"])


def test_point_cloud_for_splatfacto(recon):
    out, plan = recon
    meta = json.loads((out / "transforms.json").read_text())
    vertex = PlyData.read(str(out / meta["ply_file_path"]))["vertex"]
    assert vertex.count == 400
    xyz = np.stack([vertex["x"], vertex["y"], vertex["z"]], axis=1)
    rgb = np.stack([vertex["red"], vertex["green"], vertex["blue"]], axis=1)
    assert rgb.dtype == np.uint8 and rgb.max() > 0
    # On the scene's surfaces, area-weighted: between the floor and the ceiling (2.8 m), with
    # floor and ceiling both well represented (walls take the largest share).
    z = xyz[:, 2]
    assert z.min() >= -1e-4 and z.max() <= 2.8 + 1e-4
    assert (z < 1e-3).mean() > 0.05 and (z > 2.8 - 1e-3).mean() > 0.05
