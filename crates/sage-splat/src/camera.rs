//! Pinhole cameras in the world frame W with OpenCV axes (x right, y down, z forward), SPEC §3.

use glam::{Mat3, Mat4, Vec3};
use sage_core::{Error, Result};
use serde::{Deserialize, Serialize};

/// Near plane used when none is given (metres): Gaussians whose centre is nearer are culled.
pub const DEFAULT_NEAR: f32 = 0.1;
/// Far plane used when none is given (metres).
pub const DEFAULT_FAR: f32 = 100.0;

/// Image size and pinhole intrinsics (pixel i covers [i, i+1)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x.
    pub fx: f32,
    /// Focal length along y.
    pub fy: f32,
    /// Principal point x.
    pub cx: f32,
    /// Principal point y.
    pub cy: f32,
}

/// A pinhole camera: image size and intrinsics, pose, clip range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Image size, focal lengths and principal point.
    pub intrinsics: Intrinsics,
    /// Camera-to-world rotation: columns are the camera's right, down and forward axes in W.
    pub rotation: Mat3,
    /// Camera centre in W.
    pub position: Vec3,
    /// Near clip distance (along the optical axis).
    pub near: f32,
    /// Far clip distance.
    pub far: f32,
}

/// The largest image side, in pixels, a camera may have.
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// Bits of a depth-sort key ([`Camera::depth_key`]); the GPU renderer puts a batch's camera in
/// the byte above.
pub const DEPTH_KEY_BITS: u32 = 24;

impl Intrinsics {
    /// Square pixels from a horizontal field of view: fx = fy = (width/2)/tan(hfov/2), centred.
    pub fn from_hfov(width: u32, height: u32, hfov_deg: f32) -> Result<Intrinsics> {
        if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
            return Err(Error::invalid(format!(
                "image size must be 1-{MAX_IMAGE_SIDE} pixels, got {width}x{height}"
            )));
        }
        if !(hfov_deg > 0.0 && hfov_deg < 180.0) {
            return Err(Error::invalid(format!(
                "hfov_deg must be in (0, 180), got {hfov_deg}"
            )));
        }
        let f = (width as f32 * 0.5) / (hfov_deg.to_radians() * 0.5).tan();
        Ok(Intrinsics {
            width,
            height,
            fx: f,
            fy: f,
            cx: width as f32 * 0.5,
            cy: height as f32 * 0.5,
        })
    }
}

/// Checks a pitch in degrees, named `pitch`: from straight down to straight up (past ±90° the
/// camera would face backwards, upside down: a heading in disguise).
///
/// # Errors
///
/// Outside -90–90 degrees, NaN included.
pub fn check_pitch_deg(pitch_deg: f32) -> Result<()> {
    if (-90.0..=90.0).contains(&pitch_deg) {
        Ok(())
    } else {
        Err(Error::invalid(format!(
            "`pitch` must be -90 to 90 degrees, got {pitch_deg}"
        )))
    }
}

/// The camera rotation (columns right, down, forward) for heading ψ and pitch φ (up positive).
pub fn rotation_from_yaw_pitch(yaw: f32, pitch: f32) -> Mat3 {
    let forward = Vec3::new(
        yaw.cos() * pitch.cos(),
        yaw.sin() * pitch.cos(),
        pitch.sin(),
    );
    let right = Vec3::new(yaw.sin(), -yaw.cos(), 0.0);
    let down = forward.cross(right);
    Mat3::from_cols(right, down, forward)
}

impl Camera {
    /// A camera from intrinsics and a camera-to-world rotation and position.
    pub fn new(intrinsics: Intrinsics, rotation: Mat3, position: Vec3) -> Camera {
        Camera {
            intrinsics,
            rotation,
            position,
            near: DEFAULT_NEAR,
            far: DEFAULT_FAR,
        }
    }

    /// A camera at `position` looking along heading `yaw` and `pitch` (radians).
    pub fn from_yaw_pitch(intrinsics: Intrinsics, position: Vec3, yaw: f32, pitch: f32) -> Camera {
        Camera::new(intrinsics, rotation_from_yaw_pitch(yaw, pitch), position)
    }

