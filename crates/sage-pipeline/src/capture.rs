//! A capture of one's own as a scene folder: `sage3d scene import CAPTURE --out SCENE`.
//!
//! The capture (any 3DGS file sage3d reads) is put in the world frame W by `sage_capture`
//! (gravity and floor found, metric scale applied, floaters removed), and written as an
//! InteriorGS-layout folder with no labels: the Gaussians, the occupancy map derived from them
//! (`sage_nav::splat_grid`), `capture.json` (what was done to the capture: the transform, the
//! scale, the floor fit, the floaters) and the run record. Everything is computed before the
//! folder is touched, and a failed write removes what it wrote, so a bad capture leaves no
//! folder behind and an interrupted one no folder that looks complete.

use glam::Vec3;
use sage_capture::{Aligned, CaptureSettings, FloaterSettings, FloorFit, FloorSettings, Scale, Up};
use sage_core::{Error, Result};
use sage_nav::GridParams;
use sage_nav::splat_grid::{SplatGridParams, gaussian_grid};
use sage_scene::SplatLayout;
use sage_scene::occupancy::OccupancyMap;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

pub use sage_capture::{CEILING_AREA_SHARE, MAX_CEILING_M, MIN_CEILING_M};

/// The command that imports captures, as its run record names it.
pub const IMPORT_COMMAND: &str = sage_scene::scene::writers::IMPORT;

/// The provenance file of an imported capture.
pub const CAPTURE_FILE: &str = sage_scene::scene::files::CAPTURE;

/// Two points of the capture, in its own coordinates (`x1,y1,z1:x2,y2,z2` on the command
/// line; `[[x1, y1, z1], [x2, y2, z2]]` in files and Python).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScalePoints(pub [[f32; 3]; 2]);

impl FromStr for ScalePoints {
    type Err = Error;

    fn from_str(s: &str) -> Result<ScalePoints> {
        let bad = || Error::invalid(format!("expected two points x1,y1,z1:x2,y2,z2, got '{s}'"));
        let (a, b) = s.split_once(':').ok_or_else(bad)?;
        let point = |t: &str| -> Result<[f32; 3]> {
            let v: Vec<f32> = t
                .split(',')
                .map(|x| x.trim().parse::<f32>().map_err(|_| bad()))
                .collect::<Result<_>>()?;
            <[f32; 3]>::try_from(v).map_err(|_| bad())
        };
        Ok(ScalePoints([point(a)?, point(b)?]))
    }
}

impl fmt::Display for ScalePoints {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [a, b] = self.0;
        write!(f, "{},{},{}:{},{},{}", a[0], a[1], a[2], b[0], b[1], b[2])
    }
}

/// The Gaussian file written.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OutputLayout {
    /// `3dgs_compressed.ply` (SuperSplat chunked; what InteriorGS ships).
    #[default]
    Compressed,
    /// `3dgs.ply` (standard Inria layout, every value as computed).
    Standard,
}

impl OutputLayout {
    /// `compressed` or `standard`.
    pub fn as_str(self) -> &'static str {
        match self {
            OutputLayout::Compressed => "compressed",
            OutputLayout::Standard => "standard",
        }
    }

    fn layout(self) -> SplatLayout {
        match self {
            OutputLayout::Compressed => SplatLayout::Compressed,
            OutputLayout::Standard => SplatLayout::Standard,
        }
    }

    fn file(self) -> &'static str {
        match self {
            OutputLayout::Compressed => sage_scene::scene::files::COMPRESSED_PLY,
            OutputLayout::Standard => sage_scene::scene::files::STANDARD_PLY,
        }
    }
}

impl fmt::Display for OutputLayout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for OutputLayout {
    type Err = Error;

    fn from_str(s: &str) -> Result<OutputLayout> {
        match s.trim().to_ascii_lowercase().as_str() {
            "compressed" => Ok(OutputLayout::Compressed),
            "standard" => Ok(OutputLayout::Standard),
            _ => Err(Error::invalid(format!(
                "unknown layout '{s}' (expected compressed or standard)"
            ))),
        }
    }
}

