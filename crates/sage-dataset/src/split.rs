//! Train / val / test splits with the three unseen test sets of SAGE-Bench (SPEC §9):
//!
//! 1. scenes are shuffled (seeded); the first `scene_unseen` share (at least one when there are
//!    three scenes or more) is **test_scene_unseen**, the next `val` share (at least one from
//!    four scenes) is **val**, the rest train scenes;
//! 2. of the train scenes (in the same shuffled order) the first `donor_share` donate
//!    trajectories: a third of their trajectories (at least one), with every instruction, go to
//!    **test_trajectory_unseen** — the scene is seen in training, the path is not;
//! 3. the next `donor_share` donate instructions: of every trajectory with two or more
//!    instructions a third (at least one, never all) go to **test_instruction_unseen** — the path
//!    is seen in training with other words;
//! 4. everything else of a train scene (Base-Action and no-goal episodes included) is **train**.

use crate::episode::Episode;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};

/// The split names, in file order.
pub const SPLITS: [&str; 5] = [
    "train",
    "val",
    "test_scene_unseen",
    "test_trajectory_unseen",
    "test_instruction_unseen",
];

/// The balanced test selection's split (SPEC §9): what evaluations run by default.
pub const TEST_BALANCED: &str = "test_balanced";

/// Shares of the split rule.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SplitParams {
    /// Share of scenes held out whole for test (default 0.15).
    pub scene_unseen: f32,
    /// Share of scenes for validation (default 0.1).
    pub val: f32,
    /// Share of train scenes donating trajectories, and again instructions (default 0.3).
    pub donor_share: f32,
}

impl Default for SplitParams {
    fn default() -> Self {
        SplitParams {
            scene_unseen: 0.15,
            val: 0.1,
            donor_share: 0.3,
        }
    }
}

impl SplitParams {
    /// The split rule holding out the shares `scene_unseen` and `val` of the scenes (test and
    /// validation), the donors at their default share.
    pub fn holding_out(scene_unseen: f32, val: f32) -> SplitParams {
        SplitParams {
            scene_unseen,
            val,
            ..SplitParams::default()
        }
    }
}

fn share(n: usize, s: f32, at_least_one: bool) -> usize {
    let k = (n as f32 * s).round() as usize;
    if at_least_one { k.max(1) } else { k }.min(n)
}

/// How many of `scenes` scenes the split rule holds out whole for test and for validation,
/// and how many train scenes donate trajectories (as many again donate instructions).
fn scene_counts(scenes: usize, params: &SplitParams) -> (usize, usize, usize) {
    let n_test = share(scenes, params.scene_unseen, scenes >= 3);
    let n_val = share(scenes - n_test, params.val, scenes >= 4);
    let train = scenes - n_test - n_val;
    (n_test, n_val, share(train, params.donor_share, train >= 2))
}

/// The splits that the rule ([`assign`]) can give episodes when it deals out `scenes` scenes:
/// `train` from one scene, the others only from as many scenes as their shares need (one or
/// two scenes leave `val` empty, one scene every test split), [`TEST_BALANCED`] with any test
/// split. Whether a split that can hold episodes does also depends on the trajectories.
pub fn splits_possible(scenes: usize, params: &SplitParams) -> Vec<&'static str> {
    let (n_test, n_val, n_donor) = scene_counts(scenes, params);
    let train = scenes - n_test - n_val;
    let possible = [
        train > 0,
        n_val > 0,
        n_test > 0,
        n_donor > 0,
        train > n_donor && n_donor > 0,
    ];
    let mut splits: Vec<&'static str> = SPLITS
        .iter()
        .zip(possible)
        .filter_map(|(name, can)| can.then_some(*name))
        .collect();
    if splits.iter().any(|s| s.starts_with("test_")) {
        splits.push(TEST_BALANCED);
    }
    splits
}

