//! Ground-truth discrete actions (VLN-CE action space): following a dense reference path with
//! fixed forward steps and turns, and replaying actions into poses.
//!
//! Ids are VLN-CE's: 0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT (counter-clockwise), 3 TURN_RIGHT.
//! Headings stay exact multiples of the turn angle away from the start heading (the turn count is
//! kept as an integer), so [`replay`] reproduces the follower's poses bit for bit.

use glam::{Vec2, Vec3};
use sage_core::{Pose, wrap_angle};
use serde::{Deserialize, Serialize};

/// One ground-truth discrete action, by VLN-CE id (0-3). Named apart from `sage_env::Action`,
/// the environment's action (velocities and camera tilt too), which these are replayed into.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
pub enum DiscreteAction {
    /// End the episode (id 0).
    Stop = 0,
    /// Move forward one step (id 1).
    Forward = 1,
    /// Turn left (counter-clockwise) in place (id 2).
    Left = 2,
    /// Turn right (clockwise) in place (id 3).
    Right = 3,
}

impl From<DiscreteAction> for u8 {
    fn from(a: DiscreteAction) -> u8 {
        a as u8
    }
}

impl TryFrom<u8> for DiscreteAction {
    type Error = String;
    fn try_from(v: u8) -> Result<DiscreteAction, String> {
        match v {
            0 => Ok(DiscreteAction::Stop),
            1 => Ok(DiscreteAction::Forward),
            2 => Ok(DiscreteAction::Left),
            3 => Ok(DiscreteAction::Right),
            _ => Err(format!(
                "action id must be 0-3 (STOP, FORWARD, LEFT, RIGHT), got {v}"
            )),
        }
    }
}

/// Step sizes of the discrete action space: what a forward step and a turn amount to. Named
/// apart from `sage_env::ActionSpace`, which says which actions an environment accepts.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepSizes {
    /// Forward step, metres (VLN-CE: 0.25).
    pub forward: f32,
    /// Turn angle, degrees (VLN-CE: 15).
    pub turn_deg: f32,
}

impl Default for StepSizes {
    /// The `vlnce` preset (SPEC §13): 0.25 m, 15°.
    fn default() -> Self {
        StepSizes {
            forward: 0.25,
            turn_deg: 15.0,
        }
    }
}

impl StepSizes {
    fn turn(&self) -> f32 {
        self.turn_deg.to_radians()
    }

    /// Turns (signed, left positive) that best approximate a heading change.
    fn turns_for(&self, delta: f32) -> i32 {
        (wrap_angle(delta) / self.turn()).round() as i32
    }
}

/// The agent state during following and replay: position and the integer turn count.
#[derive(Debug, Clone, Copy)]
struct State {
    p: Vec2,
    start_yaw: f32,
    turns: i32,
}

impl State {
    fn yaw(&self, space: &StepSizes) -> f32 {
        wrap_angle(self.start_yaw + self.turns as f32 * space.turn())
    }

    fn apply(&mut self, a: DiscreteAction, space: &StepSizes) {
        match a {
            DiscreteAction::Forward => {
                let y = self.yaw(space);
                self.p += space.forward * Vec2::new(y.cos(), y.sin());
            }
            DiscreteAction::Left => self.turns += 1,
            DiscreteAction::Right => self.turns -= 1,
            DiscreteAction::Stop => {}
        }
    }

    fn emit_turns(&mut self, n: i32, space: &StepSizes, out: &mut Vec<DiscreteAction>) {
        let a = if n > 0 {
            DiscreteAction::Left
        } else {
            DiscreteAction::Right
        };
        for _ in 0..n.unsigned_abs() {
            self.apply(a, space);
            out.push(a);
        }
    }
}

/// Follows the polyline `path` (W frame, at least one point) from its first point with heading
/// `start_yaw`: at each step it turns toward the first path point at least one step ahead (in
/// whole turns; never one before the point it pursued last), then moves forward; it stops when
/// within half a step of the last point or when a step would not bring it closer; then it
/// turns to `final_yaw` (if given) and STOPs. `None` when it does not arrive within a step
/// budget (a path it cannot follow).
pub fn follow(
    path: &[Vec2],
    start_yaw: f32,
    final_yaw: Option<f32>,
    space: &StepSizes,
) -> Option<Vec<DiscreteAction>> {
    let first = *path.first()?;
    let goal = *path.last()?;
    let mut s = State {
        p: first,
        start_yaw,
        turns: 0,
    };
    let mut out = Vec::new();
    let length: f32 = path.windows(2).map(|w| w[0].distance(w[1])).sum();
    let budget = (4.0 * length / space.forward) as usize + 4 * path.len() + 64;
    let last = path.len() - 1;
    let (mut k, mut t) = (0usize, 0usize);
    while s.p.distance(goal) >= 0.5 * space.forward {
        if out.len() > budget {
            return None;
        }
        // The nearest path point at or after k (within a short window keeps it monotone).
        let window = (k..path.len().min(k + 8))
            .min_by(|&a, &b| s.p.distance(path[a]).total_cmp(&s.p.distance(path[b])));
        k = window.unwrap_or(k);
        // The point pursued never moves back along the path: where a path folds back on itself
        // the nearest point can stay put while the agent steps to and fro across the fold.
        let ahead = (k..path.len())
            .find(|&j| s.p.distance(path[j]) >= space.forward)
            .unwrap_or(last);
        t = t.max(ahead);
        let d = path[t] - s.p;
        let n = space.turns_for(d.y.atan2(d.x) - s.yaw(space));
        let mut next = s;
        next.turns += n;
        next.apply(DiscreteAction::Forward, space);
        if t == last && next.p.distance(goal) >= s.p.distance(goal) {
            break;
        }
        s.emit_turns(n, space, &mut out);
        s.apply(DiscreteAction::Forward, space);
        out.push(DiscreteAction::Forward);
    }
    if let Some(f) = final_yaw {
        let n = space.turns_for(f - s.yaw(space));
        s.emit_turns(n, space, &mut out);
    }
    out.push(DiscreteAction::Stop);
    Some(out)
}

