//! The navigation layer on hand-built and synthetic scenes: occupancy rules, the InteriorGS
//! round trip, A* against the `pathfinding` crate, the path finder API, endpoint sampling,
//! trajectory determinism, resume and bad input.

use glam::{Vec2, Vec3};
use proptest::prelude::*;
use sage_core::{InstanceId, Obb, Polygon2};
use sage_io::runner::Status;
use sage_nav::astar::{DistanceField, Graph, Search};
use sage_nav::grid::NavGrid;
use sage_nav::path::line_clear;
use sage_nav::sampling::Endpoints;
use sage_nav::trajectory::{self, TrajectoryParams};
use sage_nav::{CostParams, GridParams, PathFinder, SemanticMap};
use sage_scene::occupancy::{FREE, OCCUPIED, UNKNOWN};
use sage_scene::{Floorplan, Gaussians, Object, Room, Scene, TriMesh, Wall};
use sage_synth::{SceneKind, SynthConfig, generate};

/// A closed box mesh from `lo` to `hi`.
fn box_mesh(lo: Vec3, hi: Vec3) -> TriMesh {
    let c = |i: u32| {
        Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    };
    TriMesh {
        positions: (0..8).map(c).collect(),
        triangles: vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ],
    }
}

fn object(category: &str, mesh: Option<TriMesh>, obb: Obb) -> Object {
    Object {
        id: InstanceId::NONE,
        ins_id: category.to_string(),
        label: category.to_string(),
        category: category.to_string(),
        obb,
        room: None,
        attributes: Default::default(),
        role: Default::default(),
        rigid_body: Default::default(),
        mesh,
        body: None,
    }
}

/// A 6 × 4 m room with outside walls and the given objects.
fn room_scene(objects: Vec<Object>, inner_walls: Vec<Wall>) -> Scene {
    let (w, h) = (6.0, 4.0);
    let corners = [
        Vec2::ZERO,
        Vec2::new(w, 0.0),
        Vec2::new(w, h),
        Vec2::new(0.0, h),
    ];
    let mut walls: Vec<Wall> = (0..4)
        .map(|k| Wall {
            start: corners[k],
            end: corners[(k + 1) % 4],
            thickness: 0.1,
            height: 2.8,
        })
        .collect();
    walls.extend(inner_walls);
    let mut scene = Scene {
        name: "hand".into(),
        gaussians: Gaussians::new(0).unwrap(),
        objects,
        floorplan: Floorplan {
            rooms: vec![Room {
                profile: Polygon2::new(corners.to_vec()),
                room_type: "Living Room".into(),
            }],
            walls,
            holes: vec![],
            items: vec![],
            ceiling: None,
        },
        occupancy: None,
        structure_mesh: None,
        structure_body: None,
        instances: Default::default(),
    };
    scene.finish();
    scene
}

fn obb_of(lo: Vec3, hi: Vec3) -> Obb {
    Obb {
        center: (lo + hi) * 0.5,
        half_extents: (hi - lo) * 0.5,
        yaw: 0.0,
    }
}

fn cell_value(g: &NavGrid, p: Vec2) -> u8 {
    let (i, j) = g.cell_at(p).unwrap();
    g.cells[g.index(i, j)]
}

fn small_synth(seed: u64) -> Scene {
    generate(&SynthConfig {
        seed,
        kind: SceneKind::Home,
        rooms: 4,
        objects: 40,
        gaussians: 2000,
        ..SynthConfig::default()
    })
    .unwrap()
}

