//! Colours: distinct, stable colours for ids in label images, legends and maps; the
//! colour-blind-safe overlay set of the evaluation maps; muted tints for map backgrounds; and
//! the colour difference and colour-vision-deficiency simulation that check them.

/// A colour for `k` that stays the same from run to run and differs clearly from its
/// neighbours' (golden-ratio steps of hue at fixed saturation and value).
pub fn distinct_color(k: u32) -> [u8; 3] {
    let h = (k as f32 * 0.618_034).fract() * 6.0;
    let (s, v) = (0.65, 0.95);
    let f = h.fract();
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    let rgb = match h as u32 {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    };
    rgb.map(|c| (c * 255.0).round() as u8)
}

/// The colour of an id in instance and semantic images and their legends: its
/// [`distinct_color`], and black for id 0 (nothing).
pub fn id_color(id: u32) -> [u8; 3] {
    if id == 0 {
        return [0, 0, 0];
    }
    distinct_color(id)
}

/// Okabe and Ito's eight colours ("Color Universal Design", 2008), chosen to stay apart for
/// the common colour-vision deficiencies: black, orange, sky blue, bluish green, yellow, blue,
/// vermillion, reddish purple.
pub const OKABE_ITO: [[u8; 3]; 8] = [
    [0, 0, 0],
    [230, 159, 0],
    [86, 180, 233],
    [0, 158, 115],
    [240, 228, 66],
    [0, 114, 178],
    [213, 94, 0],
    [204, 121, 167],
];

/// The agent's path on an evaluation map (vermillion).
pub const AGENT_PATH: [u8; 3] = OKABE_ITO[6];
/// The reference path (blue; drawn dashed, so it also differs in line style).
pub const REFERENCE_PATH: [u8; 3] = OKABE_ITO[5];
/// The start marker (bluish green; a square).
pub const START: [u8; 3] = OKABE_ITO[3];
/// The goal marker (a diamond) and the goal region's outline (reddish purple).
pub const GOAL: [u8; 3] = OKABE_ITO[7];
/// A step that ended in contact (black; a cross on a white halo, so it shows on the walls it
/// touches).
pub const COLLISION: [u8; 3] = OKABE_ITO[0];
/// Door openings by state, as the semantic map names them. Light colours, because a door is
/// drawn inside a dark wall; a door of unknown state is a plain gap.
pub const DOOR_STATES: [(&str, [u8; 3]); 4] = [
    ("open", OKABE_ITO[2]),
    ("half-open", OKABE_ITO[4]),
    ("closed", OKABE_ITO[1]),
    ("unknown", [255, 255, 255]),
];

/// The colour of a door in `state` (`unknown`'s for a state [`DOOR_STATES`] does not name).
pub fn door_colour(state: &str) -> [u8; 3] {
    DOOR_STATES
        .iter()
        .find(|(s, _)| *s == state)
        .unwrap_or(&DOOR_STATES[3])
        .1
}

/// `c` mixed with a near-white at `keep` of its own strength (0: the near-white, 1: `c`):
/// pale, low-chroma tints for map backgrounds, so the overlays stand out on them.
pub fn muted(c: [u8; 3], keep: f32) -> [u8; 3] {
    let base = 245.0;
    c.map(|v| (base + (v as f32 - base) * keep).round().clamp(0.0, 255.0) as u8)
}

