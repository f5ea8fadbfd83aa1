//! The PLY container: header parsing and bounds-checked access to element rows, for the ASCII
//! and both binary encodings. Every error names the element, property or line at fault.

use sage_core::{Error, Result};

/// How the body is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// Whitespace-separated text, one row per line.
    Ascii,
    /// Binary, little-endian (what 3DGS tools write).
    BinaryLittleEndian,
    /// Binary, big-endian.
    BinaryBigEndian,
}

/// A scalar type of the PLY spec.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scalar {
    /// `char` / `int8`.
    I8,
    /// `uchar` / `uint8`.
    U8,
    /// `short` / `int16`.
    I16,
    /// `ushort` / `uint16`.
    U16,
    /// `int` / `int32`.
    I32,
    /// `uint` / `uint32`.
    U32,
    /// `float` / `float32`.
    F32,
    /// `double` / `float64`.
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Size in bytes.
    pub fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// Reads one value from the start of `b` (which must hold `size()` bytes).
    #[inline]
    pub fn read(self, b: &[u8], big_endian: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().expect("caller checked the row size");
                (if big_endian {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }) as f64
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => get!(i16, 2),
            Scalar::U16 => get!(u16, 2),
            Scalar::I32 => get!(i32, 4),
            Scalar::U32 => get!(u32, 4),
            Scalar::F32 => get!(f32, 4),
            Scalar::F64 => get!(f64, 8),
        }
    }
}

/// A property: a scalar, or a list with a count type and an item type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Property {
    /// Property name.
    pub name: String,
    /// Scalar type (the item type for lists).
    pub scalar: Scalar,
    /// For lists: the count type.
    pub list_count: Option<Scalar>,
}

/// An element declaration.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Element {
    /// Element name (`vertex`, `face`, `chunk`, `sh` …).
    pub name: String,
    /// Number of rows.
    pub count: usize,
    /// Properties in file order.
    pub properties: Vec<Property>,
}

impl Element {
    /// Bytes per row in binary encodings, when no property is a list.
    pub fn row_size(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|p| p.list_count.is_none().then_some(p.scalar.size()))
            .sum()
    }

    /// Index of the property called `name`.
    pub fn property_index(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name == name)
    }

    /// Byte offset inside a fixed-size row, and type, of the scalar property `name`.
    pub fn scalar_offset(&self, name: &str) -> Option<(usize, Scalar)> {
        let mut offset = 0;
        for p in &self.properties {
            if p.name == name {
                return p.list_count.is_none().then_some((offset, p.scalar));
            }
            offset += p.scalar.size();
        }
        None
    }
}

/// A parsed header.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Header {
    /// Body encoding.
    pub encoding: Encoding,
    /// Elements in file order.
    pub elements: Vec<Element>,
    /// `comment` lines.
    pub comments: Vec<String>,
    /// Byte offset of the body (just past `end_header\n`).
    pub body_offset: usize,
}

impl Header {
    /// The element called `name`.
    pub fn element(&self, name: &str) -> Option<(usize, &Element)> {
        self.elements
            .iter()
            .enumerate()
            .find(|(_, e)| e.name == name)
    }
}

/// The most rows any element may declare: guards allocations against garbage counts.
const MAX_ROWS: usize = 1 << 32;