#[test]
fn table_top_blocks_ceiling_lamp_does_not_and_box_interiors_fill() {
    // A table top (a thin slab at 0.72–0.75 m), a lamp hanging at 2.2–2.6 m, a rug at 0–0.01 m
    // and a wardrobe whose box mesh is hollow inside.
    let table = box_mesh(Vec3::new(1.0, 1.0, 0.72), Vec3::new(2.0, 1.6, 0.75));
    let lamp = box_mesh(Vec3::new(3.0, 1.0, 2.2), Vec3::new(3.4, 1.4, 2.6));
    let rug = box_mesh(Vec3::new(3.5, 2.5, 0.0), Vec3::new(5.0, 3.5, 0.01));
    let wardrobe = box_mesh(Vec3::new(4.2, 0.3, 0.0), Vec3::new(5.6, 1.5, 2.2));
    let objs = vec![
        object(
            "table",
            Some(table),
            obb_of(Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, 1.6, 0.75)),
        ),
        object(
            "ceiling_lamp",
            Some(lamp),
            obb_of(Vec3::new(3.0, 1.0, 2.2), Vec3::new(3.4, 1.4, 2.6)),
        ),
        object(
            "rug",
            Some(rug),
            obb_of(Vec3::new(3.5, 2.5, 0.0), Vec3::new(5.0, 3.5, 0.01)),
        ),
        object(
            "wardrobe",
            Some(wardrobe),
            obb_of(Vec3::new(4.2, 0.3, 0.0), Vec3::new(5.6, 1.5, 2.2)),
        ),
    ];
    let scene = room_scene(objs, vec![]);
    let (g, _) = NavGrid::from_scene(&scene, &GridParams::default()).unwrap();
    assert_eq!(cell_value(&g, Vec2::new(1.5, 1.3)), OCCUPIED, "table top");
    assert_eq!(cell_value(&g, Vec2::new(3.2, 1.2)), FREE, "ceiling lamp");
    assert_eq!(
        cell_value(&g, Vec2::new(4.2, 3.0)),
        FREE,
        "rug below the slab"
    );
    assert_eq!(
        cell_value(&g, Vec2::new(4.9, 0.9)),
        OCCUPIED,
        "wardrobe inside"
    );
    assert_eq!(cell_value(&g, Vec2::new(0.02, 2.0)), OCCUPIED, "outer wall");
    assert_eq!(cell_value(&g, Vec2::new(-0.3, 2.0)), UNKNOWN, "outside");
    // A lower slab lets the agent pass under the table.
    let low = GridParams {
        agent_height: 0.5,
        ..GridParams::default()
    };
    let (g2, _) = NavGrid::from_scene(&scene, &low).unwrap();
    assert_eq!(cell_value(&g2, Vec2::new(1.5, 1.3)), FREE);
}

#[test]
fn a_thin_diagonal_wall_does_not_leak() {
    // A 2 cm wall on a diagonal splits the room's left part: no 4-connected free path may cross.
    let wall = Wall {
        start: Vec2::new(0.0, 0.0),
        end: Vec2::new(4.0, 4.0),
        thickness: 0.02,
        height: 2.8,
    };
    let scene = room_scene(vec![], vec![wall]);
    let params = GridParams::default();
    let (g, _) = NavGrid::from_scene(&scene, &params).unwrap();
    let pf = PathFinder::new(
        g,
        &scene.floorplan,
        CostParams {
            robot_radius: 0.0,
            ..CostParams::default()
        },
    )
    .unwrap();
    let a = pf.island(Vec2::new(3.0, 1.0)).unwrap();
    let b = pf.island(Vec2::new(1.0, 3.0)).unwrap();
    assert_ne!(a, b);
    assert!(
        pf.find_path(Vec2::new(3.0, 1.0), Vec2::new(1.0, 3.0))
            .is_err()
    );
}

#[test]
fn occupancy_round_trips_through_the_interiorgs_files() {
    let scene = small_synth(2);
    let (g, _) = NavGrid::from_scene(&scene, &GridParams::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    g.to_occupancy((0.1, 1.2))
        .unwrap()
        .save(dir.path())
        .unwrap();
    let back =
        NavGrid::from_occupancy(&sage_scene::OccupancyMap::load(dir.path()).unwrap()).unwrap();
    assert_eq!(back.cells, g.cells);
    assert!((back.origin - g.origin).length() < 1e-4);
    // A point maps to the same cell value through the mirrored InteriorGS layout.
    let occ = g.to_occupancy((0.1, 1.2)).unwrap();
    for k in (0..g.cells.len()).step_by(97) {
        let p = g.center_of(k);
        let (c, r) = occ.cell_at(p).unwrap();
        assert_eq!(occ.get(c, r), g.cells[k]);
    }
}

#[test]
fn a_scene_without_meshes_uses_its_own_occupancy() {
    let mut scene = small_synth(3);
    for o in &mut scene.objects {
        o.mesh = None;
    }
    scene.structure_mesh = None;
    let (g, source) = NavGrid::from_scene(&scene, &GridParams::default()).unwrap();
    assert_eq!(source, sage_nav::GridSource::SceneOccupancy);
    let own = NavGrid::from_occupancy(scene.occupancy.as_ref().unwrap()).unwrap();
    assert_eq!(g.cells, own.cells);
}

/// A random grid with a blocked border.
fn random_grid(w: usize, h: usize, seed: u64, density: u64) -> Vec<bool> {
    let mut s = seed | 1;
    (0..w * h)
        .map(|k| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let (i, j) = (k % w, k / w);
            i > 0 && j > 0 && i + 1 < w && j + 1 < h && s % 100 >= density
        })
        .collect()
}

