//! Agents against known geometry: a room with walls, a doorway, a table and a movable box, built
//! by hand so every expected position has an exact oracle; and a synthetic scene's doors.

use glam::{Vec2, Vec3};
use sage_core::{InstanceId, Obb, Polygon2, Pose};
use sage_physics::agent::{PENETRATION_EPSILON, SKIN, STUCK_STEPS};
use sage_physics::{
    AgentBody, AgentProfile, Command, Decomposer, HullCache, SceneBodies, World, WorldOptions,
};
use sage_scene::{
    Attributes, DoorState, Floorplan, Gaussians, Hole, HoleKind, InstanceKind, Object, PhysicsRole,
    RigidBody, Room, Scene, Wall,
};

const T: f32 = 0.1;

fn wall(a: (f32, f32), b: (f32, f32)) -> Wall {
    Wall {
        start: Vec2::new(a.0, a.1),
        end: Vec2::new(b.0, b.1),
        thickness: T,
        height: 2.8,
    }
}

fn object(label: &str, center: Vec3, half: Vec3, yaw: f32, role: PhysicsRole) -> Object {
    Object {
        id: InstanceId::NONE,
        ins_id: label.to_string(),
        label: label.to_string(),
        category: label.to_string(),
        obb: Obb {
            center,
            half_extents: half,
            yaw,
        },
        room: None,
        attributes: Attributes::default(),
        role,
        rigid_body: RigidBody::default(),
        mesh: None,
        body: None,
    }
}

