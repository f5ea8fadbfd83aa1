//! The synthetic scene generator: determinism, structure (rooms, walls, doors, windows), objects
//! (categories, placement, meshes, attributes), Gaussians (count, coverage, view dependence,
//! instances) and the occupancy map.

use glam::Vec2;
use sage_scene::occupancy::{FREE, OCCUPIED, UNKNOWN};
use sage_scene::vocabulary::color_rgb;
use sage_scene::{DoorState, Hole, HoleKind, Scene};
use sage_synth::{SceneKind, SynthConfig, generate};
use std::collections::BTreeSet;

fn config(
    kind: SceneKind,
    seed: u64,
    rooms: usize,
    objects: usize,
    gaussians: usize,
) -> SynthConfig {
    SynthConfig {
        seed,
        kind,
        rooms,
        objects,
        gaussians,
        ..SynthConfig::default()
    }
}

fn small(kind: SceneKind, seed: u64) -> Scene {
    generate(&config(kind, seed, 4, 40, 30_000)).unwrap()
}

/// The representative of `i`'s group in a union-find forest.
fn root(group: &mut [usize], i: usize) -> usize {
    let mut r = i;
    while group[r] != r {
        r = group[r];
    }
    group[i] = r;
    r
}

/// The centre of a hole on the floor and the unit normal of its wall.
fn hole_frame(h: &Hole) -> (Vec2, Vec2) {
    let (lo, hi) = h.bounds();
    let centre = ((lo + hi) * 0.5).truncate();
    let along = (h.profile[1] - h.profile[0]).truncate().normalize();
    (centre, along.perp())
}

#[test]
fn same_seed_gives_the_same_scene_and_another_seed_another() {
    let a = small(SceneKind::Home, 7);
    let b = small(SceneKind::Home, 7);
    assert_eq!(a, b);
    assert_eq!(a.name, "synth_home_s7");
    let c = small(SceneKind::Home, 8);
    assert_ne!(a.gaussians, c.gaussians);
    assert_ne!(a.objects, c.objects);
}

#[test]
fn thread_count_does_not_change_the_scene() {
    let cfg = config(SceneKind::Office, 3, 4, 40, 30_000);
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| generate(&cfg).unwrap())
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn every_kind_generates_its_room_types() {
    let types = |kind| -> &[&str] {
        match kind {
            SceneKind::Home => &[
                "Living Room",
                "Kitchen",
                "Bedroom",
                "Master Bedroom",
                "Bathroom",
                "Dining Room",
                "Study",
                "Corridor",
            ],
            SceneKind::Office => &[
                "Open Office",
                "Meeting Room",
                "Manager Office",
                "Pantry",
                "Reception",
            ],
            SceneKind::Shop => &["Sales Floor", "Storage Room", "Checkout", "Fitting Room"],
        }
    };
    for kind in SceneKind::ALL {
        for rooms in [1, 3, 7] {
            let s = generate(&config(kind, 11, rooms, 10 * rooms, 20_000)).unwrap();
            assert_eq!(s.name, format!("synth_{}_s11", kind.as_str()));
            assert_eq!(s.floorplan.rooms.len(), rooms, "{kind} {rooms}");
            for r in &s.floorplan.rooms {
                assert!(
                    types(kind).contains(&r.room_type.as_str()),
                    "{kind}: {}",
                    r.room_type
                );
                let (lo, hi) = r.profile.bounds();
                assert!(
                    (hi - lo).min_element() >= 2.39,
                    "{kind}: room {:?} is too narrow",
                    hi - lo
                );
            }
            assert!(s.floorplan.windows().count() > 0, "{kind} {rooms}");
            assert!(s.occupancy.is_some() && s.structure_mesh.is_some());
        }
    }
}

