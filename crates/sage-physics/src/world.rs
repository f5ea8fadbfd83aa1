//! The physics world (rapier3d): static colliders for structure and static objects, dynamic rigid
//! bodies for movable objects, doors on revolute joints when asked, and the scene queries the
//! agents move with.

use crate::bodies::{Body, BodyKind, SceneBodies};
use glam::{Vec2, Vec3};
use rapier3d::prelude::*;
use sage_core::{InstanceId, Obb};
use sage_scene::{PhysicsRole, Scene};

/// Fixed time step of the rigid-body simulation (s).
pub const DYNAMICS_DT: f32 = 1.0 / 60.0;

/// How the world is assembled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldOptions {
    /// Put articulated objects (doors) on revolute joints about their hinge; otherwise they are
    /// fixed at the angle of their state.
    pub articulated_doors: bool,
    /// Gravity along −Z, m/s².
    pub gravity: f32,
}

impl Default for WorldOptions {
    fn default() -> Self {
        WorldOptions {
            articulated_doors: false,
            gravity: 9.81,
        }
    }
}

/// A scene's physics world.
pub struct World {
    /// The rapier world (bodies, colliders, joints, pipelines).
    pub physics: PhysicsWorld,
    /// The scene's bodies, indexed by collider user data.
    pub bodies: SceneBodies,
    /// The rigid body of each scene body (None for plain static colliders).
    handles: Vec<Option<RigidBodyHandle>>,
    /// Room polygons, to name the floor or ceiling room touched.
    rooms: Vec<sage_core::Polygon2>,
}

/// The hinge axis of a door leaf: the vertical line through the centre of the box's −x end face
/// (the leaf's own x runs from hinge to latch, as synthetic scenes write it).
pub fn hinge_of(obb: &Obb) -> Vec3 {
    let (ax, _) = obb.axes();
    (obb.center.truncate() - ax * obb.half_extents.x).extend(obb.min_z())
}

impl Clone for World {
    /// A copy in the same state, with fresh pipeline workspaces (rapier's pipelines hold only
    /// scratch memory): much cheaper than building the world again from the bodies' hulls.
    fn clone(&self) -> World {
        let p = &self.physics;
        let mut physics = PhysicsWorld::new();
        physics.gravity = p.gravity;
        physics.integration_parameters = p.integration_parameters;
        physics.islands = p.islands.clone();
        physics.broad_phase = p.broad_phase.clone();
        physics.narrow_phase = p.narrow_phase.clone();
        physics.bodies = p.bodies.clone();
        physics.colliders = p.colliders.clone();
        physics.impulse_joints = p.impulse_joints.clone();
        physics.multibody_joints = p.multibody_joints.clone();
        physics.soft_bodies = p.soft_bodies.clone();
        World {
            physics,
            bodies: self.bodies.clone(),
            handles: self.handles.clone(),
            rooms: self.rooms.clone(),
        }
    }
}

impl World {
    /// Builds the world from a scene's bodies.
    pub fn new(scene: &Scene, bodies: SceneBodies, options: &WorldOptions) -> World {
        let mut physics = PhysicsWorld::new();
        physics.gravity = Vector::new(0.0, 0.0, -options.gravity);
        let mut handles = vec![None; bodies.bodies.len()];
        let anchor = physics.insert_body(RigidBodyBuilder::fixed());
        for (i, b) in bodies.bodies.iter().enumerate() {
            let dynamic = match b.role {
                PhysicsRole::Movable => true,
                PhysicsRole::Articulated => options.articulated_doors,
                PhysicsRole::Static => false,
            };
            if !dynamic {
                for part in &b.parts {
                    if let Some(c) = collider(part, Vec3::ZERO, b, i, None) {
                        physics.insert_collider(c, None);
                    }
                }
                continue;
            }
            let origin = b.obb.center;
            let handle = physics.insert_body(
                RigidBodyBuilder::dynamic()
                    .translation(origin)
                    .user_data(i as u128),
            );
            let total: f32 = b.parts.iter().map(|p| p.volume()).sum::<f32>().max(1e-9);
            for part in &b.parts {
                let mass = b.rigid_body.mass.max(1e-3) * part.volume() / total;
                if let Some(c) = collider(part, -origin, b, i, Some(mass)) {
                    physics.insert_collider(c, Some(handle));
                }
            }
            handles[i] = Some(handle);
            if b.role == PhysicsRole::Articulated {
                let hinge = hinge_of(&b.obb);
                let joint = RevoluteJointBuilder::new(Vector::Z)
                    .local_anchor1(hinge)
                    .local_anchor2(hinge - origin)
                    .limits([-std::f32::consts::PI, std::f32::consts::PI])
                    .motor_velocity(0.0, 5.0);
                physics.insert_impulse_joint(anchor, handle, joint);
            }
        }
        physics.detect_collisions(&(), &());
        // Resting objects start asleep (attaching colliders woke them): they wake when moved or
        // hit, so an agent in an undisturbed scene never pays for a dynamics step.
        for h in handles.iter().flatten() {
            if let Some(b) = physics.bodies.get_mut(*h) {
                b.sleep();
            }
        }
        World {
            physics,
            bodies,
            handles,
            rooms: scene
                .floorplan
                .rooms
                .iter()
                .map(|r| r.profile.clone())
                .collect(),
        }
    }

