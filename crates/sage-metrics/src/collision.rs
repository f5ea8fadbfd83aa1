//! Collision metrics: CR (collision events; habitat's collision test in mode `vlnce`), ICP
//! (integrated collision penalty) and the published code's binary collision window (SPEC §10,
//! §10.1).

/// CR in mode `sage`: steps whose contact begins after a step without contact (the step
/// before the first one counts as without contact).
pub fn collision_events(contact: &[bool]) -> usize {
    let mut prev = false;
    let mut n = 0;
    for &c in contact {
        if c && !prev {
            n += 1;
        }
        prev = c;
    }
    n
}

/// True when a step collided as habitat-sim tests it (mode `vlnce`): the squared length of the
/// displacement achieved, plus 1e-5, is below the squared length of the translation commanded
/// (its move filter compares `dot()` of the two vectors with `EPS = 1e-5`). Turns never collide.
pub fn habitat_collided(commanded: f64, from: &[f64; 3], to: &[f64; 3]) -> bool {
    let moved2: f64 = (0..3).map(|k| (to[k] - from[k]).powi(2)).sum();
    moved2 + 1e-5 < commanded * commanded
}

/// The mean of the per-step values (0 for none): ICP = (1/T) Σ c(t) and any other step ratio.
pub fn mean(values: impl IntoIterator<Item = f64>) -> f64 {
    let (s, n) = values
        .into_iter()
        .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { 0.0 } else { s / n as f64 }
}

/// ICP as the published code computes it, over its update samples (the reset sample, then a
/// sample before and one after each step). `moves[t]` is step t's commanded and achieved
/// translation (metres along the command).
///
/// Its counter grows on a step that achieves < 30 % of a commanded translation > 0.05 m, resets
/// on one that achieves > 60 % of it, and is left as is otherwise (turns included); a sample
/// taken while the counter is positive opens a window of 3 samples (that one and the next two)
/// and ICP is the share of samples inside a window.
pub fn official_icp(moves: &[(f64, f64)]) -> f64 {
    let mut counter = 0u32;
    // Counter value seen by each sample: reset, then (before, after) per step.
    let mut seen = vec![0u32];
    for &(cmd, ach) in moves {
        seen.push(counter);
        if cmd > 0.05 {
            if ach < 0.3 * cmd {
                counter += 1;
            } else if ach > 0.6 * cmd {
                counter = 0;
            }
        }
        seen.push(counter);
    }
    let mut hold = 0u32;
    let mut inside = 0usize;
    for &c in &seen {
        if c > 0 {
            hold = 3;
        }
        if hold > 0 {
            inside += 1;
            hold -= 1;
        }
    }
    inside as f64 / seen.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn events_count_onsets() {
        assert_eq!(collision_events(&[]), 0);
        assert_eq!(collision_events(&[false, false]), 0);
        // Two onsets: steps 1 and 4; the contact held over steps 2 and 3 is one event.
        assert_eq!(collision_events(&[true, true, false, true, true, false]), 2);
        assert_eq!(collision_events(&[false, true, false, true]), 2);
    }

    #[test]
    fn habitat_collision_test_is_on_squared_lengths() {
        let o = [0.0, 0.0, 0.0];
        assert!(!habitat_collided(0.25, &o, &[0.25, 0.0, 0.0]));
        assert!(habitat_collided(0.25, &o, &[0.1, 0.0, 0.0]));
        assert!(!habitat_collided(0.0, &o, &o));
        // 1e-5 on squared lengths: 0.25² − 0.24999² ≈ 5e-6 is no collision, although the
        // lengths differ by 1e-5; 0.25² − 0.2499² ≈ 5e-5 is one.
        assert!(!habitat_collided(0.25, &o, &[0.249_99, 0.0, 0.0]));
        assert!(habitat_collided(0.25, &o, &[0.249_9, 0.0, 0.0]));
        // A slide along a wall that keeps the full length is not a collision.
        assert!(!habitat_collided(0.25, &o, &[0.15, 0.2, 0.0]));
    }

    #[test]
    fn icp_is_the_mean_intensity() {
        assert_eq!(mean([0.0, 0.5, 1.0, 0.5]), 0.5);
        assert_eq!(mean(Vec::<f64>::new()), 0.0);
    }

    #[test]
    fn official_window() {
        // Free moves only: no sample in a window.
        assert_eq!(official_icp(&[(0.2, 0.2), (0.2, 0.2)]), 0.0);
        // Step 1 blocked (counter 1 after it), step 2 free (reset), step 3 free.
        // Samples: reset 0, s1 before 0, s1 after 1, s2 before 1, s2 after 0, s3 before 0, s3 after 0.
        // Windows: the 3rd sample opens 3 (3,4,5), the 4th re-opens 3 (4,5,6): samples 3–6 → 4/7.
        let icp = official_icp(&[(0.2, 0.0), (0.2, 0.2), (0.2, 0.2)]);
        assert_eq!(icp, 4.0 / 7.0);
        // Partial progress (30–60 %) keeps the counter; a turn leaves it too; tiny moves do not count.
        // Counter after steps: 1, 1, 1, 1 → every sample from the 3rd on is inside: 7/9.
        let icp = official_icp(&[(0.2, 0.0), (0.2, 0.1), (0.0, 0.0), (0.04, 0.0)]);
        assert_eq!(icp, 7.0 / 9.0);
    }
}