#[test]
fn the_main_room_is_the_largest_and_bathrooms_are_small() {
    let s = generate(&config(SceneKind::Home, 5, 8, 60, 20_000)).unwrap();
    let area = |t: &str| {
        s.floorplan
            .rooms
            .iter()
            .filter(|r| r.room_type == t)
            .map(|r| r.profile.area())
            .collect::<Vec<_>>()
    };
    let largest = s
        .floorplan
        .rooms
        .iter()
        .map(|r| r.profile.area())
        .fold(0.0, f32::max);
    assert_eq!(area("Living Room"), vec![largest]);
    let bathrooms = area("Bathroom");
    assert!(!bathrooms.is_empty());
    let others = s
        .floorplan
        .rooms
        .iter()
        .filter(|r| r.room_type != "Bathroom")
        .map(|r| r.profile.area());
    assert!(others.fold(f32::INFINITY, f32::min) >= bathrooms.iter().copied().fold(0.0, f32::max));
}

#[test]
fn twenty_categories_across_the_three_kinds() {
    let mut categories = BTreeSet::new();
    for kind in SceneKind::ALL {
        let s = generate(&config(kind, 1, 5, 60, 20_000)).unwrap();
        categories.extend(s.objects.iter().map(|o| o.category.clone()));
    }
    assert!(
        categories.len() >= 20,
        "{} categories: {categories:?}",
        categories.len()
    );
    for c in [
        "door",
        "window",
        "bed",
        "sofa",
        "desk",
        "plant",
        "ceiling_lamp",
        "shelving_unit",
        "meeting_table",
    ] {
        assert!(categories.contains(c), "no {c} in {categories:?}");
    }
}

#[test]
fn walls_do_not_overlap_and_openings_sit_in_walls() {
    for kind in SceneKind::ALL {
        let s = small(kind, 21);
        let fp = &s.floorplan;
        // A wall as (runs along x, centre-line coordinate, extent along its direction).
        let line = |w: &sage_scene::Wall| {
            let along_x = (w.start.y - w.end.y).abs() < 1e-6;
            let (c, a, b) = if along_x {
                (w.start.y, w.start.x, w.end.x)
            } else {
                (w.start.x, w.start.y, w.end.y)
            };
            (along_x, c, a.min(b), a.max(b))
        };
        for (i, a) in fp.walls.iter().enumerate() {
            assert!(a.height == 2.8 && (a.thickness == 0.2 || a.thickness == 0.1));
            let (ax, ac, a0, a1) = line(a);
            for b in &fp.walls[i + 1..] {
                let (bx, bc, b0, b1) = line(b);
                let shared = a1.min(b1) - a0.max(b0);
                assert!(
                    ax != bx || (ac - bc).abs() > 1e-4 || shared < 1e-4,
                    "walls {a:?} and {b:?} overlap"
                );
            }
        }
        for h in &fp.holes {
            assert_eq!(h.profile.len(), 4);
            let (lo, hi) = h.bounds();
            let (centre, _) = hole_frame(h);
            let wall = fp
                .walls
                .iter()
                .find(|w| w.obb().contains(centre.extend(1.0), 1e-3));
            let wall = wall.unwrap_or_else(|| panic!("hole at {centre} is in no wall"));
            assert!((h.thickness - wall.thickness).abs() < 1e-6);
            match h.kind {
                HoleKind::Door => {
                    assert!(lo.z == 0.0 && (hi.z - 2.05).abs() < 1e-4);
                    assert!(h.state.is_some());
                    assert!((0.85..=1.15).contains(&(hi - lo).truncate().length()));
                }
                HoleKind::Window => assert!(lo.z >= 0.8 && hi.z <= 2.2 && h.state.is_none()),
            }
        }
    }
}

