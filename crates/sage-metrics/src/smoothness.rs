//! Path smoothness PS (SPEC §10) and the published code's variant.

use std::f64::consts::PI;

/// An angle wrapped to (−π, π].
pub fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(2.0 * PI);
    if w > PI { w - 2.0 * PI } else { w }
}

/// PS in modes `sage` and `vlnce`: 1 − (1/(T−1)) Σ_{t=2..T} min(|Δθ_t|/π, 1) over the headings
/// after each step; 1 when T < 2.
pub fn path_smoothness(headings: &[f64]) -> f64 {
    if headings.len() < 2 {
        return 1.0;
    }
    let s: f64 = headings
        .windows(2)
        .map(|w| (wrap(w[1] - w[0]).abs() / PI).min(1.0))
        .sum();
    1.0 - s / (headings.len() - 1) as f64
}

/// Displacements no longer than this are dropped by the published PS (metres).
pub const OFFICIAL_MIN_DISPLACEMENT: f64 = 1e-6;

/// PS of the published code over its update samples: the successive displacement vectors with
/// those no longer than 1e-6 m dropped, a_k = ‖v_{k+1} − v_k‖, PS = 1/(1 + 10·mean(a)); 1 until two
/// non-zero displacements exist.
pub fn official_path_smoothness(samples: &[[f64; 2]]) -> f64 {
    let v: Vec<[f64; 2]> = samples
        .windows(2)
        .map(|w| [w[1][0] - w[0][0], w[1][1] - w[0][1]])
        .filter(|d| d[0].hypot(d[1]) > OFFICIAL_MIN_DISPLACEMENT)
        .collect();
    if v.len() < 2 {
        return 1.0;
    }
    let a: f64 = v
        .windows(2)
        .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
        .sum::<f64>()
        / (v.len() - 1) as f64;
    1.0 / (1.0 + 10.0 * a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrapping() {
        assert_eq!(wrap(PI), PI);
        assert_eq!(wrap(-PI), PI);
        assert!((wrap(1.5 * PI) + 0.5 * PI).abs() < 1e-12);
        assert!((wrap(0.25) - 0.25).abs() < 1e-15);
    }

    #[test]
    fn smoothness_cases() {
        assert_eq!(path_smoothness(&[]), 1.0);
        assert_eq!(path_smoothness(&[0.3]), 1.0);
        assert_eq!(path_smoothness(&[0.0, 0.0, 0.0]), 1.0);
        // Turns of π/2 then 0: 1 − (0.5 + 0)/2 = 0.75.
        assert!((path_smoothness(&[0.0, PI / 2.0, PI / 2.0]) - 0.75).abs() < 1e-12);
        // Across the ±π seam the change is small: 3.1 → −3.1 is 0.0832 rad, not 6.2.
        let ps = path_smoothness(&[3.1, -3.1]);
        assert!((ps - (1.0 - (2.0 * PI - 6.2) / PI)).abs() < 1e-12);
        // A full reversal counts 1.
        assert_eq!(path_smoothness(&[0.0, PI]), 0.0);
    }

    #[test]
    fn official_smoothness_cases() {
        // Straight at constant speed: a = 0 → 1; repeated samples are dropped.
        let s = [[0.0, 0.0], [0.0, 0.0], [0.2, 0.0], [0.2, 0.0], [0.4, 0.0]];
        assert_eq!(official_path_smoothness(&s), 1.0);
        // One 90° corner of 0.2 m steps: a = [0, 0.2√2] → mean 0.1414 → 1/(1 + 1.414).
        let s = [[0.0, 0.0], [0.2, 0.0], [0.4, 0.0], [0.4, 0.2]];
        let expect = 1.0 / (1.0 + 10.0 * (0.2f64 * 2f64.sqrt() / 2.0));
        assert!((official_path_smoothness(&s) - expect).abs() < 1e-12);
        assert_eq!(official_path_smoothness(&[[0.0, 0.0], [1.0, 0.0]]), 1.0);
        // A jitter of 1e-6 m counts as no move (the corner then costs the same as above);
        // 2e-6 m is a move and a sharp turn.
        let s = [
            [0.0, 0.0],
            [0.2, 0.0],
            [0.2, 1e-6],
            [0.4, 1e-6],
            [0.4, 0.2 + 1e-6],
        ];
        let jitter = official_path_smoothness(&s);
        let corner = 1.0 / (1.0 + 10.0 * ((0.0 + 0.2 * 2f64.sqrt()) / 2.0));
        assert!((jitter - corner).abs() < 1e-9);
        let s = [[0.0, 0.0], [0.2, 0.0], [0.2, 2e-6], [0.4, 2e-6]];
        assert!(official_path_smoothness(&s) < 0.5);
    }
}
