//! A render's options as the front ends take them (names and numbers, the command line's
//! flags and Python's keyword arguments), turned into [`Settings`] in one place.

use crate::encode::RgbCodec;
use crate::output::Format;
use crate::preset::{ActionPreset, DEFAULT_MAX_ACTIONS};
use crate::run::Settings;
use sage_core::{Error, Result};
use sage_dataset::folder::scenes_folder;
use std::path::PathBuf;

/// The options of `sage3d data render` / `sage3d.render_training_data`; [`Options::new`]
/// gives their defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// The dataset folder.
    pub dataset: PathBuf,
    /// The scenes folder (`None`: the one the dataset records,
    /// [`sage_dataset::folder::scenes_folder`]).
    pub scenes: Option<PathBuf>,
    /// The split.
    pub split: String,
    /// The action preset's name.
    pub preset: String,
    /// MOVE_FORWARD distance overriding the preset's, metres.
    pub step: Option<f32>,
    /// Turn overriding the preset's, degrees.
    pub turn: Option<f32>,
    /// Motions per walk at most.
    pub max_actions: usize,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Horizontal field of view, degrees.
    pub hfov: f32,
    /// `rgb[,depth,semantic,instance]`.
    pub sensors: String,
    /// `navila`, `webdataset` or `frames`.
    pub format: String,
    /// Samples per NaVILA part (default 10,000) or episodes per WebDataset shard (default 100).
    pub shard_size: Option<usize>,
    /// The first N goal-directed episodes only.
    pub limit: Option<usize>,
    /// Seed of the NaVILA sample shuffle.
    pub seed: u64,
    /// Agent profile.
    pub agent: String,
    /// `jpg` or `png`.
    pub image: String,
    /// JPEG quality, 1–100.
    pub jpeg_quality: u8,
    /// Keep failed walks.
    pub keep_failed: bool,
    /// Episodes in the preview GIF.
    pub preview: usize,
    /// Where the frames are rendered: `cpu`, `gpu` or `auto`.
    pub device: String,
}

impl Options {
    /// The defaults for `dataset` and `scenes` (those of [`Settings::new`]).
    pub fn new(dataset: PathBuf, scenes: Option<PathBuf>) -> Options {
        Options {
            dataset,
            scenes,
            split: "train".into(),
            preset: "navila_small".into(),
            step: None,
            turn: None,
            max_actions: DEFAULT_MAX_ACTIONS,
            width: 224,
            height: 224,
            hfov: 90.0,
            sensors: "rgb".into(),
            format: "navila".into(),
            shard_size: None,
            limit: None,
            seed: 0,
            agent: "wheeled".into(),
            image: "jpg".into(),
            jpeg_quality: 90,
            keep_failed: false,
            preview: 0,
            device: "cpu".into(),
        }
    }

    /// The settings these options name.
    ///
    /// # Errors
    ///
    /// An unknown preset, format, sensor, image type or device, a step, turn or cap out of
    /// range, or no scenes folder given nor recorded by the dataset.
    pub fn settings(&self) -> Result<Settings> {
        let scenes = scenes_folder(&self.dataset, self.scenes.as_deref())?;
        let format: Format = self.format.parse()?;
        let preset = ActionPreset::with(
            ActionPreset::named(&self.preset)?,
            self.step,
            self.turn,
            Some(self.max_actions),
        )?;
        let rgb_codec = match self.image.as_str() {
            "jpg" | "jpeg" => RgbCodec::Jpeg {
                quality: self.jpeg_quality,
            },
            "png" => RgbCodec::Png,
            other => {
                return Err(Error::invalid(format!(
                    "image: unknown type '{other}' (jpg or png)"
                )));
            }
        };
        Ok(Settings {
            split: self.split.clone(),
            preset,
            agent: self.agent.clone(),
            width: self.width,
            height: self.height,
            hfov_deg: self.hfov,
            sensors: self.sensors.parse()?,
            rgb_codec,
            format,
            shard_size: self.shard_size.unwrap_or(match format {
                Format::Webdataset => 100,
                _ => 10_000,
            }),
            limit: self.limit,
            seed: self.seed,
            keep_failed: self.keep_failed,
            preview: self.preview,
            device: self.device.parse().map_err(|e: Error| e.within("device"))?,
            ..Settings::new(&self.dataset, &scenes)?
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sage_splat::Device;

    #[test]
    fn the_default_options_are_the_default_settings() {
        let (d, s) = (PathBuf::from("d"), PathBuf::from("s"));
        assert_eq!(
            Options::new(d.clone(), Some(s.clone())).settings().unwrap(),
            Settings::new(&d, &s).unwrap()
        );
        let wds = Options {
            format: "webdataset".into(),
            image: "png".into(),
            ..Options::new(d.clone(), Some(s.clone()))
        }
        .settings()
        .unwrap();
        assert_eq!((wds.shard_size, wds.rgb_codec), (100, RgbCodec::Png));
        let bad = Options {
            image: "gif".into(),
            ..Options::new(d.clone(), Some(s.clone()))
        };
        assert!(bad.settings().unwrap_err().to_string().contains("gif"));
        let uav = Options {
            agent: "uav".into(),
            ..Options::new(d, Some(s))
        };
        let e = uav
            .settings()
            .unwrap()
            .env_config()
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a ground agent"), "{e}");
    }

    #[test]
    fn the_device_reaches_the_environment_and_a_bad_name_is_refused() {
        let (d, s) = (PathBuf::from("d"), PathBuf::from("s"));
        let gpu = Options {
            device: "gpu".into(),
            ..Options::new(d.clone(), Some(s.clone()))
        };
        let settings = gpu.settings().unwrap();
        assert_eq!(settings.env_config().unwrap().device, Device::Gpu);
        assert_eq!(settings.recorded()["device"], "gpu");
        let cpu = Options::new(d.clone(), Some(s.clone())).settings().unwrap();
        assert!(
            cpu.recorded().get("device").is_none(),
            "CPU records stay as they were"
        );
        let bad = Options {
            device: "tpu".into(),
            ..Options::new(d, Some(s))
        };
        let e = bad.settings().unwrap_err().to_string();
        assert!(e.contains("device") && e.contains("cpu, gpu, auto"), "{e}");
    }
}
