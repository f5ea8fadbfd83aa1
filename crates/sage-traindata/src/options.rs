//! A render's options: the one typed form of the settings of `sage3d data render`,
//! `sage3d.render_training_data` and a `[data.render]` table, with their defaults in one
//! place ([`Default`]). The command line takes them as flags (`clap::Args`, cargo feature
//! `clap`), Python and settings files as named values (serde); [`Options::settings`] resolves
//! them into the [`Settings`] a render runs with.

use crate::encode::ImageType;
use crate::output::Layout;
use crate::preset::{ActionPreset, Answers, DEFAULT_MAX_ACTIONS, PresetName};
use crate::run::{Sensors, Settings};
use sage_core::{Error, Result};
use sage_dataset::folder::scenes_folder;
use sage_physics::{AgentProfile, SplatBodies};
use sage_splat::Device;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The options of a training-data render; [`Options::default`] gives every default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default, deny_unknown_fields)]
pub struct Options {
    /// The dataset folder (made by `sage3d data build`: episodes/{split}.jsonl).
    #[cfg_attr(feature = "clap", arg(value_name = "DATASET"))]
    pub dataset: PathBuf,
    /// A scene folder, or a folder of scene folders, holding the dataset's scenes (default: the
    /// scenes folder the dataset was built from, as its sage3d_run.json records it).
    #[cfg_attr(feature = "clap", arg(long))]
    pub scenes: Option<PathBuf>,
    /// The split to render (one of those DATASET/splits.json lists).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = Options::default().split))]
    pub split: String,
    /// Action preset: vlnce (0.25 m, 15°), navila_small (0.35 m, 30°), navila_large
    /// (0.75 m, 15°), custom_small (0.50 m, 30°).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = Options::default().preset))]
    pub preset: PresetName,
    /// MOVE_FORWARD distance in metres (overrides the preset's).
    #[cfg_attr(feature = "clap", arg(long))]
    pub step: Option<f32>,
    /// Turn angle in degrees (overrides the preset's).
    #[cfg_attr(feature = "clap", arg(long))]
    pub turn: Option<f32>,
    /// Motions per trajectory at most; past it the walk calls STOP where it stands.
    #[cfg_attr(
        feature = "clap",
        arg(
            long,
            default_value_t = Options::default().max_actions,
            value_parser = max_actions()
        )
    )]
    pub max_actions: usize,
    /// How answers word the actions: sage (SAGE-3D's, `move forward 0.35 meter`) or navila
    /// (stock NaVILA's and its evaluator's, `move forward 35 cm`: a step of whole centimetres
    /// and a turn of whole degrees, else refused).
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "sage|navila", default_value_t = Options::default().answers)
    )]
    pub answers: Answers,
    /// Image width in pixels (the published pipeline rendered 1024×768).
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = Options::default().width, value_parser = image_side())
    )]
    pub width: u32,
    /// Image height in pixels.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = Options::default().height, value_parser = image_side())
    )]
    pub height: u32,
    /// Horizontal field of view in degrees.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = Options::default().hfov, value_parser = sage_env::config::parse_hfov)
    )]
    pub hfov: f32,
    /// Images per frame, comma-separated: rgb and any of depth, semantic, instance (depth: 16-bit
    /// PNG millimetres).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = Options::default().sensors))]
    #[serde(with = "sensor_names")]
    pub sensors: Sensors,
    /// Output layout: navila, webdataset, frames or lerobot (LeRobot v3.0; frames always PNG).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = Options::default().format))]
    pub format: Layout,
    /// Samples per NaVILA part (default 10000), episodes per WebDataset shard (default 100).
    #[cfg_attr(feature = "clap", arg(long))]
    pub shard_size: Option<usize>,
    /// Render only the first N goal-directed episodes of the split.
    #[cfg_attr(feature = "clap", arg(long))]
    pub limit: Option<usize>,
    /// Seed of the NaVILA sample shuffle.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = Options::default().seed))]
    pub seed: u64,
    /// Agent profile (camera height, body radius): wheeled, go2, g1 or h1.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = Options::default().agent))]
    #[serde(with = "sage_physics::agent::profile_name")]
    pub agent: AgentProfile,
    /// RGB file type: jpg or png.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = Options::default().image))]
    pub image: ImageType,
    /// JPEG quality (1–100).
    #[cfg_attr(
        feature = "clap",
        arg(
            long,
            default_value_t = Options::default().jpeg_quality,
            value_parser = clap::value_parser!(u8).range(1..=100)
        )
    )]
    pub jpeg_quality: u8,
    /// Keep episodes whose walk collided or ended farther than 1 m from the goal (dropped by
    /// default; counted either way).
    #[cfg_attr(feature = "clap", arg(long))]
    pub keep_failed: bool,
    /// Write preview.gif of the first N kept episodes (frames with instruction and action,
    /// beside the top-down map with the pose).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = Options::default().preview))]
    pub preview: usize,
    /// Where the frames are rendered: cpu; gpu (any GPU adapter, a software one such as Mesa's
    /// lavapipe included; an error when there is none); or auto (a hardware GPU when there is
    /// one, else the CPU).
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "cpu|gpu|auto", default_value_t = Options::default().device)
    )]
    pub device: Device,
    /// Which objects get bodies recovered from their Gaussians for the walks, as `sage3d
    /// physics build --splat-bodies`: auto (those with neither a published body nor a mesh),
    /// always (every object) or never (boxes instead).
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "auto|always|never", default_value_t = Options::default().splat_bodies)
    )]
    pub splat_bodies: SplatBodies,
}

