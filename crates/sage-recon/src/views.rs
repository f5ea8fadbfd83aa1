//! The rendered views of a plan, on disk: `views/render.json` (the image size and intrinsics,
//! fixed by the first render) and, per kept view `k`, `views/rgb_{k:04}.png` and
//! `views/depth_{k:04}.png` (16-bit, millimetres). A view counts as rendered when both files
//! exist; each is written atomically, so a run cut short resumes with the views it lacks.

use crate::export::ExportView;
use crate::plan::Plan;
use crate::raster::MeshImage;
use sage_core::{Error, Result};
use sage_io::files::{write_json, write_png, write_rgb_png};
use sage_splat::Intrinsics;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The folder of the views inside a reconstruction folder.
pub const VIEWS_DIR: &str = "views";
/// The manifest's name inside [`VIEWS_DIR`].
pub const MANIFEST: &str = "render.json";

/// Why views of a replaced plan are refused, and what to do, the same wherever they are met:
/// `recon render` never deletes images, so removing them is the user's step.
const OTHER_PLAN: &str = "the views were rendered for another plan (its views differ from \
                          plan.json); remove the views folder, then run `sage3d recon render` \
                          again to render this one";

/// What every view of a folder shares.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Horizontal field of view, degrees (the plan's).
    pub hfov_deg: f32,
    /// Focal length x, pixels.
    pub fx: f32,
    /// Focal length y, pixels.
    pub fy: f32,
    /// Principal point x, pixels.
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
    /// Views in the plan.
    pub views: usize,
    /// Unit of the depth PNGs.
    pub depth_unit: String,
    /// FNV-1a hash (hex) of the plan's kept views: images rendered for one plan are never
    /// taken for another's.
    pub plan_views_hash: String,
    /// The folder name of the scene the views were rendered from (absent in folders rendered
    /// before it was recorded, which any scene resumes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<String>,
}

impl Manifest {
    /// The manifest for rendering `plan` at `width × height`.
    pub fn new(plan: &Plan, width: u32, height: u32) -> Result<Manifest> {
        let k = plan.intrinsics(width, height)?;
        Ok(Manifest {
            width,
            height,
            hfov_deg: plan.hfov_deg,
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            views: plan.views.len(),
            depth_unit: "mm".to_string(),
            plan_views_hash: views_hash(plan)?,
            scene: None,
        })
    }

    /// The shared intrinsics.
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics {
            width: self.width,
            height: self.height,
            fx: self.fx,
            fy: self.fy,
            cx: self.cx,
            cy: self.cy,
        }
    }
}

/// FNV-1a (64-bit) of the kept views as JSON, in hex.
fn views_hash(plan: &Plan) -> Result<String> {
    let bytes = serde_json::to_vec(&plan.views)
        .map_err(|e| Error::invalid(format!("plan views do not serialise: {e}")))?;
    Ok(sage_io::hash::fnv1a64_hex(&bytes))
}

/// RGB file of view `k`, relative to the reconstruction folder.
pub fn rgb_name(k: usize) -> String {
    format!("{VIEWS_DIR}/rgb_{k:04}.png")
}

/// Depth file of view `k`, relative to the reconstruction folder.
pub fn depth_name(k: usize) -> String {
    format!("{VIEWS_DIR}/depth_{k:04}.png")
}

/// Reads `views/render.json` of `dir`, if there is one (at most `SAGE3D_MAX_JSON_MB`, refused
/// from its size before it is read).
pub fn read_manifest(dir: &Path) -> Result<Option<Manifest>> {
    let path = dir.join(VIEWS_DIR).join(MANIFEST);
    if !path.is_file() {
        return Ok(None);
    }
    sage_io::files::read_json(&path).map(Some)
}