/// The split of every episode (by id).
pub fn assign(
    episodes: &[Episode],
    params: &SplitParams,
    seed: u64,
) -> BTreeMap<String, &'static str> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(0x5b1d);
    let mut scenes: Vec<&str> = episodes
        .iter()
        .map(|e| e.scene.as_str())
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    scenes.shuffle(&mut rng);
    let (n_test, n_val, n_donor) = scene_counts(scenes.len(), params);
    let train: Vec<&str> = scenes[n_test + n_val..].to_vec();
    let traj_donors: BTreeSet<&str> = train.iter().take(n_donor).copied().collect();
    let instr_donors: BTreeSet<&str> = train.iter().skip(n_donor).take(n_donor).copied().collect();
    let scene_split: BTreeMap<&str, &'static str> = scenes
        .iter()
        .enumerate()
        .map(|(i, s)| {
            (
                *s,
                if i < n_test {
                    SPLITS[2]
                } else if i < n_test + n_val {
                    SPLITS[1]
                } else {
                    SPLITS[0]
                },
            )
        })
        .collect();
    let mut out: BTreeMap<String, &'static str> = episodes
        .iter()
        .map(|e| (e.episode_id.clone(), scene_split[e.scene.as_str()]))
        .collect();
    // Trajectories (and their episodes) per scene, in id order.
    let mut by_traj: BTreeMap<(&str, usize), Vec<&str>> = BTreeMap::new();
    for e in episodes {
        if let Some(t) = e.trajectory_id {
            by_traj
                .entry((e.scene.as_str(), t))
                .or_default()
                .push(e.episode_id.as_str());
        }
    }
    for scene in traj_donors.iter() {
        let mut trajs: Vec<usize> = by_traj
            .keys()
            .filter(|(s, _)| s == scene)
            .map(|(_, t)| *t)
            .collect();
        trajs.shuffle(&mut rng);
        let k = trajs.len().div_ceil(3);
        for t in &trajs[..k] {
            for id in &by_traj[&(*scene, *t)] {
                out.insert(id.to_string(), SPLITS[3]);
            }
        }
    }
    for ((scene, _), ids) in by_traj.iter() {
        if !instr_donors.contains(scene) || ids.len() < 2 {
            continue;
        }
        let mut ids = ids.clone();
        ids.shuffle(&mut rng);
        let k = (ids.len() / 3).max(1);
        for id in &ids[..k] {
            out.insert(id.to_string(), SPLITS[4]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Episodes of `scenes` scenes, each of six trajectories with three instructions.
    fn episodes(scenes: usize) -> Vec<Episode> {
        let template: Episode = serde_json::from_str(
            r#"{"episode_id":"","scene":"","task":"vln","instruction":"Walk to the sofa.","level":"high","instruction_type":"Single-Goal","source":"template","start":{"position":[0.0,0.0,0.0],"yaw":0.0},"goal":{"ref":"room_0","kind":"room","position":[2.0,0.0,0.0]},"reference_path":[[0.0,0.0,0.0],[2.0,0.0,0.0]],"actions":[1,0],"path_length":2.0,"geodesic_distance":2.0,"slices":{"assets":"few","path":"short"}}"#,
        )
        .unwrap();
        let mut out = Vec::new();
        for s in 0..scenes {
            for t in 0..6 {
                for k in 0..3 {
                    let mut e = template.clone();
                    e.scene = format!("scene_{s}");
                    e.episode_id = format!("scene_{s}-t{t}-{k}");
                    e.trajectory_id = Some(t);
                    out.push(e);
                }
            }
        }
        out
    }

    #[test]
    fn the_splits_said_possible_are_those_the_rule_fills() {
        for params in [
            SplitParams::default(),
            SplitParams {
                scene_unseen: 0.0,
                val: 0.5,
                donor_share: 0.0,
            },
        ] {
            for scenes in 1..=9 {
                let filled: BTreeSet<&str> = assign(&episodes(scenes), &params, 7)
                    .into_values()
                    .collect();
                let possible = splits_possible(scenes, &params);
                let said: BTreeSet<&str> = possible
                    .iter()
                    .copied()
                    .filter(|s| *s != TEST_BALANCED)
                    .collect();
                assert_eq!(said, filled, "{scenes} scenes, {params:?}");
                assert_eq!(
                    possible.contains(&TEST_BALANCED),
                    filled.iter().any(|s| s.starts_with("test_")),
                );
            }
        }
        // One scene: everything is train.
        assert_eq!(splits_possible(1, &SplitParams::default()), ["train"]);
    }
}
