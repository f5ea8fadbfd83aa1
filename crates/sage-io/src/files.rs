//! Files that are never half-written: atomic writes of any file, JSON, PNG and NumPy `.npy`,
//! and the readers that name the file, line and column of a parse error, refuse a file over its
//! [`Limit`] before reading it, and accept a leading byte-order mark.

use crate::limits::{JSON_MB, Limit};
use sage_core::{Error, Result, ResultExt};
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};

/// What sets a temporary file's name apart: `.{name}.tmp-{process}-{count}`.
const TEMP_MARK: &str = ".tmp-";

/// A temporary sibling of `path`, unique to this process and this call, so that threads (and
/// processes) writing the same file at once never share one ([`is_temporary`] recognises it).
fn temp_path(path: &Path) -> PathBuf {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let k = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    path.with_file_name(format!(".{name}{TEMP_MARK}{}-{k}", std::process::id()))
}

/// Whether the file name `name` is that of a temporary file of [`write_atomic`]
/// (`.{name}.tmp-{process}-{count}`): one that a write interrupted by a crash or a signal
/// leaves behind, and that nothing reads.
pub fn is_temporary(name: &str) -> bool {
    temporary_parts(name).is_some()
}

/// The name of the file a temporary file `name` of [`write_atomic`] was to become, and the id
/// of the process that wrote it; `None` for any other name.
pub(crate) fn temporary_parts(name: &str) -> Option<(&str, &str)> {
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    let (base, tag) = name.strip_prefix('.')?.rsplit_once(TEMP_MARK)?;
    let (process, count) = tag.split_once('-')?;
    (!base.is_empty() && digits(process) && digits(count)).then_some((base, process))
}

/// Writes `path` through `body` into a temporary sibling, then renames it into place.
/// On failure the temporary file is removed and `path` is left as it was.
pub fn write_atomic(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    let tmp = temp_path(path);
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = BufWriter::with_capacity(1 << 20, file);
        body(&mut w)?;
        w.flush()?;
        w.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

/// Writes a value as pretty JSON (atomically).
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    write_atomic(path, |w| {
        serde_json::to_writer_pretty(&mut *w, value).map_err(std::io::Error::other)?;
        w.write_all(b"\n")
    })
}

/// The UTF-8 byte-order mark, which some (mostly Windows) editors put at the start
/// of a file. It means nothing in UTF-8, and JSON parsers reject it.
const BOM: char = '\u{feff}';

/// `text` without a leading byte-order mark.
pub fn strip_bom(text: &str) -> &str {
    text.strip_prefix(BOM).unwrap_or(text)
}

/// Reads the UTF-8 text file `path`, refusing one over `limit` bytes before reading it; a leading
/// byte-order mark is dropped.
pub fn read_text(path: &Path, limit: &Limit) -> Result<String> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let size = file.metadata().map_err(|e| Error::io(path, e))?.len();
    limit.check(size, "file size").in_file(path)?;
    read_text_from(file, path, limit)
}

/// Reads UTF-8 text from `reader` (a decompressor, a file that may still grow), stopping with an
/// error past `limit` bytes; `path` names the source in errors. A leading byte-order mark is
/// dropped.
pub fn read_text_from(reader: impl Read, path: &Path, limit: &Limit) -> Result<String> {
    let max = limit.get()?;
    let mut bytes = Vec::new();
    reader
        .take(max.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > max {
        let found = format!("more than {}", limit.amount(max));
        return Err(limit.exceeded("text size", &found, max).in_file(path));
    }
    if bytes.starts_with(&[0xff, 0xfe]) || bytes.starts_with(&[0xfe, 0xff]) {
        return Err(Error::format(
            "encoding",
            "the file is UTF-16 (it begins with a UTF-16 byte-order mark); save it as UTF-8",
        )
        .in_file(path));
    }
    let mut text = String::from_utf8(bytes).map_err(|e| {
        Error::format(
            "encoding",
            format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
        .in_file(path)
    })?;
    if text.starts_with(BOM) {
        text.drain(..BOM.len_utf8());
    }
    Ok(text)
}

/// Reads a JSON file into `T` (at most [`JSON_MB`]; a leading byte-order mark is accepted); a
/// parse error names the file, line and column.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text = read_text(path, &JSON_MB)?;
    parse_json(&text, path)
}

/// Parses the JSON `text` of file `path` into `T` (a leading byte-order mark is accepted); an
/// error names the file, line and column.
pub fn parse_json<T: serde::de::DeserializeOwned>(text: &str, path: &Path) -> Result<T> {
    serde_json::from_str(strip_bom(text)).map_err(|e| json_error(&e).in_file(path))
}

/// A JSON parse error located at its line and column, said once (serde_json's own text ends
/// with the place again).
pub fn json_error(e: &serde_json::Error) -> Error {
    Error::format(
        format!("line {} column {}", e.line(), e.column()),
        json_message(e),
    )
}

/// serde_json's message without the place it appends (` at line L column C`): for text whose
/// lines and columns mean nothing to its reader, such as JSON made from keyword arguments.
pub fn json_message(e: &serde_json::Error) -> String {
    let text = e.to_string();
    text.strip_suffix(&format!(" at line {} column {}", e.line(), e.column()))
        .unwrap_or(&text)
        .to_string()
}

/// Writes an 8- or 16-bit PNG (atomically). `data` holds the rows top to bottom, samples
/// big-endian for 16 bits, as the PNG format stores them.
pub fn write_png(
    path: &Path,
    width: usize,
    height: usize,
    color: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
) -> Result<()> {
    write_atomic(path, |w| {
        let mut enc = png::Encoder::new(w, width as u32, height as u32);
        enc.set_color(color);
        enc.set_depth(depth);
        let mut writer = enc.write_header().map_err(std::io::Error::other)?;
        writer
            .write_image_data(data)
            .map_err(std::io::Error::other)?;
        writer.finish().map_err(std::io::Error::other)
    })
}

/// Writes an 8-bit RGB image (`height × width × 3` bytes, rows top to bottom) as PNG.
pub fn write_rgb_png(path: &Path, width: usize, height: usize, rgb: &[u8]) -> Result<()> {
    write_png(
        path,
        width,
        height,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        rgb,
    )
}

/// Writes a little-endian float32 array in NumPy's `.npy` format (version 1.0), atomically.
pub fn write_npy_f32(path: &Path, shape: &[usize], data: &[f32]) -> Result<()> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape_text = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape_text}, }}");
    // Magic (6) + version (2) + length (2) + header + newline, padded to a multiple of 64.
    let pad = 64 - (10 + header.len() + 1) % 64;
    header.push_str(&" ".repeat(pad % 64));
    header.push('\n');
    write_atomic(path, |w| {
        w.write_all(b"\x93NUMPY\x01\x00")?;
        w.write_all(&(header.len() as u16).to_le_bytes())?;
        w.write_all(header.as_bytes())?;
        for v in data {
            w.write_all(&v.to_le_bytes())?;
        }
        Ok(())
    })
}