/// The oracle: `pathfinding`'s Dijkstra with integer costs (length × 10⁶ × weights).
fn oracle(w: usize, passable: &[bool], weight: Option<&[f32]>, s: usize, g: usize) -> Option<f64> {
    let succ = |&k: &usize| {
        let mut v = Vec::new();
        let (i, j) = ((k % w) as i64, (k / w) as i64);
        for (dx, dy) in [
            (1i64, 0i64),
            (-1, 0),
            (0, 1),
            (0, -1),
            (1, 1),
            (1, -1),
            (-1, 1),
            (-1, -1),
        ] {
            let m = ((j + dy) as usize) * w + (i + dx) as usize;
            let diag = dx != 0 && dy != 0;
            let side_a = ((j) as usize) * w + (i + dx) as usize;
            let side_b = ((j + dy) as usize) * w + i as usize;
            if passable[m] && (!diag || (passable[side_a] && passable[side_b])) {
                let len = if diag { std::f64::consts::SQRT_2 } else { 1.0 };
                let f = weight.map_or(1.0, |wt| 0.5 * (wt[k] + wt[m]) as f64);
                v.push((m, (len * f * 1e6).round() as u64));
            }
        }
        v
    };
    pathfinding::prelude::dijkstra(&s, succ, |&k| k == g).map(|(_, c)| c as f64 / 1e6)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn astar_matches_the_pathfinding_oracle(
        w in 6usize..28, h in 6usize..28, seed in any::<u64>(), density in 0u64..40,
        weighted in any::<bool>(), a in any::<u32>(), b in any::<u32>(),
    ) {
        let passable = random_grid(w, h, seed, density);
        let free: Vec<usize> = (0..w * h).filter(|&k| passable[k]).collect();
        prop_assume!(free.len() >= 2);
        let (s, g) = (free[a as usize % free.len()], free[b as usize % free.len()]);
        let weights: Vec<f32> = (0..w * h).map(|k| 1.0 + ((k * 7919) % 13) as f32 / 6.0).collect();
        let weight = weighted.then_some(weights.as_slice());
        let graph = Graph { width: w, passable: &passable, weight, min_weight: 1.0 };
        let mut search = Search::new();
        let got = search.astar(&graph, s, g);
        let want = oracle(w, &passable, weight, s, g);
        prop_assert_eq!(got.is_some(), want.is_some());
        if let (Some(got), Some(want)) = (got, want) {
            prop_assert!((got as f64 - want).abs() <= 1e-3 * want.max(1.0), "{} vs {}", got, want);
            // The path is legal: steps between neighbours, all passable, no corner cutting,
            // and its cost is the reported one.
            let mut cells = Vec::new();
            search.path_to(g, &mut cells);
            prop_assert_eq!(cells[0], s);
            prop_assert_eq!(*cells.last().unwrap(), g);
            for pair in cells.windows(2) {
                let (i0, j0) = ((pair[0] % w) as i64, (pair[0] / w) as i64);
                let (i1, j1) = ((pair[1] % w) as i64, (pair[1] / w) as i64);
                prop_assert!((i0 - i1).abs() <= 1 && (j0 - j1).abs() <= 1);
                prop_assert!(passable[pair[1]]);
                if i0 != i1 && j0 != j1 {
                    prop_assert!(passable[(j0 as usize) * w + i1 as usize]);
                    prop_assert!(passable[(j1 as usize) * w + i0 as usize]);
                }
            }
            // The distance field agrees with A*.
            let field = DistanceField::build(&graph, &[s]);
            prop_assert!((field.cost[g] - got).abs() <= 1e-3 * got.max(1.0));
            // The shortcut keeps only waypoints in sight of each other.
            let kept = sage_nav::path::shortcut(w, &passable, &cells);
            for pair in kept.windows(2) {
                prop_assert!(line_clear(w, &passable, pair[0], pair[1]));
            }
        }
    }
}

