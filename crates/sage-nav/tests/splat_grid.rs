//! Grids for scenes without a floorplan: a synthetic scene stripped of its structure (and
//! occupancy, and labels) gets its map from the Gaussians, and that map agrees with the grid
//! of the scene's own geometry.

use sage_nav::grid::NavGrid;
use sage_nav::{CostParams, GridParams, GridSource, PathFinder};
use sage_scene::occupancy::FREE;
use sage_scene::{Floorplan, Scene};
use sage_synth::{SceneKind, SynthConfig, generate};

fn synth(seed: u64) -> Scene {
    generate(&SynthConfig {
        seed,
        kind: SceneKind::Home,
        rooms: 3,
        objects: 25,
        gaussians: 60_000,
        ..SynthConfig::default()
    })
    .unwrap()
}

/// Free-space intersection over union of `b` against `a`, compared at `a`'s cell centres.
fn free_iou(a: &NavGrid, b: &NavGrid) -> f64 {
    let (mut both, mut either) = (0usize, 0usize);
    for k in 0..a.cells.len() {
        let fa = a.cells[k] == FREE;
        let fb = b
            .cell_at(a.center_of(k))
            .is_some_and(|(i, j)| b.cells[b.index(i, j)] == FREE);
        both += usize::from(fa && fb);
        either += usize::from(fa || fb);
    }
    both as f64 / either.max(1) as f64
}

#[test]
fn gaussians_alone_give_the_free_space_of_the_geometry() {
    let params = GridParams::default();
    for seed in [1, 2] {
        let full = synth(seed);
        let (truth, source) = NavGrid::from_scene(&full, &params).unwrap();
        assert_eq!(source, GridSource::Geometry);

        // Labels without structure: geometry obstacles, Gaussian free space.
        let mut labels_only = full.clone();
        labels_only.floorplan = Floorplan::default();
        labels_only.occupancy = None;
        labels_only.structure_mesh = None;
        let (mixed, source) = NavGrid::from_scene(&labels_only, &params).unwrap();
        assert_eq!(source, GridSource::GeometryGaussians);
        let iou_mixed = free_iou(&truth, &mixed);

        // Gaussians alone.
        let mut bare = labels_only.clone();
        bare.objects.clear();
        let (alone, source) = NavGrid::from_scene(&bare, &params).unwrap();
        assert_eq!(source, GridSource::Gaussians);
        let iou_alone = free_iou(&truth, &alone);
        println!(
            "seed {seed}: free-space IoU with the geometry grid: gaussians {iou_alone:.3}, geometry+gaussians {iou_mixed:.3}"
        );
        assert!(iou_alone >= 0.85, "seed {seed}: {iou_alone}");
        assert!(iou_mixed >= 0.85, "seed {seed}: {iou_mixed}");

        // The planner works on it: two far-apart navigable points of the largest island.
        let (finder, _) = PathFinder::from_scene(&bare, &params, CostParams::default()).unwrap();
        let areas = finder.island_areas();
        let biggest = (0..areas.len())
            .max_by(|&x, &y| areas[x].total_cmp(&areas[y]))
            .unwrap() as u32;
        println!(
            "seed {seed}: largest island {:.1} m2",
            areas[biggest as usize]
        );
        let cells: Vec<usize> = finder
            .navigable_cells()
            .iter()
            .map(|&k| k as usize)
            .filter(|&k| finder.island_of_cell(k) == biggest)
            .collect();
        let (a, b) = (
            alone.center_of(cells[0]),
            alone.center_of(cells[cells.len() - 1]),
        );
        let path = finder.find_path(a, b).unwrap();
        assert!(path.waypoints.len() >= 2);
    }
}

#[test]
fn a_scene_without_rooms_gaussians_or_map_is_refused() {
    let mut s = synth(3);
    s.floorplan = Floorplan::default();
    s.occupancy = None;
    s.gaussians = sage_scene::Gaussians::new(0).unwrap();
    s.objects.clear();
    s.structure_mesh = None;
    let e = NavGrid::from_scene(&s, &GridParams::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("free space is undefined"), "{e}");
}

#[test]
fn a_bare_capture_gets_regions_to_walk_between_and_trajectories() {
    let mut bare = synth(3);
    bare.floorplan = Floorplan::default();
    bare.occupancy = None;
    bare.structure_mesh = None;
    bare.objects.clear();
    let params = sage_nav::TrajectoryParams {
        count: 6,
        seed: 4,
        ..sage_nav::TrajectoryParams::default()
    };
    let (pf, _) = PathFinder::from_scene(&bare, &params.grid, params.cost.clone()).unwrap();
    let map = sage_nav::SemanticMap::build(&bare);
    let ends = sage_nav::sampling::Endpoints::collect(&map, &pf, &params.sampling);
    assert!(ends.list.len() >= 2, "{} regions", ends.list.len());
    for e in &ends.list {
        assert_eq!(e.kind, sage_nav::EndpointKind::Room);
        assert!(e.reference.starts_with("region_") && e.label == "region");
        assert!(e.stands.iter().all(|s| e.polygon.contains(s.point)));
    }
    let prep = sage_nav::trajectory::prepare(&bare, &params).unwrap();
    let (set, _) = sage_nav::trajectory::generate(&bare.name, &prep, &params).unwrap();
    assert!(!set.trajectories.is_empty());
}
