//! Our episode file: one JSON episode per line, W frame (Z up, metres, headings in radians).

use crate::episode::{Episode, check_unique_ids};
use sage_core::{Error, Result, ResultExt};
use std::io::Write;
use std::path::Path;

/// Writes `episodes`, one per line (atomically), every negative zero written as `0.0`
/// ([`Episode::without_negative_zeros`]).
pub fn write(path: &Path, episodes: &[Episode]) -> Result<()> {
    sage_io::files::write_atomic(path, |w| {
        for e in episodes {
            serde_json::to_writer(&mut *w, &e.without_negative_zeros())
                .map_err(std::io::Error::other)?;
            w.write_all(b"\n")?;
        }
        Ok(())
    })
}

/// Reads episodes (at most [`JSON_MB`](sage_io::limits::JSON_MB); a leading byte-order mark is
/// accepted), each checked ([`Episode::check`]) and no id given twice; an error names the file
/// and line.
pub fn read(path: &Path) -> Result<Vec<Episode>> {
    let text = sage_io::files::read_text(path, &sage_io::limits::JSON_MB)?;
    let mut lines = Vec::new();
    let mut episodes = Vec::new();
    for (i, l) in text.lines().enumerate() {
        if l.trim().is_empty() {
            continue;
        }
        let at = format!("line {}", i + 1);
        let episode: Episode = serde_json::from_str(l)
            .map_err(|e| Error::format(&at, format!("not an episode: {e}")))
            .in_file(path)?;
        episode.check().within(at).in_file(path)?;
        lines.push(i + 1);
        episodes.push(episode);
    }
    check_unique_ids(&episodes, |k| format!("line {}", lines[k])).in_file(path)?;
    Ok(episodes)
}