/// The poses after each action, starting with `start` (so `actions.len() + 1` poses); z is kept.
pub fn replay(start: Pose, actions: &[DiscreteAction], space: &StepSizes) -> Vec<Pose> {
    let mut s = State {
        p: start.position.truncate(),
        start_yaw: start.yaw,
        turns: 0,
    };
    let mut out = Vec::with_capacity(actions.len() + 1);
    out.push(Pose::new(start.position, start.yaw));
    for &a in actions {
        s.apply(a, space);
        out.push(Pose::new(
            Vec3::new(s.p.x, s.p.y, start.position.z),
            s.yaw(space),
        ));
    }
    out
}

/// Distance from `p` to the polyline `path`.
pub fn distance_to_polyline(path: &[Vec2], p: Vec2) -> f32 {
    match path {
        [] => f32::INFINITY,
        [a] => a.distance(p),
        _ => path
            .windows(2)
            .map(|w| {
                let (a, b) = (w[0], w[1]);
                let ab = b - a;
                let t = if ab.length_squared() > 0.0 {
                    ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                p.distance(a + t * ab)
            })
            .fold(f32::INFINITY, f32::min),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn poly(points: &[(f32, f32)], step: f32) -> Vec<Vec2> {
        let pts: Vec<Vec2> = points.iter().map(|&(x, y)| Vec2::new(x, y)).collect();
        sage_core::geometry::resample_polyline(&pts, step)
    }

    #[test]
    fn straight_path_is_forward_steps_then_stop() {
        let path = poly(&[(0.0, 0.0), (2.0, 0.0)], 0.25);
        let a = follow(&path, 0.0, None, &StepSizes::default()).unwrap();
        assert_eq!(
            a,
            [vec![DiscreteAction::Forward; 8], vec![DiscreteAction::Stop]].concat()
        );
        let a = follow(
            &path,
            std::f32::consts::FRAC_PI_2,
            None,
            &StepSizes::default(),
        )
        .unwrap();
        assert_eq!(&a[..6], &[DiscreteAction::Right; 6]);
        assert_eq!(
            a.iter().filter(|x| **x == DiscreteAction::Forward).count(),
            8
        );
    }

    #[test]
    fn a_path_that_folds_back_on_itself_is_followed_to_its_end() {
        // Found by fuzzing: down one side of a hairpin and 2 m back up the other, a few
        // centimetres apart at the fold, where the nearest path point stayed put while the
        // agent stepped to and fro across the fold until the step budget ran out.
        let corners = [
            Vec2::new(-4.265_227, 19.808_41),
            Vec2::new(-15.464_497, 7.732_727),
            Vec2::new(-13.532_638, 9.932_495),
            Vec2::new(-11.336, -5.758_663),
            Vec2::new(-11.740_94, 11.985_903),
        ];
        let mut path = vec![corners[0]];
        for w in corners.windows(2) {
            let n = (w[0].distance(w[1]) / 0.25).ceil() as usize;
            path.extend((1..=n).map(|i| w[0].lerp(w[1], i as f32 / n as f32)));
        }
        path.truncate(151);
        let (space, yaw) = (StepSizes::default(), -2.815_910_3);
        let actions = follow(&path, yaw, None, &space).expect("the hairpin is followed");
        let poses = replay(Pose::new(path[0].extend(0.0), yaw), &actions, &space);
        for p in &poses {
            assert!(distance_to_polyline(&path, p.position.truncate()) < 0.3);
        }
        let end = poses.last().unwrap().position.truncate();
        assert!(end.distance(*path.last().unwrap()) < 0.2);
    }

    #[test]
    fn ids_are_vlnce() {
        assert_eq!(
            serde_json::to_string(&[
                DiscreteAction::Stop,
                DiscreteAction::Forward,
                DiscreteAction::Left,
                DiscreteAction::Right
            ])
            .unwrap(),
            "[0,1,2,3]"
        );
        assert!(serde_json::from_str::<DiscreteAction>("4").is_err());
    }

    proptest! {
        #[test]
        fn following_stays_on_the_path_and_arrives(
            pts in proptest::collection::vec((-6.0f32..6.0, -6.0f32..6.0), 2..6),
            yaw in -3.1f32..3.1,
            final_yaw in -3.1f32..3.1,
        ) {
            let space = StepSizes::default();
            let path = poly(&pts, 0.25);
            let actions = follow(&path, yaw, Some(final_yaw), &space).unwrap();
            prop_assert_eq!(*actions.last().unwrap(), DiscreteAction::Stop);
            prop_assert_eq!(actions.iter().filter(|a| **a == DiscreteAction::Stop).count(), 1);
            let poses = replay(Pose::new(path[0].extend(0.0), yaw), &actions, &space);
            let end = poses.last().unwrap();
            prop_assert!(end.position.truncate().distance(*path.last().unwrap()) < 0.2);
            prop_assert!(wrap_angle(end.yaw - final_yaw).abs() <= 7.5f32.to_radians() + 1e-4);
            for p in &poses {
                prop_assert!(distance_to_polyline(&path, p.position.truncate()) < 0.3);
            }
        }
    }
}