/// Parses the header at the start of `bytes`.
pub fn parse_header(bytes: &[u8]) -> Result<Header> {
    if !bytes.starts_with(b"ply\n") && !bytes.starts_with(b"ply\r\n") {
        return Err(Error::format(
            "header",
            "not a PLY file (it must start with the line 'ply')",
        ));
    }
    let end = find(bytes, b"end_header")
        .ok_or_else(|| Error::format("header", "no 'end_header' line"))?;
    let mut body_offset = end + b"end_header".len();
    match bytes.get(body_offset..body_offset + 2) {
        Some([b'\r', b'\n']) => body_offset += 2,
        Some([b'\n', _]) | Some([b'\n']) => body_offset += 1,
        _ if bytes.get(body_offset) == Some(&b'\n') => body_offset += 1,
        _ => return Err(Error::format("header", "'end_header' must end its line")),
    }
    let text = std::str::from_utf8(&bytes[..end])
        .map_err(|_| Error::format("header", "header is not text"))?;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut comments = Vec::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let at = || format!("header line {}", n + 1);
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            [] => {}
            ["comment", ..] | ["obj_info", ..] => {
                comments.push(line.trim_start()[words[0].len()..].trim().to_string())
            }
            ["format", f, _version] => {
                encoding = Some(match *f {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::BinaryLittleEndian,
                    "binary_big_endian" => Encoding::BinaryBigEndian,
                    other => return Err(Error::format(at(), format!("unknown format '{other}'"))),
                })
            }
            ["element", name, count] => {
                let count: usize =
                    count
                        .parse()
                        .ok()
                        .filter(|c| *c <= MAX_ROWS)
                        .ok_or_else(|| {
                            Error::format(
                                at(),
                                format!("element '{name}' has a bad count '{count}'"),
                            )
                        })?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", "list", count_ty, item_ty, name] => {
                let e = elements
                    .last_mut()
                    .ok_or_else(|| Error::format(at(), "property before any element"))?;
                let (Some(c), Some(i)) = (Scalar::parse(count_ty), Scalar::parse(item_ty)) else {
                    return Err(Error::format(
                        at(),
                        format!("unknown list types '{count_ty} {item_ty}'"),
                    ));
                };
                e.properties.push(Property {
                    name: name.to_string(),
                    scalar: i,
                    list_count: Some(c),
                });
            }
            ["property", ty, name] => {
                let e = elements
                    .last_mut()
                    .ok_or_else(|| Error::format(at(), "property before any element"))?;
                let s = Scalar::parse(ty)
                    .ok_or_else(|| Error::format(at(), format!("unknown property type '{ty}'")))?;
                e.properties.push(Property {
                    name: name.to_string(),
                    scalar: s,
                    list_count: None,
                });
            }
            _ => {
                return Err(Error::format(
                    at(),
                    format!("cannot read '{}'", line.trim()),
                ));
            }
        }
    }
    let encoding = encoding.ok_or_else(|| Error::format("header", "no 'format' line"))?;
    Ok(Header {
        encoding,
        elements,
        comments,
        body_offset,
    })
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// The rows of one element, decoded lazily from binary bytes or eagerly from ASCII text.
pub enum Rows<'a> {
    /// Fixed-size binary rows.
    Fixed {
        /// The element's bytes.
        bytes: &'a [u8],
        /// Bytes per row.
        stride: usize,
        /// Byte order.
        big_endian: bool,
    },
    /// Rows with lists (binary), or any ASCII rows: every value as `f64`, with row starts.
    Values {
        /// All values in file order (list counts included).
        values: Vec<f64>,
        /// Index in `values` where each row starts (plus one past the end).
        row_starts: Vec<usize>,
    },
}

/// The rows of every element of a PLY body, checked against the header.
pub fn element_rows<'a>(header: &Header, bytes: &'a [u8]) -> Result<Vec<Rows<'a>>> {
    let body = &bytes[header.body_offset.min(bytes.len())..];
    match header.encoding {
        Encoding::Ascii => {
            let header_lines = bytes[..header.body_offset.min(bytes.len())]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
            ascii_rows(header, body, header_lines)
        }
        Encoding::BinaryLittleEndian => binary_rows(header, body, false),
        Encoding::BinaryBigEndian => binary_rows(header, body, true),
    }
}

fn truncated(e: &Element, need: usize, have: usize) -> Error {
    Error::format(
        format!("element '{}'", e.name),
        format!(
            "file is truncated: {} rows need {need} more bytes, {have} remain",
            e.count
        ),
    )
}

fn binary_rows<'a>(header: &Header, body: &'a [u8], big_endian: bool) -> Result<Vec<Rows<'a>>> {
    let mut pos = 0usize;
    let mut out = Vec::with_capacity(header.elements.len());
    for e in &header.elements {
        let rest = &body[pos..];
        if let Some(stride) = e.row_size() {
            let need = stride
                .checked_mul(e.count)
                .ok_or_else(|| truncated(e, usize::MAX, rest.len()))?;
            if need > rest.len() {
                return Err(truncated(e, need, rest.len()));
            }
            out.push(Rows::Fixed {
                bytes: &rest[..need],
                stride,
                big_endian,
            });
            pos += need;
            continue;
        }
        let mut values = Vec::new();
        let mut row_starts = Vec::with_capacity(e.count.min(rest.len()) + 1);
        let mut p = 0usize;
        for row in 0..e.count {
            row_starts.push(values.len());
            for prop in &e.properties {
                let read = |p: usize, s: Scalar| -> Result<f64> {
                    rest.get(p..p + s.size())
                        .map(|b| s.read(b, big_endian))
                        .ok_or_else(|| {
                            Error::format(
                                format!("element '{}' row {row}", e.name),
                                "file is truncated",
                            )
                        })
                };
                match prop.list_count {
                    None => {
                        values.push(read(p, prop.scalar)?);
                        p += prop.scalar.size();
                    }
                    Some(ct) => {
                        let n = read(p, ct)?;
                        if !(0.0..=1e6).contains(&n) {
                            return Err(Error::format(
                                format!("element '{}' row {row}.{}", e.name, prop.name),
                                format!("bad list length {n}"),
                            ));
                        }
                        p += ct.size();
                        values.push(n);
                        for _ in 0..n as usize {
                            values.push(read(p, prop.scalar)?);
                            p += prop.scalar.size();
                        }
                    }
                }
            }
        }
        row_starts.push(values.len());
        out.push(Rows::Values { values, row_starts });
        pos += p;
    }
    Ok(out)
}