/// Prepares `dir/views` for `manifest`: writes the manifest, or checks that the one already
/// there matches (views of two sizes, or of two scenes, must not mix in one folder).
pub fn prepare(dir: &Path, manifest: &Manifest) -> Result<()> {
    let views = dir.join(VIEWS_DIR);
    std::fs::create_dir_all(&views).map_err(|e| Error::io(&views, e))?;
    let Some(m) = read_manifest(dir)? else {
        return write_json(&views.join(MANIFEST), manifest);
    };
    let refused = |why: String| Err(Error::invalid(why).in_file(views.join(MANIFEST)));
    let same_size = Manifest {
        scene: m.scene.clone(),
        ..manifest.clone()
    } == m;
    if m.plan_views_hash != manifest.plan_views_hash {
        refused(OTHER_PLAN.to_string())
    } else if !same_size {
        refused(format!(
            "views already rendered at {}x{} (hfov {}°, {} views); render with the same size or remove the views folder",
            m.width, m.height, m.hfov_deg, m.views
        ))
    } else if let Some(old) = m
        .scene
        .as_ref()
        .filter(|old| manifest.scene.as_ref() != Some(*old))
    {
        refused(format!(
            "views already rendered from scene '{old}'; render that scene, or remove the views folder to render another"
        ))
    } else {
        Ok(())
    }
}

/// The kept views of `plan` not yet rendered in `dir`.
pub fn pending(dir: &Path, plan: &Plan) -> Vec<usize> {
    (0..plan.views.len())
        .filter(|&k| !(dir.join(rgb_name(k)).is_file() && dir.join(depth_name(k)).is_file()))
        .collect()
}

/// Writes view `k` (RGB first, then depth: the depth file marks the view complete).
pub fn write_view(dir: &Path, k: usize, image: &MeshImage) -> Result<()> {
    write_rgb_png(
        &dir.join(rgb_name(k)),
        image.width,
        image.height,
        &image.rgb,
    )?;
    let bytes: Vec<u8> = image
        .depth_mm()
        .iter()
        .flat_map(|d| d.to_be_bytes())
        .collect();
    write_png(
        &dir.join(depth_name(k)),
        image.width,
        image.height,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &bytes,
    )
}

/// Reads the RGB of view `k` (`height × width × 3` bytes), checking its size.
pub fn read_rgb(dir: &Path, k: usize, manifest: &Manifest) -> Result<Vec<u8>> {
    let path: PathBuf = dir.join(rgb_name(k));
    let file = std::fs::File::open(&path).map_err(|e| Error::io(&path, e))?;
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder
        .read_info()
        .map_err(|e| Error::format("png", e.to_string()).in_file(&path))?;
    let mut buf = vec![0; reader.output_buffer_size().unwrap_or(0)];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| Error::format("png", e.to_string()).in_file(&path))?;
    if (info.width, info.height) != (manifest.width, manifest.height)
        || info.color_type != png::ColorType::Rgb
    {
        return Err(Error::format(
            "png",
            format!(
                "expected an RGB image of {}x{}, found {:?} {}x{}",
                manifest.width, manifest.height, info.color_type, info.width, info.height
            ),
        )
        .in_file(&path));
    }
    buf.truncate(info.buffer_size());
    Ok(buf)
}

/// The views of `plan` rendered in `dir`, ready for [`crate::export::transforms_for`]; an error
/// when views are missing (naming how many and the first).
pub fn export_views(dir: &Path, plan: &Plan) -> Result<Vec<ExportView>> {
    let manifest = read_manifest(dir)?.ok_or_else(|| {
        Error::invalid("no rendered views (views/render.json); run `sage3d recon render` first")
            .in_file(dir.join(VIEWS_DIR).join(MANIFEST))
    })?;
    if manifest.plan_views_hash != views_hash(plan)? {
        return Err(Error::invalid(OTHER_PLAN).in_file(dir.join(VIEWS_DIR).join(MANIFEST)));
    }
    let missing = pending(dir, plan);
    if let Some(first) = missing.first() {
        return Err(Error::invalid(format!(
            "{} of {} views are not rendered yet (first: view {first}); run `sage3d recon render` to finish them",
            missing.len(),
            plan.views.len()
        ))
        .in_file(dir.join(VIEWS_DIR)));
    }
    let k = manifest.intrinsics();
    Ok(plan
        .views
        .iter()
        .map(|v| ExportView {
            camera: v.camera(k),
            rgb: rgb_name(v.id),
            depth: Some(depth_name(v.id)),
        })
        .collect())
}