#[test]
fn the_path_finder_answers_habitat_style_queries() {
    let scene = small_synth(4);
    let (pf, _) =
        PathFinder::from_scene(&scene, &GridParams::default(), CostParams::default()).unwrap();
    let cells = pf.navigable_cells();
    let a = pf.grid.center_of(cells[cells.len() / 5] as usize);
    let island = pf.island(a).unwrap();
    let same: Vec<Vec2> = cells
        .iter()
        .map(|&k| k as usize)
        .filter(|&k| pf.island_of_cell(k) == island)
        .map(|k| pf.grid.center_of(k))
        .collect();
    let b = same[same.len() * 3 / 4];
    let path = pf.find_path(a, b).unwrap();
    assert_eq!(path.waypoints[0], a);
    assert_eq!(*path.waypoints.last().unwrap(), b);
    let geo = pf.geodesic_distance(a, b).unwrap();
    assert!(
        geo >= a.distance(b) - 1e-3,
        "geodesic {geo} shorter than the straight line"
    );
    assert!(
        geo <= path.length() + 1e-3,
        "geodesic {geo} longer than the planned path"
    );
    // The planned path keeps the shortcut margin wherever it takes a shortcut: each segment
    // joins neighbouring cells or crosses only cells with radius + margin of clearance.
    let need = pf.params.robot_radius + pf.params.shortcut_margin;
    for w in path.waypoints.windows(2) {
        let (p, q) = (pf.cell_of(w[0]).unwrap(), pf.cell_of(w[1]).unwrap());
        let width = pf.grid.width;
        let neighbours =
            (p % width).abs_diff(q % width) <= 1 && (p / width).abs_diff(q / width) <= 1;
        assert!(
            neighbours || sage_nav::path::line_clear(width, &pf.roomy, p, q),
            "segment {w:?} shortcuts through a cell with less than {need} m of clearance"
        );
    }
    // One field answers many goals as separate queries do.
    let field = pf.geodesic_field(a).unwrap();
    for &p in same.iter().step_by(same.len() / 7 + 1) {
        let (x, y) = (
            field.distance_to(p).unwrap(),
            pf.geodesic_distance(a, p).unwrap(),
        );
        assert!((x - y).abs() < 0.06 * y.max(1.0), "{x} vs {y}");
    }
    // The region distance: 0-ish for a region around the start, positive further away.
    let square = |c: Vec2, r: f32| {
        Polygon2::new(vec![
            c + Vec2::new(-r, -r),
            c + Vec2::new(r, -r),
            c + Vec2::new(r, r),
            c + Vec2::new(-r, r),
        ])
    };
    assert_eq!(
        pf.geodesic_distance_to_region(a, &square(a, 0.2), 1.0),
        Some(0.0)
    );
    let d = pf
        .geodesic_distance_to_region(a, &square(b, 0.1), 1.0)
        .unwrap();
    assert!(d <= geo + 1e-3 && d >= geo - 1.2, "{d} vs {geo}");
    // Snap, navigability, sampling.
    assert!(pf.is_navigable(a));
    let far = Vec2::new(1e4, 1e4);
    assert!(!pf.is_navigable(far));
    assert_eq!(pf.snap_point(far, 1.0), None);
    // An unbounded snap finds the nearest cell anywhere, as a large finite bound does; a
    // bound that is no distance finds nothing.
    let anywhere = pf.snap_point(far, f32::INFINITY).unwrap();
    assert_eq!(Some(anywhere), pf.snap_point(far, 1e9));
    assert!(pf.is_navigable(anywhere));
    assert_eq!(pf.snap_point(a, -1.0), None);
    assert_eq!(pf.snap_point(a, f32::NAN), None);
    let wall = scene.floorplan.walls[0]
        .start
        .lerp(scene.floorplan.walls[0].end, 0.5);
    let snapped = pf.snap_point(wall, 1.5).unwrap();
    assert!(pf.is_navigable(snapped) && snapped.distance(wall) <= 1.5);
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(1);
    for _ in 0..20 {
        let p = pf.sample_navigable_point(&mut rng, Some(island)).unwrap();
        assert_eq!(pf.island(p), Some(island));
    }
    // Bad queries: a clear error, never a panic or a long search.
    let e = pf.find_path(far, b).unwrap_err().to_string();
    assert!(e.contains("outside the map"), "{e}");
    assert_eq!(pf.geodesic_distance(a, far), None);
}

#[test]
fn penalty_keeps_paths_away_from_obstacles() {
    let scene = small_synth(5);
    let grid = GridParams::default();
    let (plain, _) = PathFinder::from_scene(&scene, &grid, CostParams::length_only(0.2)).unwrap();
    let (careful, _) = PathFinder::from_scene(
        &scene,
        &grid,
        CostParams {
            narrow_weight: 5.0,
            ..CostParams::default()
        },
    )
    .unwrap();
    let mut search = Search::new();
    let cells = plain.navigable_cells();
    let (mut clear_plain, mut clear_careful, mut n) = (0.0, 0.0, 0usize);
    for k in 0..10 {
        let s = cells[(k * 7919) % cells.len()] as usize;
        let g = cells[(k * 104_729 + 13) % cells.len()] as usize;
        let (Some(p), Some(c)) = (
            plain.plan_cells(&mut search, s, g),
            careful.plan_cells(&mut search, s, g),
        ) else {
            continue;
        };
        let mean = |pf: &PathFinder, cells: &[usize]| {
            cells.iter().map(|&k| pf.clearance[k].min(1.0)).sum::<f32>() / cells.len() as f32
        };
        clear_plain += mean(&plain, &p.cells);
        clear_careful += mean(&careful, &c.cells);
        n += 1;
    }
    assert!(n > 0);
    assert!(
        clear_careful > clear_plain,
        "{clear_careful} vs {clear_plain}"
    );
}

