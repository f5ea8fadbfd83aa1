//! Frame files: a rendered observation as the image files a sample holds (RGB as JPEG or PNG,
//! depth as 16-bit PNG millimetres, semantic and instance ids as 16-bit PNG).

use sage_core::{Error, Result};
use sage_env::Images;
use sage_io::image::{encode_jpeg, encode_png};
use serde::{Deserialize, Serialize};

/// How the RGB frame is stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "codec", rename_all = "snake_case")]
pub enum RgbCodec {
    /// Baseline JPEG, 4:2:0, at this quality (1–100).
    Jpeg {
        /// Quality, 1–100.
        quality: u8,
    },
    /// Lossless 8-bit RGB PNG.
    Png,
}

/// The file type of RGB frames, as the front ends name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum ImageType {
    /// Baseline JPEG (`jpg`, also read as `jpeg`).
    #[default]
    Jpg,
    /// Lossless PNG.
    Png,
}

impl ImageType {
    /// The codec of this type at JPEG quality `jpeg_quality` (PNG has none).
    pub fn codec(self, jpeg_quality: u8) -> RgbCodec {
        match self {
            ImageType::Jpg => RgbCodec::Jpeg {
                quality: jpeg_quality,
            },
            ImageType::Png => RgbCodec::Png,
        }
    }
}

impl std::fmt::Display for ImageType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ImageType::Jpg => "jpg",
            ImageType::Png => "png",
        })
    }
}

impl std::str::FromStr for ImageType {
    type Err = Error;

    /// `jpg` (or `jpeg`) or `png`.
    fn from_str(s: &str) -> Result<ImageType> {
        match s {
            "jpg" | "jpeg" => Ok(ImageType::Jpg),
            "png" => Ok(ImageType::Png),
            other => Err(Error::invalid(format!(
                "unknown image type '{other}' (jpg or png)"
            ))),
        }
    }
}

impl RgbCodec {
    /// The file extension (`jpg` or `png`).
    pub fn extension(self) -> &'static str {
        match self {
            RgbCodec::Jpeg { .. } => "jpg",
            RgbCodec::Png => "png",
        }
    }
}

/// The suffixes of a frame's depth, semantic and instance images.
const IMAGE_SUFFIXES: [&str; 3] = ["depth.png", "semantic.png", "instance.png"];

/// The suffixes (after `NNNN.`) of a frame's files, RGB first, in the order they are written.
pub fn suffixes(images: &Images, codec: RgbCodec) -> Vec<&'static str> {
    let [depth, semantic, instance] = IMAGE_SUFFIXES;
    let mut s = Vec::new();
    if images.rgb.is_some() {
        s.push(codec.extension());
    }
    if images.depth.is_some() {
        s.push(depth);
    }
    if images.semantic.is_some() {
        s.push(semantic);
    }
    if images.instance.is_some() {
        s.push(instance);
    }
    s
}

/// True for the name of a frame's file as a render writes it: the frame's number (four digits
/// or more) and one of the [`suffixes`] any frame may have.
pub fn is_frame_file(name: &str) -> bool {
    name.split_once('.').is_some_and(|(number, suffix)| {
        number.len() >= 4
            && number.bytes().all(|b| b.is_ascii_digit())
            && (IMAGE_SUFFIXES.contains(&suffix)
                || [ImageType::Jpg, ImageType::Png]
                    .iter()
                    .any(|t| t.codec(0).extension() == suffix))
    })
}

/// Encodes every image of `images`: `(suffix, bytes)` in the order of [`suffixes`].
///
/// # Errors
///
/// An instance id above 65 535 (it does not fit the 16-bit PNG), or an encoder error.
pub fn encode(images: &Images, codec: RgbCodec) -> Result<Vec<(&'static str, Vec<u8>)>> {
    let (w, h) = (images.width, images.height);
    let mut out = Vec::with_capacity(4);
    if let Some(rgb) = &images.rgb {
        let bytes = match codec {
            RgbCodec::Jpeg { quality } => encode_jpeg(rgb, w, h, quality)?,
            RgbCodec::Png => encode_png(w, h, png::ColorType::Rgb, png::BitDepth::Eight, rgb)?,
        };
        out.push((codec.extension(), bytes));
    }
    if let Some(depth) = &images.depth {
        let (dw, dh) = images.depth_size;
        let mm: Vec<u16> = depth.iter().map(|&d| depth_mm(d)).collect();
        out.push(("depth.png", png16(dw, dh, &mm)?));
    }
    if let Some(sem) = &images.semantic {
        out.push(("semantic.png", png16(w, h, sem)?));
    }
    if let Some(inst) = &images.instance {
        let ids = inst
            .iter()
            .map(|&i| {
                u16::try_from(i).map_err(|_| {
                    Error::invalid(format!(
                        "instance id {i} does not fit a 16-bit PNG (at most 65535)"
                    ))
                })
            })
            .collect::<Result<Vec<u16>>>()?;
        out.push(("instance.png", png16(w, h, &ids)?));
    }
    Ok(out)
}

/// Depth in whole millimetres, 0 where nothing was hit, saturating at 65.535 m.
pub fn depth_mm(metres: f32) -> u16 {
    if metres.is_finite() && metres > 0.0 {
        (metres * 1000.0).round().min(f32::from(u16::MAX)) as u16
    } else {
        0
    }
}

fn png16(w: usize, h: usize, values: &[u16]) -> Result<Vec<u8>> {
    let be: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
    encode_png(w, h, png::ColorType::Grayscale, png::BitDepth::Sixteen, &be)
}

sage_core::named_by_string!(ImageType);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_is_whole_millimetres_and_zero_for_no_hit() {
        assert_eq!(depth_mm(1.2345), 1235);
        assert_eq!(depth_mm(0.0), 0);
        assert_eq!(depth_mm(f32::INFINITY), 0);
        assert_eq!(depth_mm(f32::NAN), 0);
        assert_eq!(depth_mm(100.0), u16::MAX);
    }

    #[test]
    fn every_requested_image_is_encoded_in_suffix_order() {
        let images = Images {
            width: 4,
            height: 2,
            rgb: Some(vec![200; 24]),
            depth_size: (4, 2),
            depth: Some(vec![1.5; 8]),
            semantic: Some(vec![3; 8]),
            instance: Some(vec![70_000; 8]),
        };
        assert!(encode(&images, RgbCodec::Png).is_err());
        let images = Images {
            instance: Some(vec![7; 8]),
            ..images
        };
        let files = encode(&images, RgbCodec::Jpeg { quality: 90 }).unwrap();
        let names: Vec<&str> = files.iter().map(|f| f.0).collect();
        assert_eq!(names, suffixes(&images, RgbCodec::Jpeg { quality: 90 }));
        assert_eq!(names, ["jpg", "depth.png", "semantic.png", "instance.png"]);
        assert_eq!(&files[0].1[..2], &[0xFF, 0xD8]);
        assert_eq!(&files[1].1[1..4], b"PNG");
    }
}