/// An sRGB channel (0–255) as linear light (0–1).
fn linear(v: u8) -> f32 {
    let c = v as f32 / 255.0;
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear light (0–1) as an sRGB channel (0–255).
fn encode(c: f32) -> u8 {
    let c = c.clamp(0.0, 1.0);
    let v = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (v * 255.0).round() as u8
}

/// CIE L*a*b* (D65 white) of an sRGB colour.
pub fn lab(c: [u8; 3]) -> [f32; 3] {
    let [r, g, b] = c.map(linear);
    let x = (0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.950_47;
    let y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
    let z = (0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.088_83;
    let f = |t: f32| {
        if t > 0.008_856 {
            t.cbrt()
        } else {
            7.787 * t + 16.0 / 116.0
        }
    };
    let (fx, fy, fz) = (f(x), f(y), f(z));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// The CIE76 colour difference ΔE*ab of two sRGB colours: about 2 is just noticeable, above
/// 10 two colours are told apart at a glance.
pub fn delta_e(a: [u8; 3], b: [u8; 3]) -> f32 {
    let (a, b) = (lab(a), lab(b));
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f32>()
        .sqrt()
}

/// A colour-vision deficiency, for [`simulate`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cvd {
    /// No long-wavelength (red) cones.
    Protan,
    /// No medium-wavelength (green) cones.
    Deutan,
    /// No short-wavelength (blue) cones.
    Tritan,
}

impl Cvd {
    /// Every deficiency [`simulate`] knows.
    pub const ALL: [Cvd; 3] = [Cvd::Protan, Cvd::Deutan, Cvd::Tritan];
}

/// How `c` looks with the full deficiency `cvd` (Machado, Oliveira and Fernandes 2009,
/// severity 1, in linear light): colours meant to differ should still differ here.
pub fn simulate(c: [u8; 3], cvd: Cvd) -> [u8; 3] {
    let m: [[f32; 3]; 3] = match cvd {
        Cvd::Protan => [
            [0.152_286, 1.052_583, -0.204_868],
            [0.114_503, 0.786_281, 0.099_216],
            [-0.003_882, -0.048_116, 1.051_998],
        ],
        Cvd::Deutan => [
            [0.367_322, 0.860_646, -0.227_968],
            [0.280_085, 0.672_501, 0.047_413],
            [-0.011_820, 0.042_940, 0.968_881],
        ],
        Cvd::Tritan => [
            [1.255_528, -0.076_749, -0.178_779],
            [-0.078_411, 0.930_809, 0.147_602],
            [0.004_733, 0.691_367, 0.303_900],
        ],
    };
    let l = c.map(linear);
    m.map(|row| encode(row[0] * l[0] + row[1] * l[1] + row[2] * l[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbouring_ids_get_clearly_different_colours() {
        for k in 1..500 {
            let (a, b) = (distinct_color(k), distinct_color(k + 1));
            let d: i32 = a
                .iter()
                .zip(b)
                .map(|(x, y)| (*x as i32 - y as i32).abs())
                .sum();
            assert!(d > 60, "{k}: {a:?} vs {b:?}");
        }
    }

    #[test]
    fn colour_difference_and_simulation_match_known_values() {
        // White and black are 100 apart in L*; a grey is as a dichromat sees it.
        assert!((delta_e([255; 3], [0; 3]) - 100.0).abs() < 0.1);
        assert_eq!(
            lab([255; 3]).map(|v| (v * 10.0).round() / 10.0),
            [100.0, 0.0, 0.0]
        );
        for cvd in Cvd::ALL {
            let grey = simulate([128; 3], cvd);
            assert!(
                grey.iter().all(|v| v.abs_diff(128) <= 1),
                "{cvd:?}: {grey:?}"
            );
        }
        // Red and green, told apart at a glance with full colour vision, nearly merge for a
        // deuteranope: the simulation shows what the overlay colours are chosen against.
        let (red, green) = ([200, 40, 40], [40, 170, 60]);
        assert!(delta_e(red, green) > 60.0);
        let (r, g) = (simulate(red, Cvd::Deutan), simulate(green, Cvd::Deutan));
        assert!(delta_e(r, g) < 25.0, "{}", delta_e(r, g));
    }

    #[test]
    fn doors_of_unknown_states_get_the_unknown_colour_and_muting_keeps_the_hue() {
        assert_eq!(door_colour("closed"), OKABE_ITO[1]);
        assert_eq!(door_colour("ajar"), door_colour("unknown"));
        assert_eq!(muted([200, 40, 40], 1.0), [200, 40, 40]);
        assert_eq!(muted([200, 40, 40], 0.0), [245; 3]);
        let m = muted([200, 40, 40], 0.35);
        assert!(m[0] > m[1] && m[1] == m[2] && m[1] > 150, "{m:?}");
    }
}
