//! Flag values that several commands parse the same way.

use sage_core::Result;
use sage_splat::Device;
use sage_splat::MAX_IMAGE_SIDE;

/// The settings that library errors name in backticks (`` `force` ``) and that this command
/// line takes as flags of the same name.
const NAMED_SETTINGS: [&str; 50] = [
    "jpeg_quality",
    "min_distance",
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
    "narrow_weight",
    "yaw",
    "pitch",
    "position",
    "offsets",
    "baseline",
    "count",
    "per_scene",
    "base_actions",
    "nogoal",
    "high_per_type",
    "budget",
    "point",
    "offset",
    "max_actions",
    "shard_size",
    "background",
    "turntable",
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

/// A `WxH` image size (`--size`, `--sizes`) as (width, height), each side 1 to
/// [`MAX_IMAGE_SIDE`] pixels as every camera takes it: clap's parser of those flags, so that a
/// bad size exits 2 naming its flag.
///
/// # Errors
///
/// Not `WxH` of whole numbers, or a side out of range.
pub fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("'{s}' is not WxH"))?;
    let side = |v: &str| match v.trim().parse::<u32>() {
        Ok(n) if (1..=MAX_IMAGE_SIDE).contains(&n) => Ok(n),
        Ok(n) => Err(format!("{n} is not in 1..={MAX_IMAGE_SIDE} pixels")),
        Err(_) => Err(format!("'{s}' is not WxH")),
    };
    Ok((side(w)?, side(h)?))
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