#[test]
fn every_door_state_occurs_and_door_objects_match_their_holes() {
    let s = generate(&config(SceneKind::Home, 4, 7, 50, 20_000)).unwrap();
    let states: BTreeSet<&str> = s
        .floorplan
        .doors()
        .filter_map(|h| h.state)
        .map(DoorState::as_str)
        .collect();
    assert_eq!(states.len(), 3, "{states:?}");
    let open = s
        .floorplan
        .doors()
        .filter(|h| h.state == Some(DoorState::Open))
        .count();
    assert!(
        2 * open > s.floorplan.doors().count(),
        "most doors are open"
    );
    let mut leaves: Vec<&str> = s
        .objects
        .iter()
        .filter(|o| o.category == "door")
        .filter_map(|o| o.attributes.state.as_deref())
        .collect();
    let mut holes: Vec<&str> = s
        .floorplan
        .doors()
        .filter_map(|h| h.state)
        .map(DoorState::as_str)
        .collect();
    leaves.sort_unstable();
    holes.sort_unstable();
    assert_eq!(leaves, holes);
    for o in s.objects.iter().filter(|o| o.category == "door") {
        assert_eq!(o.role, sage_scene::PhysicsRole::Articulated);
        assert!(o.door_state().is_some());
    }
}

#[test]
fn every_room_is_reachable_through_doors() {
    for kind in SceneKind::ALL {
        for seed in 0..6 {
            let s = generate(&config(kind, seed, 3 + seed as usize * 2, 20, 5_000)).unwrap();
            let fp = &s.floorplan;
            let n = fp.rooms.len();
            let mut group: Vec<usize> = (0..n).collect();
            for h in fp.doors() {
                let (c, normal) = hole_frame(h);
                let reach = h.thickness * 0.5 + 0.2;
                if let (Some(a), Some(b)) = (
                    fp.room_at(c + normal * reach),
                    fp.room_at(c - normal * reach),
                ) {
                    let (ra, rb) = (root(&mut group, a), root(&mut group, b));
                    group[ra] = rb;
                }
            }
            let first = root(&mut group, 0);
            for i in 0..n {
                assert_eq!(
                    root(&mut group, i),
                    first,
                    "{kind} seed {seed}: room {i} ({}) is cut off",
                    fp.rooms[i].room_type
                );
            }
        }
    }
}

#[test]
fn objects_do_not_overlap_and_small_items_stand_on_supports() {
    for kind in SceneKind::ALL {
        let s = generate(&config(kind, 2, 6, 120, 20_000)).unwrap();
        let objects = &s.objects;
        for (i, a) in objects.iter().enumerate() {
            for b in &objects[i + 1..] {
                assert!(
                    !a.obb.overlaps(&b.obb, -1e-3),
                    "{kind}: {} {} overlaps {} {}",
                    a.category,
                    a.ins_id,
                    b.category,
                    b.ins_id
                );
            }
        }
        let stacked = [
            "cup",
            "book",
            "laptop",
            "vase",
            "monitor",
            "tv",
            "table_lamp",
            "microwave",
            "cash_register",
        ];
        for o in objects
            .iter()
            .filter(|o| stacked.contains(&o.category.as_str()))
        {
            let support = objects.iter().find(|p| {
                (p.obb.max_z() - o.obb.min_z()).abs() < 1e-4
                    && p.obb
                        .contains(o.obb.center.truncate().extend(p.obb.center.z), 0.0)
            });
            assert!(
                support.is_some(),
                "{kind}: {} {} floats at z {}",
                o.category,
                o.ins_id,
                o.obb.min_z()
            );
        }
        for o in objects.iter().filter(|o| o.category == "ceiling_lamp") {
            assert!((o.obb.max_z() - 2.8).abs() < 1e-4);
        }
        for o in objects.iter().filter(|o| {
            !["ceiling_lamp", "painting", "mirror", "whiteboard", "window"]
                .contains(&o.category.as_str())
        }) {
            assert!(
                o.obb.min_z() < 1e-4 || stacked.contains(&o.category.as_str()),
                "{} {} does not stand",
                o.category,
                o.ins_id
            );
        }
    }
}

#[test]
fn the_object_target_is_respected_and_grows_the_scene() {
    let few = generate(&config(SceneKind::Home, 6, 4, 30, 10_000)).unwrap();
    let structural = few
        .objects
        .iter()
        .filter(|o| ["door", "window"].contains(&o.category.as_str()))
        .count();
    assert!(
        few.objects.len() <= 30.max(structural),
        "{} objects",
        few.objects.len()
    );
    let more = generate(&config(SceneKind::Home, 6, 8, 120, 10_000)).unwrap();
    assert!(
        more.objects.len() > few.objects.len() + 40,
        "{} vs {}",
        more.objects.len(),
        few.objects.len()
    );
}

