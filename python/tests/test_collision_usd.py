"""Published collision files (SAGE-Bench's `{scene}_collision.usd`) authored with Pixar's USD in
the published layout — binary `.usd`, nested transforms, several convex parts per object, parts
for walls and floor, both naming styles, the template's 180° frame — read through the CLI: the
bodies land on the right objects in W, the frame is decided from the data, the rest is
structure; damaged files give an error naming the file and the prim."""

import json
import math
import shutil
import struct
import zipfile

import pytest

pxr = pytest.importorskip("pxr", reason="usd-core is installed by scripts/test")
from pxr import Gf, Usd, UsdGeom, Vt  # noqa: E402

# A coarse V-HACD: objects here all get published parts, so nothing is decomposed anyway.
FAST = ["--resolution", 24]

# The 12 triangles of the cube with corners (±1, ±1, ±1), corner k = (x: bit 0, y: bit 1, z: bit 2).
CUBE_TRIANGLES = [
    (0, 2, 1), (1, 2, 3), (4, 5, 6), (5, 7, 6), (0, 1, 4), (1, 5, 4),
    (2, 6, 3), (3, 6, 7), (0, 4, 2), (2, 4, 6), (1, 3, 5), (3, 7, 5),
]


def cube_points(lo, hi):
    return [
        (hi[0] if k & 1 else lo[0], hi[1] if k & 2 else lo[1], hi[2] if k & 4 else lo[2])
        for k in range(8)
    ]


def define_cube(stage, path, lo=(-1, -1, -1), hi=(1, 1, 1), bad_index=False):
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in cube_points(lo, hi)]))
    mesh.CreateFaceVertexCountsAttr([3] * len(CUBE_TRIANGLES))
    indices = [i for t in CUBE_TRIANGLES for i in t]
    if bad_index:
        indices[4] = 99
    mesh.CreateFaceVertexIndicesAttr(indices)
    return mesh


def boxes(scene_dir):
    """The label boxes: ins_id -> (centre, half extents, yaw in radians), read from the corners
    as sage3d reads them (corners 0-3 one horizontal face in order)."""
    out = {}
    for entry in json.loads((scene_dir / "labels.json").read_text()):
        c = [(p["x"], p["y"], p["z"]) for p in entry["bounding_box"]]
        centre = tuple(sum(p[a] for p in c) / 8 for a in range(3))
        ex = (c[1][0] - c[0][0], c[1][1] - c[0][1])
        ey = (c[2][0] - c[1][0], c[2][1] - c[1][1])
        zs = [p[2] for p in c]
        half = (math.hypot(*ex) / 2, math.hypot(*ey) / 2, (max(zs) - min(zs)) / 2)
        out[str(entry["ins_id"])] = (centre, half, math.atan2(ex[1], ex[0]))
    return out


def in_box(p, box, tol=1e-3):
    (cx, cy, cz), (hx, hy, hz), yaw = box
    dx, dy = p[0] - cx, p[1] - cy
    lx = dx * math.cos(yaw) + dy * math.sin(yaw)
    ly = -dx * math.sin(yaw) + dy * math.cos(yaw)
    return abs(lx) <= hx + tol and abs(ly) <= hy + tol and abs(p[2] - cz) <= hz + tol


def aabb(box, grow=0.0):
    (cx, cy, cz), (hx, hy, hz), yaw = box
    rx = abs(hx * math.cos(yaw)) + abs(hy * math.sin(yaw)) + grow
    ry = abs(hx * math.sin(yaw)) + abs(hy * math.cos(yaw)) + grow
    return (cx - rx, cy - ry, cz - hz - grow), (cx + rx, cy + ry, cz + hz + grow)


def apart(a, b):
    return any(a[1][k] < b[0][k] or b[1][k] < a[0][k] for k in range(3))