/// Every file under `root` (recursively) with its bytes, keyed by its path relative to `root`:
/// what "the same seed gives the same bytes" is checked against.
pub fn read_tree(root: &Path) -> Result<std::collections::BTreeMap<String, Vec<u8>>> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).map_err(|e| Error::io(&dir, e))? {
            let path = entry.map_err(|e| Error::io(&dir, e))?.path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let key = path
                    .strip_prefix(root)
                    .unwrap_or(&path)
                    .display()
                    .to_string();
                let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
                out.insert(key, bytes);
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_leading_byte_order_mark_is_accepted() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bom.json");
        std::fs::write(&path, b"\xef\xbb\xbf{\"a\": [1, 2]}\n").unwrap();
        let v: serde_json::Value = read_json(&path).unwrap();
        assert_eq!(v, serde_json::json!({"a": [1, 2]}));
        let v: serde_json::Value = parse_json("\u{feff}[3]", &path).unwrap();
        assert_eq!(v, serde_json::json!([3]));
        assert_eq!(read_text(&path, &JSON_MB).unwrap(), "{\"a\": [1, 2]}\n");
    }

    #[test]
    fn utf16_and_invalid_utf8_say_what_is_wrong() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("wide.json");
        std::fs::write(&path, b"\xff\xfe{\0}\0").unwrap();
        let e = read_json::<serde_json::Value>(&path).unwrap_err();
        assert!(
            e.to_string().contains("encoding: the file is UTF-16"),
            "{e}"
        );
        std::fs::write(&path, b"{\"a\": \"\xc3\"}").unwrap();
        let e = read_json::<serde_json::Value>(&path).unwrap_err();
        assert!(
            e.to_string()
                .ends_with("encoding: not UTF-8 text (invalid byte at offset 7)")
        );
    }

    #[test]
    fn a_file_over_its_limit_is_refused_before_it_is_read() {
        let limit = Limit {
            variable: "SAGE3D_MAX_TEST_FILES_MB",
            default: 1,
            unit: "MB",
            scale: 1 << 20,
            what: "a test file",
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.json");
        std::fs::write(&path, vec![b' '; (1 << 20) + 1]).unwrap();
        let e = read_text(&path, &limit).unwrap_err();
        assert_eq!(e.file(), Some(path.as_path()));
        assert_eq!(
            e.to_string(),
            format!(
                "{}: file size: 1.1 MB, over the limit of 1 MB on a test file; set the \
                 environment variable SAGE3D_MAX_TEST_FILES_MB to raise it",
                path.display()
            )
        );
        // A stream (a decompressor) is cut off just past the limit, whatever its length.
        let e = read_text_from(std::io::repeat(b' '), &path, &limit).unwrap_err();
        assert!(
            e.to_string()
                .contains("text size: more than 1 MB, over the limit of 1 MB"),
            "{e}"
        );
        std::fs::write(&path, vec![b' '; 1 << 20]).unwrap();
        assert_eq!(read_text(&path, &limit).unwrap().len(), 1 << 20);
    }

    #[test]
    fn threads_writing_the_same_file_at_once_all_succeed_and_leave_one_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("shared.bin");
        std::thread::scope(|s| {
            for t in 0..8u8 {
                let path = &path;
                s.spawn(move || {
                    for _ in 0..20 {
                        write_atomic(path, |w| w.write_all(&[t; 4096])).unwrap();
                    }
                });
            }
        });
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(bytes.len(), 4096);
        assert!(bytes.iter().all(|b| *b == bytes[0]), "torn write");
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "temp files left"
        );
    }

    #[test]
    fn temporary_names_are_recognised_and_nothing_else() {
        let tmp = temp_path(Path::new("run/annotations_part_000.json"));
        let name = tmp.file_name().unwrap().to_string_lossy();
        assert!(is_temporary(&name), "{name}");
        for name in [
            ".summary.json.tmp-123-4",
            "..tmp-1-2.tmp-7-0",
            ".a.b.tmp-0-0",
        ] {
            assert!(is_temporary(name), "{name}");
        }
        for name in [
            "summary.json.tmp-123-4",
            ".summary.json.tmp-123",
            ".summary.json.tmp-12a-4",
            ".summary.json.tmp-123-",
            "..tmp-1-2",
            ".summary.json.tmp-1-2-3",
            ".summary.json",
            "annotations_part_000.json",
            ".sage3d.lock",
        ] {
            assert!(!is_temporary(name), "{name}");
        }
    }
}