/// The parser of `--max-actions`: the caps every path takes ([`MAX_ACTIONS_RANGE`](crate::preset::MAX_ACTIONS_RANGE)).
#[cfg(feature = "clap")]
fn max_actions() -> clap::builder::RangedU64ValueParser<usize> {
    let caps = crate::preset::MAX_ACTIONS_RANGE;
    clap::builder::RangedU64ValueParser::<usize>::new()
        .range(*caps.start() as u64..=*caps.end() as u64)
}

/// The parser of `--width` and `--height`: the sensors' sizes ([`sage_env::config::IMAGE_SIDE`]).
#[cfg(feature = "clap")]
fn image_side() -> clap::builder::RangedI64ValueParser<u32> {
    let side = sage_env::config::IMAGE_SIDE;
    clap::value_parser!(u32).range(i64::from(*side.start())..=i64::from(*side.end()))
}

impl Default for Options {
    /// The published defaults: split `train`, `navila_small` in SAGE-3D's words, the wheeled robot (camera
    /// 1.2 m), 224×224 RGB at 90° HFOV as JPEG quality 90, the NaVILA layout, seed 0, failed
    /// walks dropped, on the CPU. No dataset is named.
    fn default() -> Self {
        Options {
            dataset: PathBuf::new(),
            scenes: None,
            split: "train".into(),
            preset: PresetName::default(),
            step: None,
            turn: None,
            max_actions: DEFAULT_MAX_ACTIONS,
            answers: Answers::default(),
            width: 224,
            height: 224,
            hfov: 90.0,
            sensors: Sensors::default(),
            format: Layout::default(),
            shard_size: None,
            limit: None,
            seed: 0,
            agent: AgentProfile::default(),
            image: ImageType::default(),
            jpeg_quality: 90,
            keep_failed: false,
            preview: 0,
            device: Device::default(),
            splat_bodies: SplatBodies::default(),
        }
    }
}

impl Options {
    /// The defaults for `dataset` and `scenes`.
    pub fn new(dataset: PathBuf, scenes: Option<PathBuf>) -> Options {
        Options {
            dataset,
            scenes,
            ..Options::default()
        }
    }

    /// The settings these options name, with the scenes folder given or the one the dataset
    /// records.
    ///
    /// # Errors
    ///
    /// No scenes folder given nor recorded by the dataset, or as [`Options::settings_with`].
    pub fn settings(&self) -> Result<Settings> {
        let scenes = scenes_folder(&self.dataset, self.scenes.as_deref())?;
        self.settings_with(&scenes)
    }