def author(path, scene_dir, turned=False, style="ins", units=1.0):
    """Writes a collision file for the scene at `path` (binary for `.usd`, text for `.usda`).

    Objects whose middle lies clear of every other box get one unnamed part there (placed by
    box); the others two parts under a prim named after them (`ins_{id}`, or `_{id}` with
    style "id"), one under a nested, scaled Xform. Four walls and a floor round the scene belong
    to no object. With `turned`, the whole file is turned 180° about Z (frame S). Coordinates are
    written in units of `units` metres. Returns {ins_id: parts} and the structure part count."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, units)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    if turned:
        world.AddRotateZOp().Set(180.0)
    k = 1.0 / units
    bx = boxes(scene_dir)
    expected = {}
    for n, (ins_id, box) in enumerate(bx.items()):
        (cx, cy, cz), (hx, hy, hz), yaw = box
        mid_box = ((cx, cy, cz), (hx / 2, hy / 2, hz / 2), yaw)
        clear = all(apart(aabb(mid_box), aabb(other, 0.1)) for i, other in bx.items() if i != ins_id)
        if n % 2 == 1 and clear:
            # Unnamed: the middle half of the box, its points written in the file's frame.
            pts = []
            for sx, sy, sz in cube_points((-1, -1, -1), (1, 1, 1)):
                lx, ly, lz = sx * hx / 2, sy * hy / 2, sz * hz / 2
                wx = cx + lx * math.cos(yaw) - ly * math.sin(yaw)
                wy = cy + lx * math.sin(yaw) + ly * math.cos(yaw)
                pts.append((wx * k, wy * k, (cz + lz) * k))
            mesh = UsdGeom.Mesh.Define(stage, f"/World/Collision/mesh_{n}")
            mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in pts]))
            mesh.CreateFaceVertexCountsAttr([3] * 12)
            mesh.CreateFaceVertexIndicesAttr([i for t in CUBE_TRIANGLES for i in t])
            expected[ins_id] = 1
            continue
        name = f"ins_{ins_id}" if style == "ins" else f"_{ins_id}"
        xf = UsdGeom.Xform.Define(stage, f"/World/Objects/{name}")
        xf.AddTranslateOp().Set(Gf.Vec3d(cx * k, cy * k, cz * k))
        xf.AddRotateZOp().Set(math.degrees(yaw))
        # Part 0: the box's −x part, in the object's own frame.
        define_cube(
            stage,
            f"/World/Objects/{name}/part_0",
            (-0.8 * hx * k, -0.8 * hy * k, -0.8 * hz * k),
            (0.0, 0.8 * hy * k, 0.8 * hz * k),
        )
        # Part 1: a unit cube under a nested Xform that moves and scales it into the +x part.
        sub = UsdGeom.Xform.Define(stage, f"/World/Objects/{name}/sub")
        sub.AddTranslateOp().Set(Gf.Vec3d(0.4 * hx * k, 0, 0))
        sub.AddScaleOp().Set(Gf.Vec3f(0.35 * hx * k, 0.8 * hy * k, 0.8 * hz * k))
        define_cube(stage, f"/World/Objects/{name}/sub/part_1")
        expected[ins_id] = 2
    lo = [min(aabb(b)[0][a] for b in bx.values()) - 1.0 for a in range(2)]
    hi = [max(aabb(b)[1][a] for b in bx.values()) + 1.0 for a in range(2)]
    walls = [
        ((lo[0], lo[1] - 0.1, 0), (hi[0], lo[1], 2.5)),
        ((lo[0], hi[1], 0), (hi[0], hi[1] + 0.1, 2.5)),
        ((lo[0] - 0.1, lo[1], 0), (lo[0], hi[1], 2.5)),
        ((hi[0], lo[1], 0), (hi[0] + 0.1, hi[1], 2.5)),
        ((lo[0], lo[1], -0.1), (hi[0], hi[1], 0.0)),
    ]
    for i, (a, b) in enumerate(walls):
        name = "floor" if i == 4 else f"wall_{i}"
        define_cube(stage, f"/World/Structure/{name}", tuple(v * k for v in a), tuple(v * k for v in b))
    stage.GetRootLayer().Save()
    return expected, len(walls)


@pytest.fixture(scope="module")
def scene_src(sage3d, tmp_path_factory):
    out = tmp_path_factory.mktemp("colscene") / "src"
    sage3d("scene", "synth", "--seed", 4, "--out", out, "--rooms", 2, "--objects", 10, "--gaussians", 2000)
    return out


def copy_scene(src, dest):
    shutil.copytree(src, dest)
    return dest


def build(sage3d, scene, *extra):
    cache = scene.parent / f"{scene.name}-hulls"
    return json.loads(sage3d("physics", "build", scene, "--json", "--cache", cache, *FAST, *extra).stdout)


def check_report(report, expected, structure, frame):
    c = report["collision"]
    assert c["frame"] == frame and c["frame_measured"], c
    named = sum(n for n in expected.values() if n == 2)
    unnamed = sum(1 for n in expected.values() if n == 1)
    assert unnamed >= 1 and named >= 2, expected
    assert (c["by_name"], c["by_box"], c["structure"]) == (named, unnamed, structure), c
    assert c["names_rejected"] == 0 and c["objects_without"] == 0, c
    good = c["agreement_w" if frame == "W" else "agreement_s"]
    other = c["agreement_s" if frame == "W" else "agreement_w"]
    parts = c["parts"]
    assert good["inside"] == pytest.approx((parts - structure) / parts, abs=1e-6), c
    assert other["inside"] < good["inside"], c
    for s in report["sources"]:
        assert s["source"] == "published", s
        assert s["parts"] == expected[s["ins_id"]], s
    assert report["structure_parts"] == structure
    assert report["decomposed"] == 0 and report["cached"] == 0


def check_export_in_w(sage3d, scene, out, *extra):
    """Exports the scene and checks every object's hull points lie in its own W box."""
    cache = scene.parent / f"{scene.name}-hulls"
    sage3d("export", "usd", scene, out, "--cache", cache, *FAST, *extra)
    stage = Usd.Stage.Open(str(out))
    bx = boxes(scene)
    ids = list(bx)
    objects = stage.GetPrimAtPath("/World/Objects").GetChildren()
    assert len(objects) == len(ids)
    for prim in objects:
        box = bx[ids[prim.GetAttribute("sage3d:instanceId").Get() - 1]]
        assert prim.GetAttribute("sage3d:bodySource").Get() == "published", prim.GetPath()
        meshes = [c for c in prim.GetChildren() if c.IsA(UsdGeom.Mesh)]
        assert meshes, prim.GetPath()
        for m in meshes:
            for p in UsdGeom.Mesh(m).GetPointsAttr().Get():
                assert in_box(p, box, tol=2e-3), (prim.GetPath(), p, box)
    structure = stage.GetPrimAtPath("/World/Structure/structure")
    assert structure.IsValid()
    assert structure.GetAttribute("sage3d:bodySource").Get() == "published"
    assert len([c for c in structure.GetChildren() if c.IsA(UsdGeom.Mesh)]) == 5