    /// True when a dynamic body is awake (the simulation has something to do).
    pub fn has_awake_bodies(&self) -> bool {
        self.handles.iter().flatten().any(|h| {
            self.physics
                .bodies
                .get(*h)
                .is_some_and(|b| !b.is_sleeping())
        })
    }

    /// Advances the rigid bodies by `dt` seconds in fixed steps, when any is awake.
    pub fn advance(&mut self, dt: f32) {
        let mut left = dt;
        while left > 1e-6 && self.has_awake_bodies() {
            let h = left.min(DYNAMICS_DT);
            self.physics.integration_parameters.dt = h;
            self.physics.step();
            left -= h;
        }
    }

    /// Simulates until every dynamic body sleeps or `max_seconds` pass; returns the seconds
    /// simulated.
    pub fn settle(&mut self, max_seconds: f32) -> f32 {
        let mut t = 0.0;
        while t < max_seconds && self.has_awake_bodies() {
            self.advance(DYNAMICS_DT);
            t += DYNAMICS_DT;
        }
        t
    }

    /// The rigid body of a scene body, when it is dynamic.
    pub fn rigid_body(&self, body: usize) -> Option<&RigidBody> {
        self.handles
            .get(body)
            .copied()
            .flatten()
            .and_then(|h| self.physics.bodies.get(h))
    }

    /// Moves a dynamic body to `position` (its box centre) at rest and wakes it.
    pub fn place_body(&mut self, body: usize, position: Vec3) -> bool {
        let Some(h) = self.handles.get(body).copied().flatten() else {
            return false;
        };
        if let Some(rb) = self.physics.bodies.get_mut(h) {
            rb.set_translation(position, true);
            rb.set_linvel(Vector::ZERO, true);
            rb.set_angvel(Vector::ZERO, true);
            return true;
        }
        false
    }

    /// The scene body of a collider.
    pub fn body_of(&self, collider: ColliderHandle) -> Option<&Body> {
        let c = self.physics.colliders.get(collider)?;
        self.bodies.bodies.get(c.user_data as usize)
    }

    /// The instance id to report for a contact with `collider` near `at`: the body's own id, or
    /// for the floor and ceiling slabs the floor or ceiling of the room at `at`.
    pub fn instance_at(&self, collider: ColliderHandle, at: Vec2) -> InstanceId {
        let Some(b) = self.body_of(collider) else {
            return InstanceId::NONE;
        };
        let ids = match b.kind {
            BodyKind::Floor => &self.bodies.floor_ids,
            BodyKind::Ceiling => &self.bodies.ceiling_ids,
            _ => return b.instance,
        };
        self.rooms
            .iter()
            .enumerate()
            .filter(|(_, r)| r.contains(at))
            .min_by(|a, b| a.1.area().total_cmp(&b.1.area()))
            .and_then(|(i, _)| ids.get(i).copied())
            .unwrap_or(InstanceId::NONE)
    }
}

fn collider(
    part: &crate::hull::ConvexPart,
    offset: Vec3,
    body: &Body,
    index: usize,
    mass: Option<f32>,
) -> Option<Collider> {
    let vertices = part.translated(offset).vertices;
    let builder = ColliderBuilder::convex_mesh(vertices.clone(), &part.triangles)
        .or_else(|| ColliderBuilder::convex_hull(&vertices))?;
    let builder = builder
        .friction(body.rigid_body.friction)
        .restitution(body.rigid_body.restitution)
        .user_data(index as u128);
    Some(match mass {
        Some(m) => builder.mass(m).build(),
        None => builder.build(),
    })
}