    /// A camera from a 4×4 camera-to-world matrix in OpenCV axes (its rotation part is
    /// re-orthonormalised; scale or shear is an error).
    pub fn from_c2w(intrinsics: Intrinsics, c2w: Mat4) -> Result<Camera> {
        let m = Mat3::from_mat4(c2w);
        if !c2w.is_finite()
            || (m.transpose() * m - Mat3::IDENTITY)
                .to_cols_array()
                .iter()
                .any(|v| v.abs() > 1e-3)
        {
            return Err(Error::invalid(
                "the camera-to-world matrix's 3x3 part must be a rotation (orthonormal, no scale)",
            ));
        }
        if (m.determinant() - 1.0).abs() > 1e-3 {
            return Err(Error::invalid(
                "the camera-to-world matrix's 3x3 part must be a proper rotation (determinant +1)",
            ));
        }
        let forward = m.z_axis.normalize();
        let right = (m.x_axis - forward * m.x_axis.dot(forward)).normalize();
        let rotation = Mat3::from_cols(right, forward.cross(right), forward);
        Ok(Camera::new(intrinsics, rotation, c2w.w_axis.truncate()))
    }

    /// The camera-to-world matrix (OpenCV axes).
    pub fn c2w(&self) -> Mat4 {
        Mat4::from_cols(
            self.rotation.x_axis.extend(0.0),
            self.rotation.y_axis.extend(0.0),
            self.rotation.z_axis.extend(0.0),
            self.position.extend(1.0),
        )
    }

    /// A world point in camera coordinates.
    pub fn world_to_camera(&self, p: Vec3) -> Vec3 {
        self.rotation.transpose() * (p - self.position)
    }

    /// The pixel coordinates (continuous, pixel centres at +0.5) of a camera-space point.
    pub fn project(&self, c: Vec3) -> (f32, f32) {
        (
            self.intrinsics.fx * c.x / c.z + self.intrinsics.cx,
            self.intrinsics.fy * c.y / c.z + self.intrinsics.cy,
        )
    }

    /// Checks sizes, focal lengths and clip range.
    pub fn validate(&self) -> Result<()> {
        if self.intrinsics.width == 0
            || self.intrinsics.height == 0
            || self.intrinsics.width > MAX_IMAGE_SIDE
            || self.intrinsics.height > MAX_IMAGE_SIDE
        {
            return Err(Error::invalid(format!(
                "image size must be 1-{MAX_IMAGE_SIDE} pixels, got {}x{}",
                self.intrinsics.width, self.intrinsics.height
            )));
        }
        if !(self.intrinsics.fx > 0.0
            && self.intrinsics.fy > 0.0
            && self.intrinsics.fx.is_finite()
            && self.intrinsics.fy.is_finite())
        {
            return Err(Error::invalid("focal lengths must be positive and finite"));
        }
        if !(self.intrinsics.cx.is_finite() && self.intrinsics.cy.is_finite()) {
            return Err(Error::invalid(
                "the principal point (cx, cy) must be finite",
            ));
        }
        if !(self.near > 0.0 && self.far > self.near && self.far.is_finite()) {
            return Err(Error::invalid(format!(
                "need 0 < near < far, both finite, got near {} far {}",
                self.near, self.far
            )));
        }
        if !self.position.is_finite() || !self.rotation.is_finite() {
            return Err(Error::invalid("camera pose is not finite"));
        }
        Ok(())
    }

    /// The depth-sort key of a splat at depth `z` (between the near and far planes): `z`'s
    /// place between them in [`DEPTH_KEY_BITS`] bits. Both renderers blend a tile's splats in
    /// the order of this key, ties in the order of their Gaussians, so splats within a key of
    /// each other (a flat wall seen square on holds many) blend in the same order on either.
    /// Positive floats order as their bits, so the key is `z`'s bits less the near plane's,
    /// shifted right just enough to fit: every float apart while the far plane is under four
    /// times the near, and each doubling beyond costs a bit (depths 2⁻²⁰ apart still ordered
    /// over 16 octaves, e.g. 0.1 to 100 m: a micrometre at a metre). A depth nearer than the
    /// near plane keys as the near plane.
    pub fn depth_key(&self, z: f32) -> u32 {
        let near = self.near.to_bits();
        let span = self.far.to_bits().saturating_sub(near);
        let shift = (u32::BITS - span.leading_zeros()).max(DEPTH_KEY_BITS) - DEPTH_KEY_BITS;
        z.to_bits().saturating_sub(near) >> shift
    }
}

