//! The balanced test selector (SPEC §9): picks `n` episodes spread evenly over strata of
//! (instruction type, asset slice, path slice). Strata are visited round robin in sorted order,
//! each stratum's episodes in a seeded shuffled order, so every stratum gets the same count
//! (±1) unless it runs out.

use crate::episode::Episode;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

/// The stratum of an episode: `type/assets/path`.
pub fn stratum(e: &Episode) -> String {
    format!(
        "{}/{}/{}",
        e.instruction_type.as_str(),
        e.slices.assets,
        e.slices.path
    )
}

/// The ids of up to `n` episodes balanced over strata, sorted.
pub fn select_balanced(episodes: &[&Episode], n: usize, seed: u64) -> Vec<String> {
    let mut strata: BTreeMap<String, Vec<&str>> = BTreeMap::new();
    for e in episodes {
        strata
            .entry(stratum(e))
            .or_default()
            .push(e.episode_id.as_str());
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(0xba1a);
    for ids in strata.values_mut() {
        ids.sort_unstable();
        ids.shuffle(&mut rng);
    }
    let mut out = Vec::with_capacity(n.min(episodes.len()));
    let mut round = 0;
    while out.len() < n {
        let before = out.len();
        for ids in strata.values() {
            if out.len() == n {
                break;
            }
            if let Some(id) = ids.get(round) {
                out.push(id.to_string());
            }
        }
        if out.len() == before {
            break;
        }
        round += 1;
    }
    out.sort();
    out
}
