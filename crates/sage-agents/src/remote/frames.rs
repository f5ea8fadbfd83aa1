//! The episode's recent RGB frames as base64 JPEGs, the image format every SAGE-3D model
//! server reads. Each frame is encoded once, when observed; a request sends the last
//! `history` of them in order, the current frame last.

use base64::Engine;
use base64::engine::general_purpose::STANDARD;
use sage_core::{Error, Result};
use sage_env::Observation;
use std::collections::VecDeque;

pub use sage_io::image::encode_jpeg;

/// The last frames of an episode, base64 JPEG, oldest first.
#[derive(Debug, Clone)]
pub struct FrameHistory {
    cap: usize,
    quality: u8,
    frames: VecDeque<String>,
}

impl FrameHistory {
    /// Keeps the last `cap` (≥ 1) frames, encoded at `quality`.
    pub fn new(cap: usize, quality: u8) -> FrameHistory {
        FrameHistory {
            cap: cap.max(1),
            quality,
            frames: VecDeque::new(),
        }
    }

    /// Forgets every frame (a new episode).
    pub fn clear(&mut self) {
        self.frames.clear();
    }

    /// Adds the RGB image of `obs`, dropping the oldest frame beyond the cap.
    ///
    /// # Errors
    ///
    /// The observation has no RGB image.
    pub fn push(&mut self, obs: &Observation) -> Result<()> {
        let images = obs.images.as_ref();
        let Some((rgb, w, h)) = images.and_then(|i| Some((i.rgb.as_ref()?, i.width, i.height)))
        else {
            return Err(Error::invalid(
                "remote agents need RGB images (the observation has none)",
            ));
        };
        let jpeg = encode_jpeg(rgb, w, h, self.quality)?;
        if self.frames.len() == self.cap {
            self.frames.pop_front();
        }
        self.frames.push_back(STANDARD.encode(jpeg));
        Ok(())
    }

    /// The kept frames, oldest first (the current frame last).
    pub fn frames(&self) -> Vec<String> {
        self.frames.iter().cloned().collect()
    }
}