/// A camera as written in a JSON file (`sage3d render --camera`): a pose by `position` +
/// `yaw_deg` + `pitch_deg`, or by a 4×4 `c2w` (row-major, OpenCV axes); intrinsics by
/// `hfov_deg` or `fx, fy, cx, cy`; optional `near`, `far`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Horizontal field of view, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hfov_deg: Option<f32>,
    /// Focal length x.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fx: Option<f32>,
    /// Focal length y.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fy: Option<f32>,
    /// Principal point x.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cx: Option<f32>,
    /// Principal point y.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cy: Option<f32>,
    /// Camera centre, metres (W).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<[f32; 3]>,
    /// Heading, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yaw_deg: Option<f32>,
    /// Pitch, degrees, up positive.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pitch_deg: Option<f32>,
    /// Camera-to-world, row-major 4×4.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub c2w: Option<[[f32; 4]; 4]>,
    /// Near clip, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub near: Option<f32>,
    /// Far clip, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub far: Option<f32>,
}

impl CameraSpec {
    /// Parses a camera JSON text (errors name the field or line).
    pub fn parse(text: &str) -> Result<CameraSpec> {
        serde_json::from_str(text).map_err(|e| sage_io::files::json_error(&e))
    }

    /// The camera this spec describes.
    pub fn camera(&self) -> Result<Camera> {
        let intrinsics = match (self.hfov_deg, self.fx, self.fy) {
            (Some(h), None, None) => Intrinsics::from_hfov(self.width, self.height, h)?,
            (None, Some(fx), fy) => Intrinsics {
                width: self.width,
                height: self.height,
                fx,
                fy: fy.unwrap_or(fx),
                cx: self.cx.unwrap_or(self.width as f32 * 0.5),
                cy: self.cy.unwrap_or(self.height as f32 * 0.5),
            },
            _ => {
                return Err(Error::format(
                    "hfov_deg/fx",
                    "give either hfov_deg or fx (and optionally fy, cx, cy)",
                ));
            }
        };
        let mut camera = match (self.c2w, self.position) {
            (Some(m), None) => {
                Camera::from_c2w(intrinsics, Mat4::from_cols_array_2d(&m).transpose())
                    .map_err(|e| Error::format("c2w", e.message()))?
            }
            (None, Some(p)) => Camera::from_yaw_pitch(
                intrinsics,
                Vec3::from_array(p),
                self.yaw_deg.unwrap_or(0.0).to_radians(),
                self.pitch_deg.unwrap_or(0.0).to_radians(),
            ),
            _ => {
                return Err(Error::format(
                    "position/c2w",
                    "give either position (with yaw_deg, pitch_deg) or c2w",
                ));
            }
        };
        if !sage_core::within_bounds(camera.position) {
            let p = camera.position;
            return Err(Error::format(
                if self.c2w.is_some() {
                    "c2w"
                } else {
                    "position"
                },
                format!(
                    "the camera centre must be finite and within ±{} m, as a `sage3d render \
                     --position` is, got {}, {}, {}",
                    sage_core::MAX_COORDINATE,
                    p.x,
                    p.y,
                    p.z
                ),
            ));
        }
        camera.near = self.near.unwrap_or(DEFAULT_NEAR);
        camera.far = self.far.unwrap_or(DEFAULT_FAR);
        camera.validate()?;
        Ok(camera)
    }
}

