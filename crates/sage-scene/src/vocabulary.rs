//! The attribute words of the scene model that several layers share: the colour words an
//! object's `color` attribute carries and the colour each names.
//!
//! The generator renders objects in these colours, reconstruction paints an object with the
//! colour of its word, and the instruction validator counts every word here as grounded, so all
//! three must read the same list.

/// The colour words of the `color` attribute and the sRGB (0–1) each names.
pub const COLORS: &[(&str, [f32; 3])] = &[
    ("white", [0.92, 0.92, 0.90]),
    ("cream", [0.93, 0.88, 0.74]),
    ("beige", [0.82, 0.74, 0.60]),
    ("tan", [0.76, 0.60, 0.42]),
    ("brown", [0.48, 0.31, 0.18]),
    ("dark brown", [0.30, 0.19, 0.11]),
    ("black", [0.08, 0.08, 0.09]),
    ("gray", [0.50, 0.50, 0.52]),
    ("light gray", [0.76, 0.76, 0.77]),
    ("silver", [0.70, 0.72, 0.75]),
    ("gold", [0.83, 0.67, 0.28]),
    ("red", [0.72, 0.14, 0.12]),
    ("orange", [0.90, 0.48, 0.12]),
    ("yellow", [0.93, 0.80, 0.22]),
    ("green", [0.25, 0.52, 0.26]),
    ("dark green", [0.13, 0.30, 0.15]),
    ("teal", [0.10, 0.50, 0.50]),
    ("blue", [0.18, 0.36, 0.70]),
    ("light blue", [0.64, 0.77, 0.88]),
    ("navy", [0.10, 0.14, 0.33]),
    ("purple", [0.45, 0.25, 0.55]),
    ("pink", [0.90, 0.62, 0.68]),
    ("terracotta", [0.72, 0.38, 0.24]),
];

/// The sRGB (0–1) of a colour word of [`COLORS`], or `None` for any other word.
pub fn color_rgb(name: &str) -> Option<[f32; 3]> {
    COLORS.iter().find(|(n, _)| *n == name).map(|(_, rgb)| *rgb)
}