/// The settings of [`import`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default, deny_unknown_fields)]
pub struct ImportSettings {
    /// Metres per capture unit (default: the capture is taken to be in metres).
    #[cfg_attr(
        feature = "clap",
        arg(
            long,
            conflicts_with = "scale_points",
            allow_hyphen_values = true,
            value_parser = positive
        )
    )]
    pub scale: Option<f32>,
    /// Two points in the capture's own coordinates, x1,y1,z1:x2,y2,z2, whose true distance
    /// in metres is the scale distance.
    #[cfg_attr(
        feature = "clap",
        arg(long, requires = "scale_distance", allow_hyphen_values = true)
    )]
    pub scale_points: Option<ScalePoints>,
    /// The true distance between the scale points, metres.
    #[cfg_attr(
        feature = "clap",
        arg(
            long,
            requires = "scale_points",
            conflicts_with = "scale",
            allow_hyphen_values = true,
            value_parser = positive
        )
    )]
    pub scale_distance: Option<f32>,
    /// Which way is up in the capture: auto (found from floor, ceiling and walls), x, -x, y,
    /// -y, z or -z.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = Up::Auto, allow_hyphen_values = true)
    )]
    pub up: Up,
    /// Gaussians fainter than this opacity may be floaters.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = FloaterSettings::default().max_opacity))]
    pub floater_opacity: f32,
    /// A faint Gaussian with fewer others within this radius (metres) than the floater
    /// neighbours is a floater.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = FloaterSettings::default().radius))]
    pub floater_radius: f32,
    /// The fewest others a faint Gaussian has within the floater radius not to be a floater;
    /// 0 keeps every Gaussian.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = FloaterSettings::default().min_neighbours))]
    pub floater_neighbours: usize,
    /// Gaussian file layout written.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = OutputLayout::Compressed))]
    pub layout: OutputLayout,
    /// Occupancy cell, metres.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = GridParams::default().cell, value_parser = cell_size)
    )]
    pub cell: f32,
    /// Top of the agent's slab in the occupancy map, metres.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = GridParams::default().agent_height))]
    pub agent_height: f32,
}

impl Default for ImportSettings {
    fn default() -> Self {
        let floaters = FloaterSettings::default();
        let grid = GridParams::default();
        ImportSettings {
            scale: None,
            scale_points: None,
            scale_distance: None,
            up: Up::Auto,
            floater_opacity: floaters.max_opacity,
            floater_radius: floaters.radius,
            floater_neighbours: floaters.min_neighbours,
            layout: OutputLayout::Compressed,
            cell: grid.cell,
            agent_height: grid.agent_height,
        }
    }
}

impl ImportSettings {
    /// The capture settings these give, checked.
    ///
    /// # Errors
    ///
    /// A scale of 0 or less, both a scale and scale points, scale points without a distance
    /// (or the reverse), two identical scale points, or a setting out of range; each named.
    pub fn capture_settings(&self) -> Result<CaptureSettings> {
        let scale = match (self.scale, self.scale_points, self.scale_distance) {
            (Some(_), Some(_), _) => {
                return Err(Error::invalid(
                    "give either `scale` or `scale_points` with `scale_distance`, not both",
                ));
            }
            (Some(_), None, Some(_)) => {
                return Err(Error::invalid(
                    "`scale_distance` goes with `scale_points`, not with `scale`",
                ));
            }
            (Some(value), None, None) => Scale::Given { value },
            (None, Some(p), Some(distance)) => Scale::Points {
                a: Vec3::from_array(p.0[0]),
                b: Vec3::from_array(p.0[1]),
                distance,
            },
            (None, Some(_), None) => {
                return Err(Error::invalid(
                    "`scale_points` need `scale_distance`: the true distance between them in metres",
                ));
            }
            (None, None, Some(_)) => {
                return Err(Error::invalid(
                    "`scale_distance` needs `scale_points`: the two points it is the distance between",
                ));
            }
            (None, None, None) => Scale::None,
        };
        scale.factor()?;
        let settings = CaptureSettings {
            scale,
            floor: FloorSettings {
                up: self.up,
                ..FloorSettings::default()
            },
            floaters: FloaterSettings {
                max_opacity: self.floater_opacity,
                radius: self.floater_radius,
                min_neighbours: self.floater_neighbours,
            },
        };
        settings.floaters.validate()?;
        self.grid_params().validate()?;
        Ok(settings)
    }

