//! Flag values that several commands parse the same way.

use sage_core::{Error, Result};
use sage_splat::Device;

/// The settings that library errors name in backticks (`` `force` ``) and that this command
/// line takes as flags of the same name.
const NAMED_SETTINGS: [&str; 31] = [
    "jpeg_quality",
    "objects",
    "seed",
    "cell",
    "length_mix",
    "force",
    "play",
    "public",
    "scenes",
    "split",
    "out",
    "strict",
    "points",
    "sh_degree",
    "input",
    "agents",
    "agent",
    "scene_unseen",
    "val",
    "scale_points",
    "scale_distance",
    "scale",
    "floater_opacity",
    "floater_radius",
    "keep_failed",
    "sensors",
    "agent_height",
    "limit",
    "answers",
    "step",
    "turn",
];

/// A library error's text as the command line says it: each setting the text names in
/// backticks becomes its flag (`` `sh_degree` `` → `--sh-degree`), since libraries speak of
/// settings and the user typed flags.
pub fn in_flags(message: &str) -> String {
    NAMED_SETTINGS
        .iter()
        .fold(message.to_string(), |text, name| {
            text.replace(
                &format!("`{name}`"),
                &format!("--{}", name.replace('_', "-")),
            )
        })
}

/// A whole-number flag's parser that refuses values outside `range`, so that clap names the
/// flag and the command exits 2 as for any value the command line cannot take.
pub fn count_in(
    range: std::ops::RangeInclusive<usize>,
) -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::new().range(*range.start() as u64..=*range.end() as u64)
}

/// A horizontal field of view in degrees, in (0, 180) as every camera takes it (`--hfov`).
pub fn parse_hfov(s: &str) -> std::result::Result<f32, String> {
    let v: f32 = s.trim().parse().map_err(|e| format!("{e}"))?;
    if v > 0.0 && v < 180.0 {
        Ok(v)
    } else {
        Err(format!("{v} is not in (0, 180) degrees"))
    }
}

/// A `WxH` image size (`--size`, `--sizes`) as (width, height).
pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| Error::invalid(format!("size '{s}' is not WxH")))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| Error::invalid(format!("size '{s}' is not WxH")))
    };
    Ok((parse(w)?, parse(h)?))
}

/// `--device`, the same on every command that renders.
#[derive(clap::Args, Clone, Copy, Debug)]
pub struct DeviceFlag {
    /// Where images are rendered: cpu; gpu (any GPU adapter, a software one such as Mesa's
    /// lavapipe included; an error when there is none); or auto (a hardware GPU when there is
    /// one, else the CPU).
    #[arg(long, value_name = "cpu|gpu|auto", default_value = "cpu")]
    pub device: Device,
}

impl DeviceFlag {
    /// Opens the device before any work, so that a GPU that cannot be had fails the command
    /// at once, and returns the renderer in words ([`Device::probe`]).
    ///
    /// # Errors
    ///
    /// `gpu` without a usable adapter, or a build without the GPU renderer.
    pub fn probe(&self) -> Result<String> {
        probe(self.device)
    }
}

/// Opens `device` before any work and returns the renderer in words, naming `--device` on
/// failure ([`DeviceFlag::probe`]).
///
/// # Errors
///
/// As [`Device::probe`].
pub fn probe(device: Device) -> Result<String> {
    device.probe().map_err(|e| e.within("--device"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_settings_become_flags_and_other_text_stays() {
        assert_eq!(
            in_flags("choose another `split`, or set `force`; `sh_degree` 3; `sage3d eval`"),
            "choose another --split, or set --force; --sh-degree 3; `sage3d eval`"
        );
    }
}