#[test]
fn endpoints_stand_beside_their_objects_at_a_safe_distance() {
    let scene = small_synth(6);
    let params = TrajectoryParams::default();
    let prep = trajectory::prepare(&scene, &params).unwrap();
    let counts = prep.endpoints.counts();
    assert!(counts.iter().all(|&c| c > 0), "{counts:?}");
    let sp = &params.sampling;
    // Every navigable cell keeps the safety margin beyond the radius.
    let pf = &prep.finder;
    let least = params.cost.robot_radius + params.cost.safety_margin;
    assert!(params.cost.safety_margin > 0.0);
    assert!((0..pf.passable.len()).all(|k| !pf.passable[k] || pf.clearance[k] >= least));
    let inner = sp.stand_max - sp.stand_slack;
    let mut inside_slack = 0;
    for e in &prep.endpoints.list {
        if e.kind != sage_nav::EndpointKind::Room {
            // Where a roomy cell lies within the slack of the band, every stand is one.
            let roomy_inside = (0..pf.roomy.len()).any(|k| {
                let p = pf.grid.center_of(k);
                let d = e.polygon.distance_to_boundary(p);
                pf.roomy[k] && !e.polygon.contains(p) && d >= sp.stand_min && d <= inner
            });
            if roomy_inside {
                inside_slack += 1;
                for s in &e.stands {
                    let d = e.polygon.distance_to_boundary(s.point);
                    assert!(
                        pf.roomy[s.cell] && d <= inner + 1e-4,
                        "{} at {d}",
                        e.reference
                    );
                }
            }
        }
        for s in &e.stands {
            assert!(prep.finder.passable[s.cell]);
            if e.kind != sage_nav::EndpointKind::Room {
                let d = e.polygon.distance_to_boundary(s.point);
                assert!(
                    d >= sp.stand_min - 1e-4 && d <= sp.stand_max + 1e-4,
                    "{} at {d}",
                    e.reference
                );
                let f = s.facing.unwrap();
                let to = (e.centre - s.point).normalize();
                assert!((Vec2::new(f.cos(), f.sin()) - to).length() < 1e-3);
            }
        }
    }
    assert!(inside_slack > 0);
    // Item ids of object endpoints are those of the semantic map, and nobody is sent to an
    // object hung above the agent (a ceiling lamp) though the scene has some.
    let map = SemanticMap::build(&scene);
    assert!(map.items.iter().any(|i| i.min_z > sp.max_object_base));
    for e in prep
        .endpoints
        .list
        .iter()
        .filter(|e| e.kind == sage_nav::EndpointKind::Object)
    {
        let item = map.item(&e.reference).unwrap();
        assert!(item.min_z <= sp.max_object_base, "{}", e.reference);
    }
    let _: &Endpoints = &prep.endpoints;
}

#[test]
fn room_endpoints_stand_at_the_room_centre() {
    let scene = small_synth(6);
    let params = TrajectoryParams::default();
    let prep = trajectory::prepare(&scene, &params).unwrap();
    let pf = &prep.finder;
    let radius = sage_nav::sampling::ROOM_CENTRE_RADIUS;
    let rooms: Vec<_> = prep
        .endpoints
        .list
        .iter()
        .filter(|e| e.kind == sage_nav::EndpointKind::Room)
        .collect();
    assert!(!rooms.is_empty());
    for e in rooms {
        let room: usize = e.reference["room_".len()..].parse().unwrap();
        // The roomy cells of the room, found here from the grid, and the one nearest the
        // centroid of its outline: every stand lies within the radius of it, and every roomy
        // cell within that radius is a stand.
        let roomy: Vec<usize> = (0..pf.passable.len())
            .filter(|&k| {
                pf.passable[k]
                    && pf.grid.rooms[k] as usize == room
                    && pf.clearance[k] >= params.sampling.room_clearance
            })
            .collect();
        // Only the island holding most of the room counts.
        let mut sizes = std::collections::BTreeMap::new();
        for &k in &roomy {
            *sizes.entry(pf.island_of_cell(k)).or_insert(0) += 1;
        }
        let most = *sizes.values().max().unwrap();
        let island = *sizes.iter().find(|(_, n)| **n == most).unwrap().0;
        let roomy: Vec<usize> = roomy
            .into_iter()
            .filter(|&k| pf.island_of_cell(k) == island)
            .collect();
        let centre = e.polygon.centroid();
        let middle = roomy
            .iter()
            .map(|&k| pf.grid.center_of(k))
            .min_by(|a, b| a.distance(centre).total_cmp(&b.distance(centre)))
            .unwrap();
        let near = roomy
            .iter()
            .filter(|&&k| pf.grid.center_of(k).distance(middle) <= radius)
            .count();
        assert_eq!(e.stands.len(), near, "{}", e.reference);
        for s in &e.stands {
            assert!(s.point.distance(middle) <= radius + 1e-4, "{}", e.reference);
            assert!(pf.clearance[s.cell] >= params.sampling.room_clearance);
        }
        // An agent that stops at the centre is within the success distance of every stand.
        assert!(e.stands.iter().all(|s| s.point.distance(middle) < 1.0));
    }
}