    fn grid_params(&self) -> GridParams {
        GridParams {
            cell: self.cell,
            agent_height: self.agent_height,
            ..GridParams::default()
        }
    }
}

/// A finite number > 0, for the command line's parser, so that a value out of range is
/// refused as a malformed one is (exit status 2); [`ImportSettings::capture_settings`] checks
/// the same for settings from elsewhere.
#[cfg(feature = "clap")]
fn positive(s: &str) -> std::result::Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        Ok(v) => Err(format!("must be a finite number > 0, got {v}")),
        Err(e) => Err(e.to_string()),
    }
}

/// An occupancy cell size within the grid's range ([`GridParams::validate`]), for the command
/// line's parser.
#[cfg(feature = "clap")]
fn cell_size(s: &str) -> std::result::Result<f32, String> {
    let cell = s.trim().parse::<f32>().map_err(|e| e.to_string())?;
    GridParams {
        cell,
        ..GridParams::default()
    }
    .validate()
    .map(|()| cell)
    .map_err(|e| e.message().to_string())
}

/// The stages of [`import`], as they start.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Reading the capture.
    Reading,
    /// Finding floor and floaters, transforming.
    Aligning,
    /// Building the occupancy map.
    Mapping,
    /// Writing the folder.
    Writing,
}

/// What [`import`] did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImportReport {
    /// The capture read.
    pub input: PathBuf,
    /// Its format (told from its content).
    pub format: String,
    /// Gaussians in the capture.
    pub gaussians_in: usize,
    /// Floaters removed.
    pub floaters: usize,
    /// Gaussians written.
    pub gaussians_out: usize,
    /// Metres per capture unit.
    pub scale: f32,
    /// Where the scale came from (`none`, `given`, `points`).
    pub scale_source: String,
    /// Gravity's up in the capture's axes.
    pub up: [f32; 3],
    /// The capture's tilt from its nearest axis, degrees.
    pub tilt_deg: f32,
    /// Floor area found, m².
    pub floor_area: f32,
    /// Floor fit's root mean square distance, metres.
    pub floor_rms: f32,
    /// Floor-to-ceiling height found, metres (0: no ceiling).
    pub ceiling: f32,
    /// The highest plane facing up, metres above the floor (the ceiling, or what was too low
    /// or too small to be one; 0: none).
    pub top_plane: f32,
    /// The shift in x and y, metres, that brought a capture far from its origin back to it
    /// (`None`: x and y kept).
    pub recentred: Option<[f32; 2]>,
    /// The turn about up that put the walls on x and y, degrees.
    pub yaw_deg: f32,
    /// Free area of the occupancy map, m².
    pub free_m2: f32,
    /// Occupied area of the occupancy map, m².
    pub occupied_m2: f32,
    /// The Gaussian file written (`3dgs_compressed.ply` or `3dgs.ply`).
    pub splat_file: String,
    /// What that file does not hold of the Gaussians as computed (the compressed layout
    /// quantises every value; the standard one loses nothing: empty).
    pub losses: Vec<String>,
    /// What looks wrong with the result, each with its likely cause and what to try (see
    /// [`plausibility`]); the import went through.
    pub warnings: Vec<String>,
    /// The scene folder written.
    pub out: PathBuf,
}