    /// The settings these options name over the scenes folder `scenes` (no file is read).
    ///
    /// # Errors
    ///
    /// A step, turn, cap or JPEG quality out of range; a step or turn the `answers` wording
    /// cannot say exactly.
    pub fn settings_with(&self, scenes: &Path) -> Result<Settings> {
        if !(1..=100).contains(&self.jpeg_quality) {
            return Err(Error::invalid(format!(
                "`jpeg_quality` must be 1-100, got {}",
                self.jpeg_quality
            )));
        }
        let preset = ActionPreset::with(
            self.preset.preset(),
            self.step,
            self.turn,
            Some(self.max_actions),
        )?
        .worded(self.answers)?;
        Ok(Settings {
            dataset: self.dataset.clone(),
            scenes: scenes.to_path_buf(),
            split: self.split.clone(),
            preset,
            agent: self.agent.name.to_string(),
            width: self.width,
            height: self.height,
            hfov_deg: self.hfov,
            sensors: self.sensors,
            // LeRobot's image feature holds PNG bytes: lossless, as LeRobot writes them.
            rgb_codec: match self.format {
                Layout::Lerobot => crate::encode::RgbCodec::Png,
                _ => self.image.codec(self.jpeg_quality),
            },
            format: self.format,
            shard_size: self.shard_size.unwrap_or(match self.format {
                Layout::Webdataset => 100,
                _ => 10_000,
            }),
            limit: self.limit,
            seed: self.seed,
            keep_failed: self.keep_failed,
            preview: self.preview,
            device: self.device,
            splat_bodies: self.splat_bodies,
        })
    }
}

/// Sensors in settings files and Python as names: `"rgb,depth"` or `["rgb", "depth"]`.
mod sensor_names {
    use crate::run::Sensors;
    use serde::{Deserialize, Deserializer, Serializer};

    /// Either form of the names.
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Names {
        Text(String),
        List(Vec<String>),
    }