#[test]
fn objects_have_ids_attributes_and_physics() {
    let s = small(SceneKind::Home, 12);
    let ids: BTreeSet<&str> = s.objects.iter().map(|o| o.ins_id.as_str()).collect();
    assert_eq!(ids.len(), s.objects.len());
    for (i, o) in s.objects.iter().enumerate() {
        assert!(o.ins_id.parse::<u32>().is_ok());
        assert_eq!(o.id.0 as usize, i + 1);
        assert_eq!(o.category, sage_scene::object::normalize_category(&o.label));
        let a = &o.attributes;
        let color = a.color.as_deref().unwrap_or_default();
        assert!(
            color_rgb(color).is_some(),
            "{} has colour '{color}'",
            o.category
        );
        assert!(a.material.is_some() && a.size.is_some(), "{}", o.category);
        assert!(o.rigid_body.mass > 0.0 && o.rigid_body.friction > 0.0);
    }
}

#[test]
fn meshes_lie_in_their_boxes_and_furniture_is_concave() {
    let s = generate(&config(SceneKind::Home, 3, 8, 100, 10_000)).unwrap();
    let mut concave = BTreeSet::new();
    for o in &s.objects {
        let mesh = o
            .mesh
            .as_ref()
            .unwrap_or_else(|| panic!("{} has no mesh", o.category));
        mesh.validate().unwrap();
        assert!(!mesh.triangles.is_empty());
        for p in &mesh.positions {
            assert!(
                o.obb.contains(*p, 1e-3),
                "{} {}: vertex {p} outside its box",
                o.category,
                o.ins_id
            );
        }
        let v = mesh.signed_volume();
        assert!(v > 0.0, "{} {}: mesh faces inwards", o.category, o.ins_id);
        if ["dining_table", "coffee_table", "chair", "desk", "bookshelf"]
            .contains(&o.category.as_str())
        {
            assert!(
                v < 0.6 * o.obb.volume(),
                "{}: volume {v} vs box {}",
                o.category,
                o.obb.volume()
            );
            concave.insert(o.category.as_str());
        }
    }
    assert!(
        concave.contains("chair") && concave.contains("dining_table"),
        "{concave:?}"
    );
}

#[test]
fn gaussians_are_finite_view_dependent_and_on_budget() {
    for kind in SceneKind::ALL {
        let s = generate(&config(kind, 5, 4, 40, 25_000)).unwrap();
        let g = &s.gaussians;
        assert_eq!(g.len(), 25_000, "the budget is met exactly");
        g.validate().unwrap();
        assert!(g.sh_degree() >= 1);
        let (lo, hi) =
            s.floorplan
                .rooms
                .iter()
                .fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), r| {
                    let (a, b) = r.profile.bounds();
                    (lo.min(a), hi.max(b))
                });
        let mut with_highlight = 0;
        for i in 0..g.len() {
            let x = g.get(i);
            let p = x.position;
            assert!(p.is_finite() && x.log_scale.is_finite() && x.opacity_logit.is_finite());
            assert!(
                p.truncate().cmpge(lo - Vec2::splat(0.11)).all()
                    && p.truncate().cmple(hi + Vec2::splat(0.11)).all(),
                "{p}"
            );
            assert!(p.z >= -1e-4 && p.z <= 2.8 + 1e-4, "{p}");
            assert!(
                x.log_scale.z < x.log_scale.x && x.log_scale.z < x.log_scale.y,
                "flat discs"
            );
            if x.sh_rest[..3].iter().flatten().any(|c| *c != 0.0) {
                with_highlight += 1;
            }
        }
        assert_eq!(with_highlight, g.len());
        let opaque = (0..g.len())
            .filter(|&i| (2.5..=4.0).contains(&g.opacity_logit(i)))
            .count();
        assert!(opaque as f64 > 0.9 * g.len() as f64);
    }
}