/// Imports the capture at `input` into the new scene folder `out` (see the module docs).
/// `out` must not exist or be empty, or hold an import that did not finish (its run record,
/// marked unfinished before the first file: [`sage_io::run::mark_unfinished`], says so; the
/// rerun replaces it). `on_stage` is told each [`Stage`] as it starts.
///
/// # Errors
///
/// Bad settings, an unreadable, empty or malformed capture, no floor found, a capture too
/// large for a scene, an occupancy map without one free cell (with its likely causes), an
/// output folder that holds anything else, or a write error (after which the files written
/// are removed).
pub fn import(
    input: &Path,
    out: &Path,
    settings: &ImportSettings,
    on_stage: &dyn Fn(Stage),
) -> Result<ImportReport> {
    let capture = settings.capture_settings()?;
    refuse_filled(out)?;
    on_stage(Stage::Reading);
    let meta = std::fs::metadata(input).map_err(|e| Error::io(input, e))?;
    if !meta.is_file() {
        return Err(Error::invalid("the capture must be a 3DGS file, not a folder").in_file(input));
    }
    if meta.len() == 0 {
        return Err(Error::invalid("the capture file is empty").in_file(input));
    }
    let (gaussians, format) = sage_scene::splats::read_gaussians_file(input)?;
    on_stage(Stage::Aligning);
    let aligned = sage_capture::align(&gaussians, &capture).map_err(|e| e.in_file(input))?;
    drop(gaussians);
    let Aligned {
        gaussians: mut scene_gaussians,
        transform,
        floor,
        input: gaussians_in,
        floaters,
        recentred,
        ..
    } = aligned;
    scene_gaussians.sort_morton();
    on_stage(Stage::Mapping);
    let grid_params = settings.grid_params();
    let slab = (grid_params.slab_bottom, grid_params.agent_height);
    let grid = gaussian_grid(
        &scene_gaussians,
        grid_params.cell,
        slab,
        grid_params.margin,
        &SplatGridParams::default(),
    )?;
    let occupancy = grid.to_occupancy(slab)?;
    let (free, occupied, _) = grid.counts();
    let cell_area = grid.cell * grid.cell;
    let scale = capture.scale.factor()?;
    let scale_source = match capture.scale {
        Scale::None => "none",
        Scale::Given { .. } => "given",
        Scale::Points { .. } => "points",
    };
    let warnings = plausibility(&floor, capture.scale, settings.up);
    if free == 0 {
        // A map without one free cell gives no trajectory, episode or start pose: every
        // command after the import would fail on it, far from the cause. Nothing is written.
        return Err(no_free_floor(&floor, capture.scale, settings, &warnings).in_file(input));
    }
    let input_hash =
        sage_io::hash::fnv1a64_hex(&std::fs::read(input).map_err(|e| Error::io(input, e))?);
    let input_name = input
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let rotation = transform.rotation;
    let rotation_wxyz = [rotation.w, rotation.x, rotation.y, rotation.z].map(r6);
    let record = serde_json::json!({
        "frame": "W",
        "note": "p_W = transform.matrix · [p_capture, 1]: scale, then rotation, then translation",
        "source": {
            "file": input_name,
            "format": format.as_str(),
            "fnv1a64": input_hash,
            "gaussians": gaussians_in,
            "sh_degree": scene_gaussians.sh_degree(),
        },
        "transform": {
            "scale": r6(transform.scale),
            "rotation_wxyz": rotation_wxyz,
            "translation": transform.translation.to_array().map(r6),
            "matrix": transform.rows().map(|row| row.map(r6)),
            "recentred": recentred.map(|v| v.map(r6)),
        },
        "scale": {
            "source": scale_source,
            "metres_per_unit": r6(scale),
            "metric": scale_source != "none",
            "given": capture.scale,
        },
        "floor": {
            "up_in_capture": floor.up.to_array().map(r6),
            "up_setting": settings.up.as_str(),
            "height_m": r6(floor.offset),
            "tilt_deg": r6(floor.tilt_deg),
            "area_m2": r6(floor.area),
            "rms_m": r6(floor.rms),
            "gaussians": floor.inliers,
            "lower_share": r6(floor.lower_share),
            "floor_side": floor.side.as_str(),
            "up_doubtful": floor.side_doubtful,
            "ceiling_m": r6(floor.ceiling),
            "top_plane_m": r6(floor.top_plane),
            "top_plane_area_m2": r6(floor.top_plane_area),
            "yaw_deg": r6(floor.yaw.to_degrees()),
            "wall_agreement": r6(floor.wall_agreement),
            "surface_samples": floor.samples,
        },
        "floaters": {
            "removed": floaters,
            "max_opacity": r6(capture.floaters.max_opacity),
            "radius_m": r6(capture.floaters.radius),
            "min_neighbours": capture.floaters.min_neighbours,
        },
        "gaussians": scene_gaussians.len(),
        "occupancy": {
            "source": sage_nav::GridSource::Gaussians.as_str(),
            "cell": r6(grid.cell),
            "agent_height": r6(grid_params.agent_height),
            "slab_bottom": r6(grid_params.slab_bottom),
            "free_m2": r6(free as f32 * cell_area),
            "occupied_m2": r6(occupied as f32 * cell_area),
        },
        "warnings": warnings,
    });
    on_stage(Stage::Writing);
    let splat_file = settings.layout.file();
    let names = [
        splat_file,
        "occupancy.png",
        "occupancy.json",
        CAPTURE_FILE,
        sage_io::RUN_RECORD,
    ];
    let lock = sage_io::run::claim_folder(out, &[IMPORT_COMMAND], &names, false)?;
    // Claimed: no other command writes here now, so emptiness cannot change under us.
    refuse_filled(out)?;
    let written = write_folder(
        out,
        &scene_gaussians,
        settings.layout,
        &occupancy,
        &record,
        settings,
    );
    if let Err(e) = written {
        for name in names {
            let _ = std::fs::remove_file(out.join(name));
        }
        drop(lock);
        return Err(e);
    }
    drop(lock);
    Ok(ImportReport {
        input: input.to_path_buf(),
        format: format.as_str().to_string(),
        gaussians_in,
        floaters,
        gaussians_out: scene_gaussians.len(),
        scale,
        scale_source: scale_source.to_string(),
        up: floor.up.to_array(),
        tilt_deg: floor.tilt_deg,
        floor_area: floor.area,
        floor_rms: floor.rms,
        ceiling: floor.ceiling,
        top_plane: floor.top_plane,
        recentred,
        yaw_deg: floor.yaw.to_degrees(),
        free_m2: free as f32 * cell_area,
        occupied_m2: occupied as f32 * cell_area,
        splat_file: splat_file.to_string(),
        losses: sage_scene::splats::convert::losses(
            sage_scene::splats::Format::Ply(settings.layout.layout()),
            scene_gaussians.sh_degree(),
            scene_gaussians.sh_degree(),
        ),
        warnings,
        out: out.to_path_buf(),
    })
}