fn ascii_rows<'a>(header: &Header, body: &[u8], header_lines: usize) -> Result<Vec<Rows<'a>>> {
    let text =
        std::str::from_utf8(body).map_err(|_| Error::format("body", "ASCII body is not text"))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let mut out = Vec::with_capacity(header.elements.len());
    for e in &header.elements {
        let mut values = Vec::new();
        let mut row_starts = Vec::with_capacity(e.count.min(body.len()) + 1);
        for row in 0..e.count {
            let (n, line) = lines.next().ok_or_else(|| {
                Error::format(
                    format!("element '{}'", e.name),
                    format!("file ends after {row} of {} rows", e.count),
                )
            })?;
            let at = || {
                format!(
                    "body line {} (element '{}' row {row})",
                    n + 1 + header_lines,
                    e.name
                )
            };
            row_starts.push(values.len());
            let mut words = line.split_whitespace();
            let mut next = |what: &str| -> Result<f64> {
                let w = words
                    .next()
                    .ok_or_else(|| Error::format(at(), format!("missing value for '{what}'")))?;
                w.parse::<f64>()
                    .map_err(|_| Error::format(at(), format!("'{w}' is not a number ({what})")))
            };
            for prop in &e.properties {
                match prop.list_count {
                    None => values.push(next(&prop.name)?),
                    Some(_) => {
                        let n = next(&prop.name)?;
                        if !(0.0..=1e6).contains(&n) || n.fract() != 0.0 {
                            return Err(Error::format(at(), format!("bad list length {n}")));
                        }
                        values.push(n);
                        for _ in 0..n as usize {
                            values.push(next(&prop.name)?);
                        }
                    }
                }
            }
        }
        row_starts.push(values.len());
        out.push(Rows::Values { values, row_starts });
    }
    Ok(out)
}

impl Rows<'_> {
    /// Number of rows.
    pub fn len(&self) -> usize {
        match self {
            Rows::Fixed { bytes, stride, .. } => bytes.len().checked_div(*stride).unwrap_or(0),
            Rows::Values { row_starts, .. } => row_starts.len().saturating_sub(1),
        }
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The values of row `row` for property `prop` of `element`: one for a scalar, the items for
    /// a list. `row` must be in range.
    pub fn values(&self, element: &Element, row: usize, prop: usize) -> Vec<f64> {
        match self {
            Rows::Fixed {
                bytes,
                stride,
                big_endian,
            } => {
                let offset: usize = element.properties[..prop]
                    .iter()
                    .map(|p| p.scalar.size())
                    .sum();
                let s = element.properties[prop].scalar;
                vec![s.read(&bytes[row * stride + offset..], *big_endian)]
            }
            Rows::Values { values, row_starts } => {
                let row_values = &values[row_starts[row]..row_starts[row + 1]];
                let mut i = 0;
                for (k, p) in element.properties.iter().enumerate() {
                    let len = if p.list_count.is_some() {
                        1 + row_values[i] as usize
                    } else {
                        1
                    };
                    if k == prop {
                        let v = &row_values[i..i + len];
                        return if p.list_count.is_some() {
                            v[1..].to_vec()
                        } else {
                            v.to_vec()
                        };
                    }
                    i += len;
                }
                Vec::new()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_header_and_finds_body() {
        let h = parse_header(b"ply\nformat binary_little_endian 1.0\ncomment hi there\nelement vertex 2\nproperty float x\nproperty uchar r\nelement face 1\nproperty list uchar int vertex_indices\nend_header\nXYZ").unwrap();
        assert_eq!(h.encoding, Encoding::BinaryLittleEndian);
        assert_eq!(h.comments, vec!["hi there"]);
        assert_eq!(h.elements[0].row_size(), Some(5));
        assert_eq!(h.elements[1].row_size(), None);
        assert_eq!(h.elements[0].scalar_offset("r"), Some((4, Scalar::U8)));
        assert_eq!(h.body_offset, h.body_offset.min(200));
    }

    #[test]
    fn ascii_body_with_lists() {
        let src = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        let h = parse_header(src).unwrap();
        let rows = element_rows(&h, src).unwrap();
        assert_eq!(rows[1].values(&h.elements[1], 0, 0), vec![0.0, 1.0, 2.0]);
        assert_eq!(rows[0].values(&h.elements[0], 1, 0), vec![1.0]);
    }

    #[test]
    fn truncated_binary_names_the_element() {
        let mut src = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nend_header\n".to_vec();
        src.extend_from_slice(&[0u8; 12]);
        let h = parse_header(&src).unwrap();
        let e = element_rows(&h, &src).err().unwrap();
        assert!(
            e.to_string()
                .contains("element 'vertex': file is truncated"),
            "{e}"
        );
    }

    #[test]
    fn garbage_is_an_error() {
        assert!(parse_header(b"PK\x03\x04").is_err());
        assert!(
            parse_header(b"ply\nformat binary_little_endian 1.0\nelement vertex -3\nend_header\n")
                .is_err()
        );
        assert!(parse_header(b"ply\nproperty float x\nend_header\n").is_err());
    }
}
