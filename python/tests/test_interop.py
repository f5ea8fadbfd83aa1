"""sage3d's files read by independent, widely used readers (plyfile, json, numpy, and
PlayCanvas splat-transform under Node where `scripts/test` installed it)."""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import plyfile
import pytest
from PIL import Image

from conftest import TESTDATA

SH_C0 = 0.28209479177387814


def vertex_table(path):
    return plyfile.PlyData.read(str(path))["vertex"].data


def test_convert_compressed_to_standard_matches_splat_transform(sage3d, tmp_path):
    """Our decoding, written as a standard PLY and read by plyfile, equals the tool's decoding."""
    for stem in ["random_4k_sh3", "random_3k_sh0"]:
        out = tmp_path / f"{stem}.ply"
        sage3d("splat", "convert", TESTDATA / f"{stem}.compressed.ply", out)
        ours = vertex_table(out)
        tool = vertex_table(TESTDATA / f"{stem}.decompressed.ply")
        assert len(ours) == len(tool)
        for name in ["x", "y", "z"]:
            np.testing.assert_allclose(ours[name], tool[name], atol=1e-4, err_msg=name)
        # sage3d keeps log-scales in steps of 1/2048 (docs/scene-format.md): half a step more.
        for name in ["scale_0", "scale_1", "scale_2"]:
            np.testing.assert_allclose(ours[name], tool[name], atol=1e-4 + 1 / 4096, err_msg=name)
        for name in ["f_dc_0", "f_dc_1", "f_dc_2"]:
            np.testing.assert_allclose(ours[name], tool[name], atol=2e-3, err_msg=name)
        alpha = lambda logit: 1.0 / (1.0 + np.exp(-np.clip(logit, -30, 30)))
        np.testing.assert_allclose(alpha(ours["opacity"]), alpha(tool["opacity"]), atol=1 / 255)
        q_ours = np.stack([ours[f"rot_{i}"] for i in range(4)], axis=1)
        q_tool = np.stack([tool[f"rot_{i}"] for i in range(4)], axis=1)
        q_tool /= np.linalg.norm(q_tool, axis=1, keepdims=True)
        assert np.all(np.abs(np.sum(q_ours * q_tool, axis=1)) > 1 - 1e-4)
        rest = [n for n in tool.dtype.names if n.startswith("f_rest_")]
        assert len(rest) == len([n for n in ours.dtype.names if n.startswith("f_rest_")])
        if rest:
            a = np.stack([ours[n] for n in rest], axis=1)
            b = np.stack([tool[n] for n in rest], axis=1)
            tol = np.abs(b).max(axis=1, keepdims=True) / 127 + 1e-5
            assert np.all(np.abs(a - b) <= tol)


def test_convert_standard_to_compressed_chunks_along_a_z_curve(sage3d, tmp_path):
    """The tool's random scene is in no spatial order (as a trained PLY is): written compressed,
    its Gaussians are reordered so that each chunk of 256 is compact, as splat-transform's own
    writer does, and every Gaussian comes back once, within a step of its chunk's bounds."""
    src = TESTDATA / "random_4k_sh3.ply"
    packed = tmp_path / "x.compressed.ply"
    back = tmp_path / "x.ply"
    out = sage3d("splat", "convert", src, packed)
    assert "Z-order" in out.stdout + out.stderr
    sage3d("splat", "convert", packed, back)
    a, b = vertex_table(src), vertex_table(back)
    assert len(a) == len(b)
    pa = np.stack([a["x"], a["y"], a["z"]], axis=1).astype(np.float64)
    pb = np.stack([b["x"], b["y"], b["z"]], axis=1).astype(np.float64)
    data = plyfile.PlyData.read(str(packed))
    assert [e.name for e in data.elements] == ["chunk", "vertex", "sh"]
    chunks = data["chunk"].data
    assert len(chunks) == (len(a) + 255) // 256
    assert len(data["sh"].data.dtype.names) == 45
    lo = np.stack([chunks["min_x"], chunks["min_y"], chunks["min_z"]], axis=1)
    hi = np.stack([chunks["max_x"], chunks["max_y"], chunks["max_z"]], axis=1)
    # Each Gaussian read back is the nearest source Gaussian, one for one, within half an
    # 11-10-11 bit step of its chunk's bounds (plus float rounding).
    step = np.repeat((hi - lo) / np.array([2047.0, 1023.0, 2047.0]), 256, axis=0)[: len(b)]
    nearest = np.array([np.argmin(((pa - p) ** 2).sum(axis=1)) for p in pb])
    assert len(set(nearest.tolist())) == len(a)
    assert np.all(np.abs(pb - pa[nearest]) <= step / 2 + 1e-5)
    # Compact chunks: in the source's order each would span the whole scene.
    extent = np.ptp(pa, axis=0)
    assert np.mean(hi - lo, axis=0).sum() < 0.7 * extent.sum()


