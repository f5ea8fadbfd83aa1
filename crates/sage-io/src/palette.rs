//! Distinct, stable colours for ids in label images, legends and maps.

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
}