/// A 10 × 4 m hall: outer walls on x = 0, 10 and y = 0, 4, a partition on x = 6 with a 1 m
/// doorway (y 1.5–2.5, 2.1 m high), a table at (3, 3) and a movable box at (2, 0.7).
fn hall(door: Option<DoorState>) -> Scene {
    let mut objects = vec![
        object(
            "table",
            Vec3::new(3.0, 3.0, 0.375),
            Vec3::new(0.5, 0.5, 0.375),
            0.0,
            PhysicsRole::Static,
        ),
        object(
            "box",
            Vec3::new(2.0, 0.7, 0.2),
            Vec3::splat(0.2),
            0.0,
            PhysicsRole::Movable,
        ),
    ];
    if let Some(state) = door {
        // The leaf hinged at (6, 1.5): closed it spans the doorway, open it stands
        // perpendicular to the partition along the jamb, half-open at 45°.
        let yaw = std::f32::consts::FRAC_PI_2 - state.swing_angle();
        let (s, c) = yaw.sin_cos();
        let hinge = Vec2::new(6.0 - T * 0.5 - 0.03, 1.52);
        let centre = hinge + Vec2::new(c, s) * 0.48;
        let mut leaf = object(
            "door",
            centre.extend(1.03),
            Vec3::new(0.48, 0.02, 1.03),
            yaw,
            PhysicsRole::Articulated,
        );
        leaf.attributes.state = Some(state.as_str().to_string());
        objects.push(leaf);
    }
    let room = |x0: f32, x1: f32| Room {
        profile: Polygon2::new(vec![
            Vec2::new(x0, 0.0),
            Vec2::new(x1, 0.0),
            Vec2::new(x1, 4.0),
            Vec2::new(x0, 4.0),
        ]),
        room_type: "Hall".into(),
    };
    let mut scene = Scene {
        name: "hall".into(),
        gaussians: Gaussians::new(0).unwrap(),
        objects,
        floorplan: Floorplan {
            rooms: vec![room(0.0, 6.0), room(6.0, 10.0)],
            walls: vec![
                wall((0.0, 0.0), (10.0, 0.0)),
                wall((10.0, 0.0), (10.0, 4.0)),
                wall((10.0, 4.0), (0.0, 4.0)),
                wall((0.0, 4.0), (0.0, 0.0)),
                wall((6.0, 0.0), (6.0, 4.0)),
            ],
            holes: vec![Hole {
                profile: vec![
                    Vec3::new(6.0, 1.5, 0.0),
                    Vec3::new(6.0, 2.5, 0.0),
                    Vec3::new(6.0, 2.5, 2.1),
                    Vec3::new(6.0, 1.5, 2.1),
                ],
                thickness: T,
                kind: HoleKind::Door,
                state: door,
            }],
            items: Vec::new(),
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

fn world_of(scene: &Scene) -> World {
    let dir = tempfile::tempdir().unwrap();
    let (bodies, _) =
        SceneBodies::build(scene, &Decomposer::default(), &HullCache::new(dir.path())).unwrap();
    World::new(scene, bodies, &WorldOptions::default())
}

fn wall_id(scene: &Scene, i: usize) -> InstanceId {
    let k = scene
        .instances
        .kinds
        .iter()
        .position(|k| *k == InstanceKind::Wall(i));
    InstanceId(k.unwrap() as u32)
}

fn agent(name: &str, x: f32, y: f32, z: f32, yaw_deg: f32) -> AgentBody {
    let profile: AgentProfile = name.parse().unwrap();
    AgentBody::new(profile, Pose::new(Vec3::new(x, y, z), yaw_deg.to_radians()))
}

#[test]
fn commands_and_poses_out_of_range_are_refused_and_the_largest_stops_at_the_wall() {
    let scene = hall(None);
    let mut world = world_of(&scene);
    // The farthest move allowed, into the outer wall x = 0: stopped there like any other.
    let mut a = agent("wheeled", 1.0, 1.5, 0.0, 180.0);
    let far = a
        .step(&mut world, &Command::Forward { distance: 1e4 })
        .unwrap();
    assert!(!far.touched.is_empty());
    assert!((a.pose.position.x - (0.05 + a.profile.radius + SKIN)).abs() < 2e-3);
    // Beyond it, or not finite, the step is refused and the agent stays where it was.
    let before = a.pose;
    for c in [
        Command::Forward { distance: 1e20 },
        Command::Forward { distance: f32::NAN },
        Command::Ground {
            vx: 1.0,
            vy: 0.0,
            wz: 0.0,
            dt: 1e6,
        },
    ] {
        let e = a.step(&mut world, &c).unwrap_err().to_string();
        assert!(e.starts_with("command '"), "{e}");
        assert_eq!(a.pose, before);
    }
    // An agent placed at a pose that is not finite takes no step.
    let mut lost = agent("wheeled", f32::NAN, 1.5, 0.0, 0.0);
    let e = lost
        .step(&mut world, &Command::Stop)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("the agent's pose: position [NaN, 1.5, 0.0]"),
        "{e}"
    );
}

#[test]
fn agent_driven_into_a_wall_stops_at_its_radius_and_slides_along_it() {
    let scene = hall(None);
    let mut world = world_of(&scene);
    // Towards the outer wall x = 0 (inner face at 0.05), in the band y ≈ 1.5 (clear of the box).
    let mut a = agent("wheeled", 1.0, 1.5, 0.0, 180.0);
    let free = a
        .step(&mut world, &Command::Forward { distance: 0.3 })
        .unwrap();
    assert_eq!(free.intensity, 0.0);
    assert!(free.touched.is_empty());
    assert!((free.achieved.x + 0.3).abs() < 1e-4);
    let hit = a
        .step(&mut world, &Command::Forward { distance: 1.0 })
        .unwrap();
    let stop = 0.05 + a.profile.radius + SKIN;
    assert!(
        (a.pose.position.x - stop).abs() < 2e-3,
        "x = {}",
        a.pose.position.x
    );
    assert!(hit.contact_onset);
    assert!(
        hit.intensity > 0.5 && hit.intensity < 1.0,
        "{}",
        hit.intensity
    );
    assert_eq!(hit.touched.len(), 1);
    assert_eq!(hit.touched[0].instance, wall_id(&scene, 3));
    let head_on = a
        .step(&mut world, &Command::Forward { distance: 0.25 })
        .unwrap();
    assert!(
        (head_on.intensity - 1.0).abs() < 1e-3,
        "{}",
        head_on.intensity
    );
    assert!(!head_on.contact_onset);
    // Heading 150° (30° off the wall's normal, into it): the agent slides along +y only.
    a.step(
        &mut world,
        &Command::Turn {
            angle: (-30f32).to_radians(),
        },
    )
    .unwrap();
    let graze = a
        .step(
            &mut world,
            &Command::Ground {
                vx: 0.5,
                vy: 0.0,
                wz: 0.0,
                dt: 1.0,
            },
        )
        .unwrap();
    assert!(
        (a.pose.position.x - stop).abs() < 2e-3,
        "x = {}",
        a.pose.position.x
    );
    assert!(
        (graze.achieved.y - 0.25).abs() < 5e-3,
        "{:?}",
        graze.achieved
    );
    // c = 1 − (a·d)/|d|² = (d̂·n)² = cos² 30° for a slide along the wall.
    assert!((graze.intensity - 0.75).abs() < 0.02, "{}", graze.intensity);
    assert!(graze.penetration <= PENETRATION_EPSILON && graze.recovery.is_none());
}

#[test]
fn pushing_against_a_wall_becomes_stuck() {
    let scene = hall(None);
    let mut world = world_of(&scene);
    let mut a = agent("h1", 9.0, 3.0, 0.0, 0.0);
    let reports: Vec<_> = (0..STUCK_STEPS + 2)
        .map(|_| {
            a.step(&mut world, &Command::Forward { distance: 0.5 })
                .unwrap()
        })
        .collect();
    let first_blocked = reports
        .iter()
        .position(|r| r.no_progress_steps == 1)
        .unwrap();
    assert!(!reports[first_blocked + STUCK_STEPS as usize - 2].stuck);
    assert!(reports[first_blocked + STUCK_STEPS as usize - 1].stuck);
    let after = a.step(&mut world, &Command::Turn { angle: 3.0 }).unwrap();
    assert!(after.stuck, "turning in place is not progress, nor a reset");
    let away = a
        .step(&mut world, &Command::Forward { distance: 0.5 })
        .unwrap();
    assert!(!away.stuck && away.no_progress_steps == 0);
}

#[test]
fn a_closed_door_blocks_an_open_one_does_not_and_a_half_open_one_partly() {
    let through = |door: Option<DoorState>| {
        let scene = hall(door);
        let mut world = world_of(&scene);
        let door_id = scene
            .objects
            .iter()
            .find(|o| o.category == "door")
            .map(|o| o.id);
        let mut a = agent("wheeled", 4.5, 2.0, 0.0, 0.0);
        let mut door_intensity = Vec::new();
        for _ in 0..12 {
            let r = a
                .step(&mut world, &Command::Forward { distance: 0.25 })
                .unwrap();
            if r.touched.iter().any(|t| Some(t.instance) == door_id) {
                door_intensity.push(r.intensity);
            }
        }
        (a.pose.position.x, door_intensity)
    };
    let (closed, c) = through(Some(DoorState::Closed));
    assert!(closed < 6.0 - 0.2, "closed door passed: x = {closed}");
    assert!(c.iter().any(|&c| c > 0.999), "{c:?}");
    let (open, c) = through(Some(DoorState::Open));
    assert!(open > 7.0 && c.is_empty(), "{open} {c:?}");
    assert!(through(None).0 > 7.0);
    // The half-open leaf stands at 45° across the path: the agent meets it and slides off it.
    let (_, c) = through(Some(DoorState::HalfOpen));
    assert!(c.iter().any(|&c| c > 0.1 && c < 0.9), "{c:?}");
}

#[test]
fn uav_flies_over_a_table_but_not_through_it_or_the_ceiling() {
    let scene = hall(None);
    let mut world = world_of(&scene);
    let fly = |z: f32, world: &mut World| {
        let mut a = agent("uav", 1.5, 3.0, z, 0.0);
        for _ in 0..10 {
            a.step(
                world,
                &Command::Uav {
                    vx: 1.0,
                    vy: 0.0,
                    vz: 0.0,
                    wz: 0.0,
                    dt: 0.3,
                },
            )
            .unwrap();
        }
        a.pose.position
    };
    let low = fly(0.5, &mut world);
    assert!(low.x < 2.5 - 0.25 + 0.01, "flew through the table: {low}");
    let high = fly(1.2, &mut world);
    assert!(high.x > 4.0, "did not pass over the table: {high}");
    let mut a = agent("uav", 8.0, 2.0, 1.0, 0.0);
    let mut last = None;
    for _ in 0..20 {
        last = Some(
            a.step(
                &mut world,
                &Command::Uav {
                    vx: 0.0,
                    vy: 0.0,
                    vz: 1.5,
                    wz: 0.0,
                    dt: 0.5,
                },
            )
            .unwrap(),
        );
    }
    let top = 2.8 - 0.25 - SKIN;
    assert!(
        (a.pose.position.z - top).abs() < 2e-3,
        "z = {}",
        a.pose.position.z
    );
    let last = last.unwrap();
    assert!((last.intensity - 1.0).abs() < 1e-3);
    assert!(last.touched.iter().any(|t| !t.instance.is_none()));
}

#[test]
fn a_dropped_movable_object_comes_to_rest_on_the_floor() {
    let scene = hall(None);
    let mut world = world_of(&scene);
    assert!(!world.has_awake_bodies(), "resting objects start asleep");
    let body = scene
        .objects
        .iter()
        .position(|o| o.category == "box")
        .unwrap();
    assert!(world.place_body(body, Vec3::new(2.0, 0.7, 1.5)));
    let t = world.settle(10.0);
    assert!(t < 10.0, "still moving after 10 s");
    let rb = world.rigid_body(body).unwrap();
    let z = rb.translation().z;
    assert!((z - 0.2).abs() < 0.02, "box centre at z = {z}");
    assert!(rb.is_sleeping());
}

#[test]
fn a_copied_world_evolves_exactly_as_a_freshly_built_one() {
    let scene = hall(None);
    let template = world_of(&scene);
    let body = scene
        .objects
        .iter()
        .position(|o| o.category == "box")
        .unwrap();
    let run = |mut world: World| {
        assert!(world.place_body(body, Vec3::new(2.0, 0.7, 1.5)));
        let mut trace = Vec::new();
        for _ in 0..60 {
            world.advance(1.0 / 30.0);
            trace.push(world.rigid_body(body).unwrap().translation());
        }
        let mut agent = agent("wheeled", 0.5, 0.0, 0.0, 0.0);
        let report = agent
            .step(&mut world, &Command::Forward { distance: 0.25 })
            .unwrap();
        (trace, agent.pose, report.touched.len())
    };
    let fresh = run(world_of(&scene));
    // The template stays untouched by its copies.
    assert_eq!(run(template.clone()), fresh);
    assert_eq!(run(template.clone()), fresh);
    assert!(!template.has_awake_bodies());
}

#[test]
fn an_agent_placed_inside_an_obstacle_is_reported_and_pushed_out() {
    let scene = hall(None);
    let mut world = world_of(&scene);
    // 10 cm into the table's side.
    let mut a = agent("wheeled", 3.0 - 0.5 - 0.1, 3.0, 0.0, 0.0);
    let r = a.step(&mut world, &Command::Stop).unwrap();
    assert!(r.interpenetrating && r.penetration > 0.09, "{r:?}");
    let off = r.recovery.expect("a free pose is near");
    assert!(off.length() < 0.5 && off.z == 0.0, "{off}");
    let again = a.step(&mut world, &Command::Stop).unwrap();
    assert!(
        !again.interpenetrating && again.recovery.is_none(),
        "{again:?}"
    );
    assert!(again.penetration <= PENETRATION_EPSILON);
}

#[test]
fn ground_commands_respect_speed_limits_and_kinds() {
    let scene = hall(None);
    let mut world = world_of(&scene);
    let mut a = agent("wheeled", 8.0, 2.0, 0.0, 90.0);
    let r = a
        .step(
            &mut world,
            &Command::Ground {
                vx: 5.0,
                vy: 0.0,
                wz: 10.0,
                dt: 0.5,
            },
        )
        .unwrap();
    assert!((r.commanded.length() - a.profile.max_speed * 0.5).abs() < 1e-5);
    assert!((a.pose.yaw - (90f32.to_radians() + a.profile.max_yaw_rate * 0.5)).abs() < 1e-5);
    assert!(
        a.step(
            &mut world,
            &Command::Uav {
                vx: 0.0,
                vy: 0.0,
                vz: 1.0,
                wz: 0.0,
                dt: 1.0
            }
        )
        .is_err()
    );
    let mut u = agent("uav", 8.0, 2.0, 0.0, 0.0);
    assert!((u.pose.position.z - u.profile.altitude[0]).abs() < 1e-6);
    assert!(
        u.step(
            &mut world,
            &Command::Ground {
                vx: 1.0,
                vy: 0.0,
                wz: 0.0,
                dt: 1.0
            }
        )
        .is_err()
    );
}