    pub fn serialize<S: Serializer>(sensors: &Sensors, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(sensors)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Sensors, D::Error> {
        let text = match Names::deserialize(d)? {
            Names::Text(t) => t,
            Names::List(v) => v.join(","),
        };
        text.parse().map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::RgbCodec;

    #[test]
    fn the_default_options_are_the_default_settings() {
        let (d, s) = (PathBuf::from("d"), PathBuf::from("s"));
        assert_eq!(
            Options::new(d.clone(), Some(s.clone())).settings().unwrap(),
            Settings::new(&d, &s).unwrap()
        );
        let wds = Options {
            format: Layout::Webdataset,
            image: ImageType::Png,
            ..Options::new(d.clone(), Some(s.clone()))
        }
        .settings()
        .unwrap();
        assert_eq!((wds.shard_size, wds.rgb_codec), (100, RgbCodec::Png));
        let uav = Options {
            agent: "uav".parse().unwrap(),
            ..Options::new(d, Some(s))
        };
        let e = uav
            .settings()
            .unwrap()
            .env_config()
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a ground agent"), "{e}");
        let none = Options {
            limit: Some(0),
            ..Options::new(PathBuf::from("d"), Some(PathBuf::from("s")))
        };
        let e = none
            .settings()
            .unwrap()
            .env_config()
            .unwrap_err()
            .to_string();
        assert!(e.contains("`limit` 0 renders nothing"), "{e}");
    }

    #[test]
    fn named_values_read_with_defaults_and_bad_ones_are_refused_by_name() {
        let o: Options = serde_json::from_str(
            r#"{"preset": "vlnce", "sensors": ["rgb", "depth"], "image": "jpeg", "agent": "go2", "device": "gpu"}"#,
        )
        .unwrap();
        assert_eq!(o.preset, PresetName::Vlnce);
        assert!(o.sensors.depth && !o.sensors.semantic);
        assert_eq!(
            (o.image, o.agent.name, o.device),
            (ImageType::Jpg, "go2", Device::Gpu)
        );
        assert_eq!(o.width, Options::default().width);
        let settings = o.settings_with(Path::new("s")).unwrap();
        assert_eq!(settings.env_config().unwrap().device, Device::Gpu);
        assert_eq!(settings.recorded()["device"], "gpu");
        // Written back, the options read as the same options.
        let text = serde_json::to_string(&o).unwrap();
        assert_eq!(serde_json::from_str::<Options>(&text).unwrap(), o);
        for (bad, named) in [
            (r#"{"image": "gif"}"#, "gif"),
            (r#"{"device": "tpu"}"#, "tpu"),
            (r#"{"agent": "tank"}"#, "tank"),
            (r#"{"sensors": "rgb,heat"}"#, "heat"),
            (r#"{"preset": "habitat"}"#, "habitat"),
            (r#"{"widht": 3}"#, "widht"),
        ] {
            let e = serde_json::from_str::<Options>(bad)
                .unwrap_err()
                .to_string();
            assert!(e.contains(named), "{bad}: {e}");
        }
        // The LeRobot layout has no feature for ids: asking for them is refused, not ignored.
        let ids: Options =
            serde_json::from_str(r#"{"format": "lerobot", "sensors": "rgb,depth,semantic"}"#)
                .unwrap();
        let e = ids
            .settings_with(Path::new("s"))
            .unwrap()
            .env_config()
            .unwrap_err()
            .to_string();
        assert!(e.contains("LeRobot") && e.contains("semantic"), "{e}");
        let cpu = Options::default().settings_with(Path::new("s")).unwrap();
        assert!(
            cpu.recorded().get("device").is_none(),
            "CPU records stay as they were"
        );
        assert!(
            cpu.recorded().get("splat_bodies").is_none(),
            "records of the default bodies stay as they were"
        );
        let never: Options = serde_json::from_str(r#"{"splat_bodies": "never"}"#).unwrap();
        let settings = never.settings_with(Path::new("s")).unwrap();
        assert_eq!(settings.recorded()["splat_bodies"], "never");
        assert_eq!(
            settings.env_config().unwrap().splat_bodies,
            SplatBodies::Never
        );
        let e = serde_json::from_str::<Options>(r#"{"splat_bodies": "sometimes"}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("sometimes"), "{e}");
    }

    #[test]
    fn the_motion_cap_is_bounded_on_every_path_naming_max_actions() {
        for bad in [0, 1_000_001, usize::MAX] {
            let o: Options =
                serde_json::from_value(serde_json::json!({ "max_actions": bad })).unwrap();
            let e = o.settings_with(Path::new("s")).unwrap_err().to_string();
            assert!(
                e.contains("`max_actions`") && e.contains("1..=1000000"),
                "{bad}: {e}"
            );
        }
        let most: Options = serde_json::from_str(r#"{"max_actions": 1000000}"#).unwrap();
        let settings = most.settings_with(Path::new("s")).unwrap();
        assert_eq!(settings.env_config().unwrap().task.max_steps, 1_000_001);
        // Settings JSON that never went through the options (a distributed render's steps) is
        // refused where a render starts, not overflowed into the step limit.
        let mut text = serde_json::to_value(&settings).unwrap();
        text["preset"]["max_actions"] = serde_json::json!(usize::MAX);
        let direct: Settings = serde_json::from_value(text).unwrap();
        let e = direct.env_config().unwrap_err().to_string();
        assert!(e.contains("`max_actions`"), "{e}");
    }

    #[test]
    fn the_answers_wording_is_recorded_when_not_the_default_and_checked_up_front() {
        let sage = Options::default().settings_with(Path::new("s")).unwrap();
        assert!(
            sage.recorded()["preset"].get("answers").is_none(),
            "records of SAGE-3D's wording stay as they were"
        );
        let navila: Options =
            serde_json::from_str(r#"{"preset": "navila_large", "answers": "navila"}"#).unwrap();
        let settings = navila.settings_with(Path::new("s")).unwrap();
        assert_eq!(settings.recorded()["preset"]["answers"], "navila");
        assert_eq!(
            settings.preset.words(sage_env::Action::MoveForward),
            "move forward 75 cm"
        );
        // The settings a Python step reads back are the same settings.
        let text = serde_json::to_string(&settings).unwrap();
        assert_eq!(serde_json::from_str::<Settings>(&text).unwrap(), settings);
        // A step NaVILA's words cannot say is refused before any file is read.
        let odd = Options {
            step: Some(0.255),
            ..navila.clone()
        };
        let e = odd.settings_with(Path::new("s")).unwrap_err().to_string();
        assert!(e.contains("`answers`") && e.contains("25.5 cm"), "{e}");
        let e = Options {
            turn: Some(7.5),
            ..navila.clone()
        }
        .settings_with(Path::new("s"))
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("`answers`") && e.contains("whole degrees"),
            "{e}"
        );
        // Settings made without the options are checked where a render starts.
        let mut direct = settings;
        direct.preset.turn_deg = 22.5;
        let e = direct.env_config().unwrap_err().to_string();
        assert!(e.contains("`answers`"), "{e}");
        for bad in [r#"{"answers": "cm"}"#, r#"{"answers": 5}"#] {
            let e = serde_json::from_str::<Options>(bad)
                .unwrap_err()
                .to_string();
            assert!(e.contains("cm") || e.contains("string"), "{bad}: {e}");
        }
    }
}
