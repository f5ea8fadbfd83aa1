//! The preview GIF of a small render: one GIF frame per step of the episodes shown, the RGB
//! frame on the left, a map and text beside and below it, the same bytes whichever format is
//! written (the WebDataset render removes the frames the preview was made from).

mod common;

use sage_traindata::preview::{END_DELAY, MAX_WIDTH, PREVIEW_FILE, STEP_DELAY};
use sage_traindata::sample::EpisodeSample;
use sage_traindata::{Layout, Settings};
use std::path::{Path, PathBuf};

/// A 3-room home and its dataset, every episode in `train`: (dir, scenes, dataset).
fn data() -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, dataset) = common::home_dataset(dir.path(), 3);
    (dir, scenes, dataset)
}

/// A decoded GIF frame.
struct GifFrame {
    width: u16,
    height: u16,
    /// Hundredths of a second.
    delay: u16,
    rgba: Vec<u8>,
}

/// The logical screen's size of a GIF and every frame.
fn decode(path: &Path) -> ((u16, u16), Vec<GifFrame>) {
    let mut opts = gif::DecodeOptions::new();
    opts.set_color_output(gif::ColorOutput::RGBA);
    let mut dec = opts
        .read_info(std::io::BufReader::new(std::fs::File::open(path).unwrap()))
        .unwrap();
    let screen = (dec.width(), dec.height());
    let mut frames = Vec::new();
    while let Some(f) = dec.read_next_frame().unwrap() {
        frames.push(GifFrame {
            width: f.width,
            height: f.height,
            delay: f.delay,
            rgba: f.buffer.to_vec(),
        });
    }
    (screen, frames)
}

#[test]
fn the_preview_shows_every_step_of_the_first_episodes_with_their_frames() {
    let (_dir, scenes, dataset) = data();
    let settings = Settings {
        width: 64,
        height: 48,
        format: Layout::Frames,
        keep_failed: true,
        limit: Some(6),
        preview: 2,
        ..Settings::new(&dataset, &scenes).unwrap()
    };
    let out = tempfile::tempdir().unwrap();
    let m = sage_traindata::render(&settings, out.path(), false, &|_| {}).unwrap();
    assert!(m.counts.kept >= 2, "{:?}", m.counts);
    let text = std::fs::read_to_string(out.path().join("episodes.jsonl")).unwrap();
    let shown: Vec<EpisodeSample> = text
        .lines()
        .take(2)
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let steps: usize = shown.iter().map(|e| e.steps.len()).sum();

    let (screen, frames) = decode(&out.path().join(PREVIEW_FILE));
    assert_eq!(frames.len(), steps);
    let (w, h) = (usize::from(screen.0), usize::from(screen.1));
    // The 48-pixel frames are scaled 5 times (240 pixels) with a map beside them and text
    // below.
    assert!((5 * 64 + 120..=MAX_WIDTH).contains(&w), "{w}");
    assert!(h > 5 * 48 + 40, "{h}");
    let mut k = 0;
    for e in &shown {
        for j in 0..e.steps.len() {
            let GifFrame {
                width,
                height,
                delay,
                rgba,
            } = &frames[k];
            assert_eq!((usize::from(*width), usize::from(*height)), (w, h));
            let last = j + 1 == e.steps.len();
            assert_eq!(*delay, if last { END_DELAY } else { STEP_DELAY });
            let first = &rgba[..4];
            assert!(
                rgba.chunks_exact(4).any(|p| p != first),
                "frame {k} is uniform"
            );
            // The left panel is the step's RGB frame, each pixel a 5×5 block from (8, 8).
            let bytes = std::fs::read(out.path().join("images").join(&e.files[j][0])).unwrap();
            let mut dec = zune_jpeg::JpegDecoder::new(bytes.as_slice());
            let jpeg = dec.decode().unwrap();
            let mut diff = 0u64;
            for y in 0..48 {
                for x in 0..64 {
                    let g = ((8 + 5 * y + 2) * w + 8 + 5 * x + 2) * 4;
                    let s = (y * 64 + x) * 3;
                    for c in 0..3 {
                        diff += u64::from(rgba[g + c].abs_diff(jpeg[s + c]));
                    }
                }
            }
            let mean = diff as f64 / (64.0 * 48.0 * 3.0);
            assert!(mean < 12.0, "frame {k}: mean difference {mean}");
            k += 1;
        }
    }

    // The WebDataset render makes the same preview before it removes the frames.
    let web = tempfile::tempdir().unwrap();
    let s = Settings {
        format: Layout::Webdataset,
        ..settings
    };
    sage_traindata::render(&s, web.path(), false, &|_| {}).unwrap();
    assert!(!web.path().join("images").exists());
    assert_eq!(
        std::fs::read(web.path().join(PREVIEW_FILE)).unwrap(),
        std::fs::read(out.path().join(PREVIEW_FILE)).unwrap()
    );
}