/// What to try about the scale, naming the one used.
fn scale_hint(scale: Scale) -> String {
    let used = match scale {
        Scale::None => "none was given, so the capture's units were taken as metres".to_string(),
        Scale::Given { value } => format!("`--scale {value}` was given"),
        Scale::Points { distance, .. } => {
            format!("`--scale-points` {distance} m apart were given")
        }
    };
    format!(
        "the scale is likely wrong ({used}): give `--scale` (metres per capture unit) or two points of the capture with `--scale-points` and their true distance with `--scale-distance`"
    )
}

/// What to try about the up axis given as `up`.
fn up_hint(up: Up) -> String {
    let opposite = match up {
        Up::Auto => None,
        Up::X => Some(Up::NegX),
        Up::NegX => Some(Up::X),
        Up::Y => Some(Up::NegY),
        Up::NegY => Some(Up::Y),
        Up::Z => Some(Up::NegZ),
        Up::NegZ => Some(Up::Z),
    };
    match opposite {
        Some(o) => format!("try `--up={o}` or `--up auto`"),
        None => "name the axis that points up in the capture with `--up` (x, -x, y, -y, z or -z)"
            .to_string(),
    }
}

/// What looks wrong with a capture levelled by `floor`, scaled by `scale`, with `up` given:
/// each entry names what was seen, its likely cause and what to try. Empty when the result is
/// plausible. A capture may have no ceiling: that alone is no warning.
///
/// - A given up axis that the Gaussians contradict ([`FloorFit::side_doubtful`]): upside down.
/// - A ceiling higher than [`MAX_CEILING_M`]: a scale too large.
/// - No ceiling, but a plane facing up that spans at least half the floor's area and stands
///   lower than [`MIN_CEILING_M`] above it: a ceiling scaled too small, or the capture upside
///   down (its floor under a table-high "ceiling"). Furniture tops span far less than half
///   a floor, so they give no warning.
pub fn plausibility(floor: &FloorFit, scale: Scale, up: Up) -> Vec<String> {
    let mut warnings = Vec::new();
    if floor.side_doubtful {
        warnings.push(format!(
            "the capture looks upside down: the Gaussians put the floor at the other end of the up axis given (`--up={up}`): {}",
            up_hint(up)
        ));
    }
    if floor.ceiling > MAX_CEILING_M {
        warnings.push(format!(
            "the ceiling found is {:.2} m above the floor, higher than rooms are ({MAX_CEILING_M} m at most): {}",
            floor.ceiling,
            scale_hint(scale)
        ));
    }
    if floor.ceiling == 0.0
        && floor.top_plane > 0.0
        && floor.top_plane < MIN_CEILING_M
        && floor.top_plane_area >= 0.5 * floor.area
    {
        warnings.push(format!(
            "a plane as large as a ceiling ({:.1} m2 against the floor's {:.1} m2) lies only {:.2} m above the floor, lower than a ceiling ({MIN_CEILING_M} m at least), so no ceiling was recorded: if it is the ceiling, {}; if it is the floor, the capture is upside down: {}",
            floor.top_plane_area,
            floor.area,
            floor.top_plane,
            scale_hint(scale),
            up_hint(up)
        ));
    }
    warnings
}