#[test]
fn floors_are_covered_without_holes() {
    let s = generate(&config(SceneKind::Home, 9, 2, 12, 100_000)).unwrap();
    let g = &s.gaussians;
    let cell = 0.1;
    for (index, room) in s.floorplan.rooms.iter().enumerate() {
        let (lo, hi) = room.profile.bounds();
        let (lo, hi) = (lo + Vec2::splat(0.15), hi - Vec2::splat(0.15));
        let (nx, ny) = (
            ((hi.x - lo.x) / cell) as usize,
            ((hi.y - lo.y) / cell) as usize,
        );
        let mut hit = vec![false; nx * ny];
        for p in &g.positions {
            let q = (Vec2::new(p[0], p[1]) - lo) / cell;
            if p[2].abs() < 1e-3
                && q.x >= 0.0
                && q.y >= 0.0
                && (q.x as usize) < nx
                && (q.y as usize) < ny
            {
                hit[q.y as usize * nx + q.x as usize] = true;
            }
        }
        let empty = hit.iter().filter(|h| !**h).count();
        assert_eq!(
            empty,
            0,
            "room {index}: {empty} of {} floor cells hold no Gaussian",
            hit.len()
        );
    }
}

#[test]
fn nearly_every_gaussian_belongs_to_an_instance() {
    let s = small(SceneKind::Shop, 14);
    let assigned = s.gaussians.instances.iter().filter(|&&i| i != 0).count();
    assert!(
        assigned as f64 >= 0.9 * s.gaussians.len() as f64,
        "{assigned} of {}",
        s.gaussians.len()
    );
    let objects = s
        .gaussians
        .instances
        .iter()
        .filter(|&&i| i != 0 && (i as usize) <= s.objects.len())
        .count();
    assert!(
        objects > s.gaussians.len() / 10,
        "objects hold {objects} Gaussians"
    );
}

#[test]
fn rendered_colours_match_the_colour_words() {
    let s = generate(&config(SceneKind::Home, 8, 6, 80, 60_000)).unwrap();
    let g = &s.gaussians;
    let mut checked = 0;
    for o in s.objects.iter().filter(|o| {
        [
            "wardrobe",
            "refrigerator",
            "sofa",
            "kitchen_cabinet",
            "dresser",
        ]
        .contains(&o.category.as_str())
    }) {
        let mut channels: [Vec<f32>; 3] = Default::default();
        for i in 0..g.len() {
            if g.instances[i] == o.id.0 && g.positions[i][2] > 0.03 {
                let c = g.get(i).base_color();
                for k in 0..3 {
                    channels[k].push(c[k]);
                }
            }
        }
        let Some(want) = o.attributes.color.as_deref().and_then(color_rgb) else {
            continue;
        };
        for (k, mut values) in channels.into_iter().enumerate() {
            values.sort_by(f32::total_cmp);
            let median = values[values.len() / 2];
            assert!(
                (median - want[k]).abs() < 0.12,
                "{} {}: channel {k} {median} vs {:?}",
                o.category,
                o.attributes.color.as_deref().unwrap_or(""),
                want
            );
        }
        checked += 1;
    }
    assert!(checked >= 3, "only {checked} objects checked");
}

