//! The error type of sage3d: every failure says which file, which field or line, and what was
//! expected, so a researcher with a broken scene folder knows what to fix.

use std::fmt;
use std::path::{Path, PathBuf};

/// What went wrong, broadly; the message says the rest.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// The operating system refused a read or write.
    Io,
    /// A file's content does not follow its format (truncated, garbage, wrong counts, NaN…).
    Format,
    /// A caller passed an argument or configuration that cannot be honoured.
    InvalidInput,
}

/// An error with the file, the location inside it (element, field, line) and a message.
#[derive(Debug)]
pub struct Error {
    kind: ErrorKind,
    file: Option<PathBuf>,
    /// Where the file was read (`scene s1`): places named after the file was, outermost first.
    context: Vec<String>,
    location: Vec<String>,
    message: String,
    source: Option<std::io::Error>,
}

/// `Result` with sage3d's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An I/O failure on `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error {
            kind: ErrorKind::Io,
            file: Some(path.as_ref().to_path_buf()),
            context: Vec::new(),
            location: Vec::new(),
            message: source.to_string(),
            source: Some(source),
        }
    }

    /// Content that breaks its format at `location` (a field, element or line).
    pub fn format(location: impl Into<String>, message: impl Into<String>) -> Self {
        Error {
            kind: ErrorKind::Format,
            file: None,
            context: Vec::new(),
            location: vec![location.into()],
            message: message.into(),
            source: None,
        }
    }

    /// An argument or setting that cannot be honoured.
    pub fn invalid(message: impl Into<String>) -> Self {
        Error {
            kind: ErrorKind::InvalidInput,
            file: None,
            context: Vec::new(),
            location: Vec::new(),
            message: message.into(),
            source: None,
        }
    }

    /// Names the file the error belongs to (kept if one is already set).
    pub fn in_file(mut self, path: impl AsRef<Path>) -> Self {
        if self.file.is_none() {
            self.file = Some(path.as_ref().to_path_buf());
        }
        self
    }

    /// Adds an outer location, e.g. `"labels[3]"` around `"bounding_box"`.
    /// Once the error names its file, an outer place says where that file was read (`scene
    /// s1` around a labels file's `line 1 column 9`) and is shown before the file, so two
    /// places never run together.
    pub fn within(mut self, outer: impl Into<String>) -> Self {
        if self.file.is_some() {
            self.context.insert(0, outer.into());
        } else {
            self.location.insert(0, outer.into());
        }
        self
    }

    /// The broad class of the failure.
    pub fn kind(&self) -> ErrorKind {
        self.kind
    }

    /// The file at fault, when known.
    pub fn file(&self) -> Option<&Path> {
        self.file.as_deref()
    }

    /// The location inside the file, outermost first, joined with `.`, except after a place
    /// that ends with a line of a line-per-record file (`line 3`, `shard 0, line 3`), which a
    /// comma ends: `line 3, record.steps[0]` (a field path is not a member of the line).
    pub fn location(&self) -> String {
        let mut out = String::new();
        for (k, part) in self.location.iter().enumerate() {
            if k > 0 {
                let line = self.location[k - 1]
                    .rsplit_once("line ")
                    .is_some_and(|(_, n)| n.parse::<u64>().is_ok());
                out.push_str(if line { ", " } else { "." });
            }
            out.push_str(part);
        }
        out
    }

    /// The message alone, without file or location.
    pub fn message(&self) -> &str {
        &self.message
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for place in &self.context {
            write!(f, "{place}: ")?;
        }
        if let Some(file) = &self.file {
            write!(f, "{}: ", file.display())?;
        }
        if !self.location.is_empty() {
            write!(f, "{}: ", self.location())?;
        }
        f.write_str(&self.message)
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.source.as_ref().map(|e| e as _)
    }
}

/// Attaches file and location context to any `Result` carrying an [`Error`].
pub trait ResultExt<T> {
    /// See [`Error::in_file`].
    fn in_file(self, path: impl AsRef<Path>) -> Result<T>;
    /// See [`Error::within`].
    fn within(self, outer: impl Into<String>) -> Result<T>;
}

impl<T> ResultExt<T> for Result<T> {
    fn in_file(self, path: impl AsRef<Path>) -> Result<T> {
        self.map_err(|e| e.in_file(path))
    }
    fn within(self, outer: impl Into<String>) -> Result<T> {
        self.map_err(|e| e.within(outer))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_and_its_field_path_are_told_apart() {
        let e = Error::format("position", "not finite")
            .within("start")
            .within("line 3")
            .in_file("episodes.jsonl");
        assert_eq!(
            e.to_string(),
            "episodes.jsonl: line 3, start.position: not finite"
        );
    }

    #[test]
    fn display_names_file_location_and_message() {
        let e = Error::format("bounding_box", "expected 8 corners, found 7")
            .within("labels[3]")
            .in_file("scene/labels.json");
        assert_eq!(
            e.to_string(),
            "scene/labels.json: labels[3].bounding_box: expected 8 corners, found 7"
        );
        assert_eq!(e.kind(), ErrorKind::Format);
    }

    #[test]
    fn a_place_around_a_named_file_comes_before_it() {
        let e = Error::format("line 1 column 9", "expected value")
            .in_file("s1/labels.json")
            .within("scene s1");
        assert_eq!(
            e.to_string(),
            "scene s1: s1/labels.json: line 1 column 9: expected value"
        );
        assert_eq!(e.location(), "line 1 column 9");
    }

    #[test]
    fn first_file_wins() {
        let e = Error::invalid("x").in_file("a").in_file("b");
        assert_eq!(e.file(), Some(Path::new("a")));
    }
}
