"""The path finder from Python answers as the Rust planner behind `sage3d nav trajectories` on
the same scene: geodesic distances equal those recorded in its trajectory file, endpoints are
navigable, paths join them; snapping and seeded sampling behave as documented."""

import json
import math

import numpy as np
import pytest

import sage3d as sg


@pytest.fixture(scope="module")
def planned(small_scene, sage3d, tmp_path_factory):
    out = tmp_path_factory.mktemp("traj")
    sage3d("nav", "trajectories", small_scene, "--count", 6, "--seed", 4, "--out", out)
    (path,) = out.rglob("trajectories.json")
    return sg.Scene.load(small_scene), json.loads(path.read_text())["trajectories"]


def test_geodesic_distances_equal_the_cli_planner(planned):
    scene, trajectories = planned
    pf = scene.pathfinder
    assert len(trajectories) >= 3
    for t in trajectories:
        s, g = t["start"]["point"], t["goal"]["point"]
        assert pf.is_navigable(s) and pf.is_navigable(g)
        geo = pf.geodesic_distance(s, g)
        # The planner records min(length-only geodesic, planned length): the same A*.
        assert min(geo, t["length"]) == pytest.approx(t["geodesic_distance"], abs=1e-5)
        assert geo >= math.dist(s[:2], g[:2]) - 1e-4
        path = pf.find_path(s, g)
        assert path.dtype == np.float32 and path.shape[1] == 2
        np.testing.assert_allclose(path[0], s[:2], atol=1e-6)
        np.testing.assert_allclose(path[-1], g[:2], atol=1e-6)
        length = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
        assert length >= geo - 1e-3
        assert pf.island(s) == pf.island(g)


def test_snapping_sampling_and_unreachable_points(planned):
    scene, trajectories = planned
    pf = scene.pathfinder
    p = np.array(trajectories[0]["start"]["point"][:2]) + 0.01
    q = pf.snap_point(p)
    assert pf.is_navigable(q) and np.linalg.norm(q - p) <= pf.cell_size
    assert pf.snap_point([1e4, 1e4]) is None
    # Unbounded, the nearest cell anywhere, as any bound wide enough finds it.
    anywhere = pf.snap_point([1e4, 1e4], max_distance=math.inf)
    np.testing.assert_array_equal(anywhere, pf.snap_point([1e4, 1e4], max_distance=1e9))
    for bad in (-1.0, math.nan):
        with pytest.raises(ValueError, match="max_distance"):
            pf.snap_point(p, max_distance=bad)
    for bad in (-1, 2**70):
        with pytest.raises(ValueError, match="seed: expected a whole number"):
            pf.seed(bad)
    assert pf.geodesic_distance([1e4, 1e4], p) == math.inf
    with pytest.raises(ValueError, match="not navigable|outside the map"):
        pf.find_path([1e4, 1e4], p)
    with pytest.raises(ValueError, match="expected finite"):
        pf.is_navigable([1.0])
    pf.seed(5)
    a = [pf.sample_navigable_point() for _ in range(5)]
    pf.seed(5)
    b = [pf.sample_navigable_point() for _ in range(5)]
    np.testing.assert_array_equal(a, b)
    assert all(pf.is_navigable(x) for x in a)
    areas = pf.island_areas()
    island = pf.island(a[0])
    assert areas[island] > 0
    assert pf.island(pf.sample_navigable_point(island)) == island
    # Out-of-range integers are ValueErrors naming the argument, not bare OverflowErrors.
    with pytest.raises(ValueError, match=f"island: {len(areas)} is not an island"):
        pf.sample_navigable_point(len(areas))
    with pytest.raises(ValueError, match="island: expected a whole number within u32, got -1"):
        pf.sample_navigable_point(-1)
    with pytest.raises(ValueError, match="count: expected a whole number within usize, got -1"):
        scene.episodes(count=-1)