#[test]
fn the_occupancy_map_blocks_walls_furniture_and_closed_doors() {
    let s = generate(&config(SceneKind::Home, 4, 7, 50, 10_000)).unwrap();
    let map = s.occupancy.as_ref().unwrap();
    assert_eq!(map.scale, 0.05);
    let (free, occupied, unknown) = map.counts();
    assert!(
        free > 0 && occupied > 0 && unknown > 0,
        "{free} {occupied} {unknown}"
    );
    assert!(
        map.cells
            .iter()
            .all(|&c| c == FREE || c == OCCUPIED || c == UNKNOWN)
    );
    let at = |p: Vec2| map.cell_at(p).map(|(c, r)| map.get(c, r));
    let mut seen = BTreeSet::new();
    for h in s.floorplan.doors() {
        let (centre, _) = hole_frame(h);
        let want = if h.state == Some(DoorState::Open) {
            FREE
        } else {
            OCCUPIED
        };
        assert_eq!(at(centre), Some(want), "{:?} door at {centre}", h.state);
        seen.insert(h.state.map(DoorState::as_str));
    }
    assert_eq!(seen.len(), 3);
    for o in s
        .objects
        .iter()
        .filter(|o| ["bed", "wardrobe", "sofa"].contains(&o.category.as_str()))
    {
        assert_eq!(
            at(o.obb.center.truncate()),
            Some(OCCUPIED),
            "{}",
            o.category
        );
    }
    for o in s.objects.iter().filter(|o| o.category == "ceiling_lamp") {
        let under = o.obb.center.truncate();
        let blocked = s
            .objects
            .iter()
            .any(|p| p.obb.min_z() < 1.2 && p.obb.contains(under.extend(p.obb.center.z), 0.06));
        if !blocked {
            assert_eq!(
                at(under),
                Some(FREE),
                "the floor under a ceiling lamp is free"
            );
        }
    }
    let corner = map.cell_center(0, 0);
    assert_eq!(at(corner), Some(UNKNOWN));
}

#[test]
fn invalid_configs_are_errors() {
    let base = SynthConfig::default();
    let bad = [
        SynthConfig {
            rooms: 0,
            ..base.clone()
        },
        SynthConfig {
            rooms: 65,
            ..base.clone()
        },
        SynthConfig {
            gaussians: 10,
            ..base.clone()
        },
        SynthConfig {
            objects: 100_000,
            ..base.clone()
        },
        SynthConfig {
            wall_height: f32::NAN,
            ..base.clone()
        },
        SynthConfig {
            wall_height: 1.0,
            ..base.clone()
        },
        SynthConfig {
            cell: 0.0,
            ..base.clone()
        },
        SynthConfig {
            cell: f32::INFINITY,
            ..base.clone()
        },
    ];
    for cfg in bad {
        let e = generate(&cfg).unwrap_err();
        assert!(e.to_string().contains("synth:"), "{e}");
    }
    assert!(base.validate().is_ok());
    assert_eq!("Office".parse::<SceneKind>().unwrap(), SceneKind::Office);
    assert_eq!(" shop ".parse::<SceneKind>().unwrap(), SceneKind::Shop);
    assert!("castle".parse::<SceneKind>().is_err());
    for k in SceneKind::ALL {
        assert_eq!(k.as_str().parse::<SceneKind>().unwrap(), k);
    }
}

#[test]
fn odd_but_valid_configs_generate() {
    for cfg in [
        config(SceneKind::Home, u64::MAX, 1, 0, 1_000),
        config(SceneKind::Shop, 1, 2, 5000, 1_000),
        SynthConfig {
            wall_height: 2.4,
            cell: 0.5,
            ..config(SceneKind::Office, 2, 3, 30, 2_000)
        },
        SynthConfig {
            wall_height: 5.0,
            cell: 0.02,
            ..config(SceneKind::Home, 3, 3, 30, 2_000)
        },
    ] {
        let s = generate(&cfg).unwrap();
        assert_eq!(s.gaussians.len(), cfg.gaussians);
        s.gaussians.validate().unwrap();
    }
}

/// The large configuration: 16 rooms, 200–600 objects and the full 1M-Gaussian budget.
#[test]
fn large_home_is_full() {
    let cfg = config(SceneKind::Home, 0, 16, 400, 1_000_000);
    let s = generate(&cfg).unwrap();
    let categories: BTreeSet<&str> = s.objects.iter().map(|o| o.category.as_str()).collect();
    assert!(categories.len() >= 20, "{} categories", categories.len());
    assert_eq!(s.floorplan.rooms.len(), 16);
    assert!(
        (200..=600).contains(&s.objects.len()),
        "{} objects",
        s.objects.len()
    );
    assert_eq!(s.gaussians.len(), 1_000_000);
}