#[test]
fn item_ids_count_every_object_per_category() {
    let scene = small_synth(7);
    let map = SemanticMap::build(&scene);
    let mut seen = std::collections::BTreeMap::new();
    for (o, item) in scene.objects.iter().zip(&map.items) {
        let n = seen.entry(o.category.clone()).or_insert(0);
        *n += 1;
        assert_eq!(item.item_id, format!("{}_{}", o.category, n));
        // Mesh footprints hold every mesh vertex.
        let poly = item.footprint_polygon();
        for p in o.mesh.as_ref().unwrap().positions.iter().step_by(5) {
            let q = p.truncate();
            assert!(poly.contains(q) || poly.distance_to_boundary(q) < 1e-3);
        }
    }
}

#[test]
fn trajectories_are_deterministic_across_thread_counts_and_meet_the_rules() {
    let scene = small_synth(8);
    let params = TrajectoryParams {
        count: 30,
        seed: 11,
        ..TrajectoryParams::default()
    };
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let prep = trajectory::prepare(&scene, &params).unwrap();
            let (set, _) = trajectory::generate(&scene.name, &prep, &params).unwrap();
            serde_json::to_string(&set).unwrap()
        })
    };
    let one = run(1);
    assert_eq!(one, run(2));
    let set: trajectory::TrajectorySet = serde_json::from_str(&one).unwrap();
    assert_eq!(set.trajectories.len(), 30);
    let r = &set.report;
    assert_eq!(r.generated, 30);
    assert_eq!(
        r.candidates,
        r.generated
            + r.rejected_too_close
            + r.rejected_unreachable
            + r.rejected_too_short
            + r.rejected_bin_full
            + r.rejected_duplicate
    );
    assert_eq!(r.by_kinds.values().sum::<usize>(), 30);
    assert_eq!(r.by_length.values().sum::<usize>(), 30);
    let prep = trajectory::prepare(&scene, &params).unwrap();
    for t in &set.trajectories {
        let s = Vec2::new(t.start.point[0], t.start.point[1]);
        let g = Vec2::new(t.goal.point[0], t.goal.point[1]);
        assert!(s.distance(g) >= params.sampling.min_distance);
        assert!(t.length >= params.sampling.min_length);
        assert!(
            t.geodesic_distance <= t.length + 1e-4 && t.geodesic_distance >= s.distance(g) - 1e-3
        );
        assert_eq!(t.points.len(), t.headings.len());
        for w in t.points.windows(2) {
            let d = Vec2::new(w[1][0] - w[0][0], w[1][1] - w[0][1]).length();
            assert!(d <= params.step + 1e-3);
        }
        for p in &t.points {
            assert!(
                prep.finder.is_navigable(Vec2::new(p[0], p[1])),
                "point off the navigable grid"
            );
            assert_eq!(p[2], 0.0);
        }
    }
    // Another seed, other trajectories.
    let other = TrajectoryParams {
        seed: 12,
        ..params.clone()
    };
    let (set2, _) = trajectory::generate(&scene.name, &prep, &other).unwrap();
    assert_ne!(set2.trajectories, set.trajectories);
    // Asked for more trajectories than the scene has distinct routes to spare, sampling draws
    // routes again: none is taken twice.
    let many = TrajectoryParams {
        count: 150,
        ..params.clone()
    };
    let (set3, _) = trajectory::generate(&scene.name, &prep, &many).unwrap();
    assert!(set3.report.rejected_duplicate > 0, "{:?}", set3.report);
    let routes: std::collections::HashSet<(&str, &str, Vec<[u32; 3]>)> = set3
        .trajectories
        .iter()
        .map(|t| {
            let points = t.points.iter().map(|p| p.map(f32::to_bits)).collect();
            (
                t.start.reference.as_str(),
                t.goal.reference.as_str(),
                points,
            )
        })
        .collect();
    assert_eq!(routes.len(), set3.trajectories.len());
}