def splat_attributes(path):
    """A standard PLY's Gaussians: {name: float64 array}, rotations normalised with w ≥ 0."""
    v = vertex_table(path)
    out = {n: np.asarray(v[n], dtype=np.float64) for n in v.dtype.names
           if n[0] in "xyz" or n.startswith(("scale_", "opacity", "f_dc_", "f_rest_"))}
    q = np.stack([np.asarray(v[f"rot_{i}"], dtype=np.float64) for i in range(4)], axis=1)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    out.update({f"rot_{i}": q[:, i] for i in range(4)})
    return out


def test_splat_transform_decodes_what_we_write_as_we_do(sage3d, tmp_path):
    """Each file `splat convert` writes (standard PLY, compressed PLY, SPZ), from a standard and
    an SPZ input, decoded by PlayCanvas splat-transform (2.7.1, pinned in
    python/tests/splat-transform) to a standard PLY, equals sage3d's own decoding of it: the
    same Gaussians in the same order, within 1e-5 (float rounding)."""
    cli = os.environ.get("SAGE3D_SPLAT_TRANSFORM")
    if not cli:
        pytest.skip("SAGE3D_SPLAT_TRANSFORM unset: scripts/test installs splat-transform and sets it")
    assert Path(cli).is_file(), f"SAGE3D_SPLAT_TRANSFORM={cli} is not a file"
    for source in ["random_4k_sh3.ply", "random_3k_sh0.ply", "random_4k_sh3.spz"]:
        for ext in ["ply", "compressed.ply", "spz"]:
            written = tmp_path / f"w.{ext}"
            ours, theirs = tmp_path / "ours.ply", tmp_path / "theirs.ply"
            sage3d("splat", "convert", TESTDATA / source, written, "--force")
            sage3d("splat", "convert", written, ours, "--force")
            done = subprocess.run(["node", cli, "-w", str(written), str(theirs)], capture_output=True,
                                  text=True, timeout=300)
            assert done.returncode == 0, f"{source} -> {ext}: {done.stdout}{done.stderr}"
            a, b = splat_attributes(ours), splat_attributes(theirs)
            assert sorted(a) == sorted(b), (source, ext)
            # Alpha bytes 0 and 255: splat-transform decodes their logits as ∓∞, sage3d as ∓20.
            saturated = np.abs(a["opacity"]) == 20.0
            assert (b["opacity"][saturated] == np.inf * np.sign(a["opacity"][saturated])).all() or \
                (b["opacity"][saturated] == a["opacity"][saturated]).all(), (source, ext)
            b["opacity"][saturated] = a["opacity"][saturated]
            for name in a:
                np.testing.assert_allclose(b[name], a[name], rtol=0, atol=1e-5,
                                           err_msg=f"{source} -> {ext}: {name}")