def test_binary_file_in_folder_by_numeric_id(scene_src, sage3d, tmp_path):
    """The published name: folder `0001_839920`, file `839920_collision.usd` (USDC) in W."""
    scene = copy_scene(scene_src, tmp_path / "0001_839920")
    path = scene / "839920_collision.usd"
    expected, structure = author(path, scene)
    assert path.read_bytes()[:8] == b"PXR-USDC"
    check_report(build(sage3d, scene), expected, structure, "W")
    check_export_in_w(sage3d, scene, tmp_path / "out.usda")
    info = json.loads(sage3d("scene", "info", scene, "--json").stdout)
    assert info["collision"]["frame"] == "W"
    assert "839920_collision.usd" in info["files"]
    text = sage3d("scene", "info", scene).stdout
    assert "collision" in text and "frame W (measured" in text and "% inside" in text


def test_given_file_turned_180_in_centimetres(scene_src, sage3d, tmp_path):
    """`--collision FILE` from elsewhere, the template's frame S, prims named `_{id}`, cm units."""
    scene = copy_scene(scene_src, tmp_path / "kitchen")
    path = tmp_path / "elsewhere" / "whatever.usd"
    path.parent.mkdir()
    expected, structure = author(path, scene, turned=True, style="id", units=0.01)
    report = build(sage3d, scene, "--collision", path)
    check_report(report, expected, structure, "S")
    assert report["collision"]["meters_per_unit"] == pytest.approx(0.01)
    check_export_in_w(sage3d, scene, tmp_path / "out.usda", "--collision", path)
    info = json.loads(sage3d("scene", "info", scene, "--json", "--collision", path).stdout)
    assert info["collision"]["frame"] == "S"
    # Without the flag the folder has no published layer.
    assert "collision" not in build(sage3d, scene)


def test_text_file_by_folder_name(scene_src, sage3d, tmp_path):
    """`{folder}_collision.usda`, text, found by the folder's whole name."""
    scene = copy_scene(scene_src, tmp_path / "0002_777")
    path = scene / "0002_777_collision.usda"
    expected, structure = author(path, scene)
    assert path.read_text().startswith("#usda")
    check_report(build(sage3d, scene), expected, structure, "W")