#[test]
fn a_length_mix_caps_each_bin() {
    let scene = small_synth(9);
    let mut params = TrajectoryParams {
        count: 20,
        seed: 3,
        ..TrajectoryParams::default()
    };
    params.sampling.length_edges = vec![5.0];
    params.sampling.length_mix = Some(vec![0.5, 0.5]);
    let prep = trajectory::prepare(&scene, &params).unwrap();
    let (set, _) = trajectory::generate(&scene.name, &prep, &params).unwrap();
    for n in set.report.by_length.values() {
        assert!(*n <= 10, "{:?}", set.report.by_length);
    }
}

#[test]
fn a_run_writes_resumes_and_reports_skips() {
    let root = tempfile::tempdir().unwrap();
    let scenes = root.path().join("scenes");
    let good = scenes.join("a_good");
    small_synth(10)
        .save(&good, sage_scene::SplatLayout::Standard)
        .unwrap();
    // A scene whose only room is filled by one object: no navigable space.
    let bad = room_scene(
        vec![object(
            "block",
            None,
            obb_of(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(7.0, 5.0, 1.0)),
        )],
        vec![],
    );
    let bad_dir = scenes.join("b_blocked");
    bad.save(&bad_dir, sage_scene::SplatLayout::Standard)
        .unwrap_or_else(|_| {
            std::fs::create_dir_all(&bad_dir).unwrap();
        });
    let dirs = sage_io::scenes::scene_dirs(&scenes).unwrap();
    assert_eq!(dirs.len(), 2);
    let params = TrajectoryParams {
        count: 5,
        seed: 1,
        ..TrajectoryParams::default()
    };
    let out = root.path().join("out");
    let first = trajectory::run_scene(&good, &out.join("a_good"), &params);
    assert_eq!(first.status, Status::Done, "{:?}", first.reason);
    let bytes = std::fs::read(out.join("a_good").join(trajectory::TRAJECTORIES_FILE)).unwrap();
    assert!(
        out.join("a_good")
            .join(trajectory::TRAJECTORIES_PNG)
            .is_file()
    );
    let again = trajectory::run_scene(&good, &out.join("a_good"), &params);
    assert_eq!(again.status, Status::Resumed);
    assert_eq!(
        std::fs::read(out.join("a_good").join(trajectory::TRAJECTORIES_FILE)).unwrap(),
        bytes
    );
    // Other settings: the scene is redone.
    let more = TrajectoryParams {
        count: 6,
        ..params.clone()
    };
    assert_eq!(
        trajectory::run_scene(&good, &out.join("a_good"), &more).status,
        Status::Done
    );
    let skipped = trajectory::run_scene(&bad_dir, &out.join("b_blocked"), &params);
    assert_eq!(skipped.status, Status::Skipped);
    assert!(skipped.reason.unwrap().contains("no navigable space"));
    assert!(
        !out.join("b_blocked")
            .join(trajectory::TRAJECTORIES_FILE)
            .exists()
    );
}

#[test]
fn a_rerun_makes_an_edited_scene_again_and_keeps_an_unchanged_one() {
    let root = tempfile::tempdir().unwrap();
    let scene = root.path().join("home");
    small_synth(10)
        .save(&scene, sage_scene::SplatLayout::Standard)
        .unwrap();
    let params = TrajectoryParams {
        count: 3,
        seed: 4,
        ..TrajectoryParams::default()
    };
    let out = root.path().join("out");
    let file = out.join(trajectory::TRAJECTORIES_FILE);
    let read = || -> trajectory::TrajectorySet {
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap()
    };
    let first = trajectory::run_scene(&scene, &out, &params);
    assert_eq!(first.status, Status::Done, "{:?}", first.reason);
    assert_eq!(read().inputs, sage_io::scenes::input_hashes(&scene));
    assert!(read().inputs.contains_key("labels.json"));
    assert_eq!(
        trajectory::run_scene(&scene, &out, &params).status,
        Status::Resumed
    );
    // The same settings over an edited scene: the file is made again, from the scene as it is
    // now, and says so in its hashes (and so does the outcome, which the run record lists).
    let labels = scene.join("labels.json");
    let text = std::fs::read_to_string(&labels).unwrap();
    let value: serde_json::Value = serde_json::from_str(&text).unwrap();
    std::fs::write(
        &labels,
        serde_json::to_string_pretty(&value).unwrap() + "\n",
    )
    .unwrap();
    let edited = sage_io::scenes::input_hashes(&scene);
    assert_ne!(edited, first.inputs);
    let again = trajectory::run_scene(&scene, &out, &params);
    assert_eq!(again.status, Status::Done, "{:?}", again.reason);
    assert_eq!(again.inputs, edited);
    assert_eq!(read().inputs, edited);
    assert_eq!(
        trajectory::run_scene(&scene, &out, &params).status,
        Status::Resumed
    );
    // A file written before the hashes were recorded cannot tell what it was made from: made
    // again.
    let mut old: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    old.as_object_mut().unwrap().remove("inputs");
    std::fs::write(&file, old.to_string()).unwrap();
    assert!(read().inputs.is_empty());
    assert_eq!(
        trajectory::run_scene(&scene, &out, &params).status,
        Status::Done
    );
    assert_eq!(read().inputs, edited);
}