def test_synthetic_scene_files_follow_the_interiorgs_layout(small_scene):
    data = plyfile.PlyData.read(str(small_scene / "3dgs_compressed.ply"))
    n = len(data["vertex"].data)
    assert 55000 <= n <= 65000
    assert set(data["vertex"].data.dtype.names) == {"packed_position", "packed_rotation", "packed_scale", "packed_color"}
    assert len(data["sh"].data.dtype.names) >= 9
    labels = json.loads((small_scene / "labels.json").read_text())
    assert len(labels) >= 20
    for entry in labels:
        assert isinstance(entry["ins_id"], str) and entry["label"]
        corners = np.array([[c["x"], c["y"], c["z"]] for c in entry["bounding_box"]])
        assert corners.shape == (8, 3)
        assert np.allclose(corners[:4, 2], corners[0, 2])
    structure = json.loads((small_scene / "structure.json").read_text())
    assert len(structure["rooms"]) >= 4
    assert {h["type"] for h in structure["holes"]} <= {"DOOR", "WINDOW"}
    occupancy = json.loads((small_scene / "occupancy.json").read_text())
    assert occupancy["min"] == occupancy["lower"] and occupancy["scale"] > 0


def test_same_seed_same_bytes(sage3d, tmp_path):
    outs = []
    for name in ["a", "b"]:
        out = tmp_path / name
        sage3d("scene", "synth", "--seed", 11, "--out", out, "--rooms", 3, "--objects", 20, "--gaussians", 20000)
        outs.append(out)
    files = sorted(p.relative_to(outs[0]) for p in outs[0].rglob("*") if p.is_file())
    assert files
    for f in files:
        assert (outs[0] / f).read_bytes() == (outs[1] / f).read_bytes(), f


def test_info_json(sage3d, small_scene):
    info = json.loads(sage3d("scene", "info", small_scene, "--json").stdout)
    s = info["summary"]
    assert s["objects"] >= 20 and s["gaussians"] > 0 and s["sh_degree"] >= 1
    assert s["bytes_per_gaussian"] < 100
    assert "labels.json" in info["files"]


def test_bad_input_names_the_file(sage3d, tmp_path):
    bad = tmp_path / "broken.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\nend_header\n\0\0")
    proc = sage3d("splat", "convert", bad, tmp_path / "out.ply", check=False)
    assert proc.returncode != 0
    assert "broken.ply" in proc.stderr and "vertex" in proc.stderr
    assert not (tmp_path / "out.ply").exists()


def test_render_outputs_read_with_numpy(sage3d, small_scene, tmp_path):
    out = tmp_path / "render"
    sage3d("render", small_scene, "--out", out, "--width", 64, "--height", 48, "--yaw", 30, "--pitch=-10")
    depth = np.load(out / "depth.npy")
    median = np.load(out / "depth_median.npy")
    alpha = np.load(out / "alpha.npy")
    assert depth.shape == (48, 64) and depth.dtype == np.float32
    assert median.shape == alpha.shape == (48, 64)
    inside = alpha > 0.5
    assert inside.mean() > 0.9, "a camera inside a room sees surfaces everywhere"
    assert np.all((depth[inside] > 0.1) & (depth[inside] < 30.0))
    # depth.png holds the same expected depth in millimetres (16-bit grey).
    png = Image.open(out / "depth.png")
    assert png.size == (64, 48) and png.mode.startswith("I")
    mm = np.array(png).astype(np.float64)
    np.testing.assert_allclose(mm, np.clip(np.round(depth * 1000), 0, 65535), atol=1)
    rgb = np.array(Image.open(out / "rgb.png"))
    assert rgb.shape == (48, 64, 3) and rgb.dtype == np.uint8
    legend = json.loads((out / "legend.json").read_text())
    instance = np.array(Image.open(out / "instance.png"))
    colours = {tuple(e["color"]) for e in legend["instances"]}
    assert {tuple(c) for c in instance.reshape(-1, 3)} <= colours