/// The error of an import whose occupancy map has no free cell, with its likely causes.
fn no_free_floor(
    floor: &FloorFit,
    scale: Scale,
    settings: &ImportSettings,
    warnings: &[String],
) -> Error {
    let mut causes = vec![
        format!(
            "the floor found ({:.1} m2) is not the floor: {}",
            floor.area,
            up_hint(settings.up)
        ),
        scale_hint(scale),
    ];
    if settings.cell > 0.2 {
        causes.push(format!(
            "`--cell {}` is coarser than the gaps between furniture: try the default {} m",
            settings.cell,
            GridParams::default().cell
        ));
    }
    let mut message = format!(
        "the occupancy map derived from the capture has no free cell (no floor seen clear of obstacles from {} to {} m above it), so the scene would have nowhere to place an agent; nothing was written. Likely causes: {}",
        GridParams::default().slab_bottom,
        settings.agent_height,
        causes.join("; or ")
    );
    for w in warnings {
        message.push_str(&format!(". Also: {w}"));
    }
    Error::invalid(message)
}

/// `v` rounded to 6 decimals, so the file reads 0.15 where the f32 holds 0.150000006.
fn r6(v: f32) -> f64 {
    (f64::from(v) * 1e6).round() / 1e6
}

/// Refuses an output folder that holds anything (the import writes a whole new scene) but an
/// import that did not finish, which the rerun replaces.
fn refuse_filled(out: &Path) -> Result<()> {
    if out.exists() && !out.is_dir() {
        return Err(Error::invalid(
            "the output is a file; `sage3d scene import` writes a new scene folder there",
        )
        .in_file(out));
    }
    let unfinished = sage_io::run::unfinished_command(out).as_deref() == Some(IMPORT_COMMAND);
    if out.is_dir() && !unfinished {
        let held = sage_io::run::entries(out)?;
        if let Some(first) = held.first() {
            return Err(Error::invalid(format!(
                "the output folder is not empty (it holds '{first}'); `sage3d scene import` writes a new scene folder: choose a new or empty one"
            ))
            .in_file(out));
        }
    }
    Ok(())
}

/// Writes the scene folder's files and the provenance between the run record marked
/// unfinished and the full one.
fn write_folder(
    out: &Path,
    gaussians: &sage_scene::Gaussians,
    layout: OutputLayout,
    occupancy: &OccupancyMap,
    record: &serde_json::Value,
    settings: &ImportSettings,
) -> Result<()> {
    sage_io::run::mark_unfinished(out, IMPORT_COMMAND, None)?;
    // The folder is empty or an import that did not finish (`refuse_filled`), so a Gaussian
    // file of the other layout is that import's own. Left there, the loader, which reads
    // `3dgs_compressed.ply` before `3dgs.ply`, could take the old Gaussians with the new map.
    let other = match layout {
        OutputLayout::Compressed => OutputLayout::Standard,
        OutputLayout::Standard => OutputLayout::Compressed,
    };
    let stale = out.join(other.file());
    if std::fs::symlink_metadata(&stale).is_ok_and(|m| m.is_file()) {
        std::fs::remove_file(&stale).map_err(|e| Error::io(&stale, e))?;
    }
    sage_scene::ply::write_splats_file(&out.join(layout.file()), gaussians, layout.layout())?;
    occupancy.save(out)?;
    sage_io::files::write_json(&out.join(CAPTURE_FILE), record)?;
    sage_io::run::write_run_record(
        out,
        IMPORT_COMMAND,
        None,
        serde_json::json!({ "config": settings, "inputs": [record["source"].clone()] }),
    )
}