def test_damaged_files_are_clear_errors(scene_src, sage3d, tmp_path):
    scene = copy_scene(scene_src, tmp_path / "s")
    good = tmp_path / "good.usd"
    author(good, scene)

    def fails(path, *needles):
        proc = sage3d("physics", "build", scene, "--collision", path, *FAST, check=False)
        assert proc.returncode != 0, proc.stdout
        assert "panicked" not in proc.stderr, proc.stderr
        for n in (path.name, *needles):
            assert n in proc.stderr, proc.stderr
        return proc.stderr

    truncated = tmp_path / "truncated.usd"
    truncated.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    fails(truncated, "not a readable USD file")

    empty = tmp_path / "empty.usd"
    stage = Usd.Stage.CreateNew(str(empty))
    UsdGeom.Xform.Define(stage, "/World/Nothing")
    stage.GetRootLayer().Save()
    fails(empty, "no mesh prim")

    bad = tmp_path / "bad_index.usd"
    stage = Usd.Stage.CreateNew(str(bad))
    define_cube(stage, "/World/Objects/ins_1000/part_0", bad_index=True)
    stage.GetRootLayer().Save()
    fails(bad, "/World/Objects/ins_1000/part_0", "faceVertexIndices[4]", "out of range")

    # Sizes the file declares past what its bytes hold are refused before anything is
    # allocated for them (the reader would ask for terabytes and the process would abort):
    # a mesh's points array, and the table of paths.
    lo, hi = (0.25, 0.5, 0.75), (1.25, 1.5, 1.75)
    one = tmp_path / "one_cube.usd"
    stage = Usd.Stage.CreateNew(str(one))
    define_cube(stage, "/World/Objects/ins_1000/part_0", lo, hi)
    stage.GetRootLayer().Save()
    data = bytearray(one.read_bytes())
    points = data.find(struct.pack("<24f", *[v for p in cube_points(lo, hi) for v in p]))
    assert points > 0 and struct.unpack_from("<Q", data, points - 8)[0] == 8
    struct.pack_into("<Q", data, points - 8, 1 << 40)
    huge_points = tmp_path / "huge_points.usd"
    huge_points.write_bytes(bytes(data))
    fails(huge_points, "not a readable USD file", "array value")
    # The same layer packed in a USDZ archive (stored, its checksum right).
    packed = tmp_path / "huge_points.usdz"
    with zipfile.ZipFile(packed, "w", zipfile.ZIP_STORED) as z:
        z.writestr("one_cube.usd", bytes(data))
    fails(packed, "not a readable USD file", "one_cube.usd", "array value")

    data = bytearray(one.read_bytes())
    (toc,) = struct.unpack_from("<Q", data, 16)
    (sections,) = struct.unpack_from("<Q", data, toc)
    starts = {
        data[toc + 8 + 32 * k : toc + 24 + 32 * k].rstrip(b"\0").decode(): struct.unpack_from("<Q", data, toc + 24 + 32 * k)[0]
        for k in range(sections)
    }
    struct.pack_into("<Q", data, starts["PATHS"], 1 << 40)
    huge_paths = tmp_path / "huge_paths.usd"
    huge_paths.write_bytes(bytes(data))
    fails(huge_paths, "not a readable USD file", "PATHS", "paths")

    proc = sage3d("physics", "build", scene, "--collision", tmp_path / "missing.usd", check=False)
    assert proc.returncode != 0 and "missing.usd" in proc.stderr and "does not exist" in proc.stderr


def test_the_flag_is_in_the_help(sage3d):
    for cmd in (["physics", "build"], ["export", "usd"], ["scene", "info"], ["physics", "pending"]):
        assert "--collision <FILE>" in sage3d(*cmd, "--help").stdout, cmd


def test_python_scene_load_takes_collision(scene_src, tmp_path):
    sg = pytest.importorskip("sage3d")
    scene = copy_scene(scene_src, tmp_path / "py")
    path = tmp_path / "c.usd"
    author(path, scene, turned=True)
    loaded = sg.Scene.load(scene, cache=tmp_path / "hulls", collision=path)
    assert loaded.num_objects == len(boxes(scene))
    with pytest.raises(Exception, match="missing.usd"):
        sg.Scene.load(scene, cache=tmp_path / "hulls", collision=tmp_path / "missing.usd")
