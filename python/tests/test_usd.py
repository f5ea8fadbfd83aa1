"""The hybrid USDA scene opened with Pixar's USD (usd-core): stage metadata, prim counts against
the scene's own files, and the UsdPhysics and UsdSemantics schemas applied."""

import json

import pytest

pxr = pytest.importorskip("pxr", reason="usd-core is installed by scripts/test")
from pxr import Sdf, Usd, UsdGeom, UsdPhysics, UsdSemantics  # noqa: E402


@pytest.fixture(scope="module")
def exported(small_scene, sage3d, tmp_path_factory):
    out = tmp_path_factory.mktemp("usd") / "scene.usda"
    # A coarse V-HACD keeps the debug build quick; the cache lives in a temp folder.
    cache = tmp_path_factory.mktemp("hulls")
    args = ["--resolution", 24, "--cache", cache]
    sage3d("export", "usd", small_scene, out, *args)
    report = json.loads(sage3d("physics", "build", small_scene, "--json", *args).stdout)
    stage = Usd.Stage.Open(str(out))
    assert stage is not None
    return stage, report, small_scene


def test_stage_is_z_up_in_metres(exported):
    stage, _, _ = exported
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdPhysics.GetStageKilogramsPerUnit(stage) == 1.0
    assert stage.GetDefaultPrim().GetPath() == Sdf.Path("/World")
    scenes = [p for p in stage.Traverse() if p.IsA(UsdPhysics.Scene)]
    assert len(scenes) == 1


def test_one_prim_per_object_and_wall_with_labels(exported):
    stage, report, scene_dir = exported
    labels = json.loads((scene_dir / "labels.json").read_text())
    structure = json.loads((scene_dir / "structure.json").read_text())
    objects = stage.GetPrimAtPath("/World/Objects").GetChildren()
    assert len(objects) == len(labels)
    walls = [p for p in stage.GetPrimAtPath("/World/Structure").GetChildren() if p.GetName().startswith("wall_")]
    assert len(walls) == len(structure["walls"])
    extras = json.loads((scene_dir / "objects.json").read_text())["objects"]
    categories = {e["category"] for e in extras}
    for prim in objects + walls:
        assert prim.HasAPI(UsdSemantics.LabelsAPI, "class"), prim.GetPath()
        labels_attr = UsdSemantics.LabelsAPI(prim, "class").GetLabelsAttr().Get()
        assert len(labels_attr) == 1
    assert {UsdSemantics.LabelsAPI(p, "class").GetLabelsAttr().Get()[0] for p in objects} == categories
    ids = sorted(p.GetAttribute("sage3d:instanceId").Get() for p in objects)
    assert ids == list(range(1, len(labels) + 1))


def test_every_convex_part_is_an_invisible_collision_mesh(exported):
    stage, report, _ = exported
    meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert len(meshes) == report["parts"]
    for m in meshes:
        assert m.HasAPI(UsdPhysics.CollisionAPI) and m.HasAPI(UsdPhysics.MeshCollisionAPI)
        assert UsdPhysics.MeshCollisionAPI(m).GetApproximationAttr().Get() == "convexHull"
        mesh = UsdGeom.Mesh(m)
        assert UsdGeom.Imageable(m).ComputeVisibility() == UsdGeom.Tokens.invisible
        counts = mesh.GetFaceVertexCountsAttr().Get()
        indices = mesh.GetFaceVertexIndicesAttr().Get()
        points = mesh.GetPointsAttr().Get()
        assert len(points) >= 4 and all(c == 3 for c in counts)
        assert len(indices) == 3 * len(counts) and max(indices) < len(points)


def test_movable_and_articulated_objects_have_bodies_and_joints(exported):
    stage, _, scene_dir = exported
    extras = json.loads((scene_dir / "objects.json").read_text())["objects"]
    roles = [e["physics"]["role"] for e in extras]
    objects = stage.GetPrimAtPath("/World/Objects").GetChildren()
    by_role = {}
    for p in objects:
        by_role.setdefault(p.GetAttribute("sage3d:physicsRole").Get(), []).append(p)
    assert len(by_role.get("movable", [])) > 0 and len(by_role.get("articulated", [])) > 0
    for role in ("static", "movable", "articulated"):
        assert len(by_role.get(role, [])) == roles.count(role), role
    for p in by_role.get("movable", []) + by_role.get("articulated", []):
        assert p.HasAPI(UsdPhysics.RigidBodyAPI) and p.HasAPI(UsdPhysics.MassAPI)
        assert UsdPhysics.MassAPI(p).GetMassAttr().Get() > 0
    for p in by_role.get("static", []):
        assert not p.HasAPI(UsdPhysics.RigidBodyAPI)
    joints = [p for p in stage.Traverse() if p.IsA(UsdPhysics.RevoluteJoint)]
    assert len(joints) == len(by_role["articulated"])
    for j in joints:
        joint = UsdPhysics.RevoluteJoint(j)
        assert joint.GetAxisAttr().Get() == "Z"
        assert joint.GetBody1Rel().GetForwardedTargets() == [j.GetParent().GetPath()]


def test_gaussians_are_referenced_as_the_scene_ply(exported):
    stage, _, scene_dir = exported
    asset = stage.GetPrimAtPath("/World/Gaussians").GetAttribute("sage3d:splats").Get()
    resolved = asset.resolvedPath
    assert resolved and resolved.endswith("3dgs_compressed.ply")
    assert (scene_dir / "3dgs_compressed.ply").samefile(resolved)