#[test]
fn scene_folders_without_plain_names_are_refused_by_name() {
    let root = tempfile::tempdir().unwrap();
    let plain = root.path().join("home_1.b");
    let spaced = root.path().join("My Home");
    trajectory::check_scene_names(std::slice::from_ref(&plain)).unwrap();
    let e = trajectory::check_scene_names(&[plain, spaced.clone()])
        .unwrap_err()
        .to_string();
    assert!(e.contains(&spaced.display().to_string()), "{e}");
    assert!(
        e.contains("'My Home'") && e.contains("rename the folder"),
        "{e}"
    );
}

#[test]
fn an_object_outside_the_map_is_clipped_not_a_panic() {
    let far = object(
        "crate",
        None,
        obb_of(Vec3::new(50.0, 50.0, 0.0), Vec3::new(51.0, 51.0, 1.0)),
    );
    let partly = object(
        "bench",
        None,
        obb_of(Vec3::new(-2.0, 1.0, 0.0), Vec3::new(0.5, 1.5, 0.5)),
    );
    let scene = room_scene(vec![far, partly], vec![]);
    let (g, _) = NavGrid::from_scene(&scene, &GridParams::default()).unwrap();
    assert_eq!(cell_value(&g, Vec2::new(0.3, 1.2)), OCCUPIED);
    let pf = PathFinder::new(g, &scene.floorplan, CostParams::default()).unwrap();
    let map = SemanticMap::build(&scene);
    let eps = Endpoints::collect(&map, &pf, &Default::default());
    assert!(
        eps.list.iter().all(|e| e.reference != "crate_1"),
        "an object off the map has no stand point"
    );
}

#[test]
fn a_grid_too_large_names_the_part_that_stretches_it() {
    // One wall 9 km off, the rest a 6 x 4 m room: 180000 x 180000 cells of 5 cm.
    let far = Wall {
        start: Vec2::new(0.0, 9000.0),
        end: Vec2::new(9000.0, 9000.0),
        thickness: 0.1,
        height: 2.8,
    };
    let scene = room_scene(vec![], vec![far]);
    let e = NavGrid::from_scene(&scene, &GridParams::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("scene hand: a ") && e.contains("grid is too large"),
        "{e}"
    );
    assert!(
        e.contains("it reaches farthest at structure.json walls[4], which spans x "),
        "{e}"
    );
}

#[test]
fn a_map_of_an_object_reaching_kilometres_away_is_drawn_within_the_grid() {
    // A mesh reaching to the coordinate bound: its footprint is kilometres across, the map
    // only the room's; drawing costs the map's pixels, not the footprint's.
    let mesh = box_mesh(Vec3::new(1.0, 1.0, 0.0), Vec3::new(1e4, 1e4, 1.0));
    let scene = room_scene(
        vec![object(
            "sofa",
            Some(mesh),
            obb_of(Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, 2.0, 1.0)),
        )],
        vec![],
    );
    let (g, _) = NavGrid::from_scene(&scene, &GridParams::default()).unwrap();
    let (canvas, map_width) = SemanticMap::build(&scene).draw(&g, &[]);
    assert!(map_width >= g.width && canvas.height >= g.height);
    // The footprint covers the room's upper right corner.
    let (x, y) = (map_width - 2, 1);
    let k = (y * canvas.width + x) * 3;
    assert_eq!(
        canvas.rgb[k..k + 3],
        sage_io::canvas::palette(0),
        "the footprint is drawn in the colour of its category, the only one"
    );
}

#[test]
fn grid_params_refuse_heights_that_make_no_slab() {
    GridParams::default().validate().unwrap();
    for height in [f32::INFINITY, f32::NAN, 0.03, 0.0, -1.0] {
        let params = GridParams {
            agent_height: height,
            ..GridParams::default()
        };
        let e = params.validate().unwrap_err().to_string();
        assert!(
            e.contains("`agent_height` must be a finite height"),
            "{height}: {e}"
        );
    }
    let params = GridParams {
        slab_bottom: f32::INFINITY,
        ..GridParams::default()
    };
    assert!(
        params
            .validate()
            .unwrap_err()
            .to_string()
            .contains("slab bottom")
    );
}