/// The eye of `sage3d bench render` (kept as it is, so that its figures compare across
/// history): the middle of the largest room at 1.2 m, else the middle of the Gaussians. That
/// point may be inside furniture or outside the free space, so `sage3d render` given no camera
/// position stands instead over the free cell of the scene's navigation grid nearest to it
/// (`sage_pipeline::render::free_default_eye`; this crate sits below the navigation layer).
pub fn default_eye(scene: &sage_scene::Scene) -> Vec3 {
    let room = scene
        .floorplan
        .rooms
        .iter()
        .max_by(|a, b| a.profile.area().total_cmp(&b.profile.area()));
    match room {
        Some(r) => r.profile.centroid().extend(1.2),
        None => {
            let b = scene.gaussians.bounds();
            if b.is_empty() {
                Vec3::new(0.0, 0.0, 1.2)
            } else {
                (b.min + b.max) * 0.5
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn depth_keys_keep_the_order_of_depths_and_fit_their_bits() {
        let cam = |near: f32, far: f32| Camera {
            near,
            far,
            ..Camera::from_yaw_pitch(
                Intrinsics::from_hfov(8, 8, 90.0).unwrap(),
                Vec3::ZERO,
                0.0,
                0.0,
            )
        };
        for (near, far) in [(0.1, 100.0), (0.5, 1.0), (1e-3, 1e6), (2.0, 2.5)] {
            let c = cam(near, far);
            assert_eq!(c.depth_key(near), 0);
            assert!(c.depth_key(far) < 1 << DEPTH_KEY_BITS, "{near}..{far}");
            assert_eq!(c.depth_key(near * 0.5), 0, "nearer than the near plane");
            let mut z = near;
            let mut last = 0;
            while z < far {
                let k = c.depth_key(z);
                assert!(k >= last, "{near}..{far}: key of {z} below the one before");
                last = k;
                z = z * 1.001 + 1e-6;
            }
        }
        // Every float apart while the far plane is under four times the near.
        let c = cam(0.5, 1.0);
        let z = 0.75f32;
        assert_eq!(
            c.depth_key(f32::from_bits(z.to_bits() + 1)),
            c.depth_key(z) + 1
        );
        // 0.1 to 100 m: a micrometre apart at a metre is apart.
        let c = cam(0.1, 100.0);
        assert!(c.depth_key(1.000_001) > c.depth_key(1.0));
    }

    #[test]
    fn spec_axes_for_yaw_zero() {
        let r = rotation_from_yaw_pitch(0.0, 0.0);
        assert!(
            (r.x_axis - Vec3::new(0.0, -1.0, 0.0)).length() < 1e-6,
            "right"
        );
        assert!(
            (r.y_axis - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6,
            "down"
        );
        assert!((r.z_axis - Vec3::X).length() < 1e-6, "forward");
    }

    #[test]
    fn hfov_gives_spec_focal() {
        let k = Intrinsics::from_hfov(224, 224, 90.0).unwrap();
        assert!((k.fx - 112.0).abs() < 1e-3 && k.cx == 112.0);
    }

    proptest! {
        #[test]
        fn rotation_is_proper_and_c2w_round_trips(yaw in -3.1f32..3.1, pitch in -1.5f32..1.5, x in -5.0f32..5.0) {
            let k = Intrinsics::from_hfov(64, 48, 90.0).unwrap();
            let cam = Camera::from_yaw_pitch(k, Vec3::new(x, 1.0, 1.2), yaw, pitch);
            prop_assert!((cam.rotation.determinant() - 1.0).abs() < 1e-5);
            let back = Camera::from_c2w(k, cam.c2w()).unwrap();
            prop_assert!((back.rotation.to_cols_array().iter().zip(cam.rotation.to_cols_array()).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max)) < 1e-5);
            // A point straight ahead projects to the principal point.
            let ahead = cam.position + cam.rotation.z_axis * 3.0;
            let (u, v) = cam.project(cam.world_to_camera(ahead));
            prop_assert!((u - 32.0).abs() < 1e-3 && (v - 24.0).abs() < 1e-3);
            // Up in the world is up (negative v) in the image when pitch is moderate.
            let above = ahead + Vec3::Z * 0.1;
            let (_, v2) = cam.project(cam.world_to_camera(above));
            prop_assert!(pitch.abs() > 1.4 || v2 < v);
        }
    }

    #[test]
    fn spec_errors_name_fields() {
        let e = CameraSpec::parse(r#"{"width":64,"height":48,"position":[0,0,1]}"#)
            .unwrap()
            .camera()
            .unwrap_err();
        assert!(e.to_string().contains("hfov_deg/fx"), "{e}");
        let e = CameraSpec::parse(r#"{"width":64,"height":48,"hfov_deg":90,"c2w":[[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}"#).unwrap().camera().unwrap_err();
        assert!(e.to_string().starts_with("c2w:"), "{e}");
        let far = r#"{"width":64,"height":48,"hfov_deg":90,"position":[0,20000,1]}"#;
        let e = CameraSpec::parse(far).unwrap().camera().unwrap_err();
        assert!(
            e.to_string().starts_with("position:") && e.to_string().contains("20000"),
            "{e}"
        );
        let far = r#"{"width":64,"height":48,"hfov_deg":90,"c2w":[[1,0,0,-1e5],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}"#;
        let e = CameraSpec::parse(far).unwrap().camera().unwrap_err();
        assert!(e.to_string().starts_with("c2w:"), "{e}");
        let near = r#"{"width":64,"height":48,"hfov_deg":90,"position":[-9999,0,1]}"#;
        assert!(CameraSpec::parse(near).unwrap().camera().is_ok());
        let e = CameraSpec::parse(r#"{"width":64,"height":48,"hfov":90}"#).unwrap_err();
        assert!(e.to_string().contains("unknown field `hfov`"), "{e}");
    }
}
