//! openpi's msgpack-numpy encoding, the message format of the GN0 / openpi WebSocket policy
//! servers: one MessagePack value per message, NumPy arrays as maps with **bin** keys
//! `__ndarray__` (true), `data` (the C-order bytes), `dtype` (the NumPy type string, e.g.
//! `|u1`, `<f4`) and `shape` (an array of ints), and NumPy scalars as maps with bin keys
//! `__npgeneric__` (true), `data` (the plain value) and `dtype`.
//!
//! [`decode`] reads a message into an [`Item`] tree in which those maps are recognised
//! ([`Item::Array`]) and every other map key is turned into text, as GN0's client does.

use rmpv::Value;

/// A NumPy array as openpi sends it: type string, shape and C-order bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct NdArray {
    /// The NumPy type string: byte order (`<`, `>`, `|`, `=`), kind and item size (`|u1`).
    pub dtype: String,
    /// The shape; empty for a 0-d array.
    pub shape: Vec<usize>,
    /// The elements in C order, `dtype`'s byte order.
    pub data: Vec<u8>,
}

/// A decoded message: MessagePack values with NumPy arrays and scalars recognised.
#[derive(Debug, Clone, PartialEq)]
pub enum Item {
    /// `nil` (Python `None`).
    Nil,
    /// A boolean.
    Bool(bool),
    /// An integer (or an integer NumPy scalar).
    Int(i128),
    /// A float (or a float NumPy scalar).
    Float(f64),
    /// A string.
    Str(String),
    /// A byte string.
    Bin(Vec<u8>),
    /// A list.
    List(Vec<Item>),
    /// A map, keys as text (byte keys read as UTF-8, other keys as MessagePack writes them).
    Map(Vec<(String, Item)>),
    /// A NumPy array.
    Array(NdArray),
}

impl Item {
    /// The value under `key` of a map.
    pub fn get(&self, key: &str) -> Option<&Item> {
        match self {
            Item::Map(pairs) => pairs.iter().find(|(k, _)| k == key).map(|(_, v)| v),
            _ => None,
        }
    }

    /// The text of a string or UTF-8 byte string.
    pub fn as_str(&self) -> Option<&str> {
        match self {
            Item::Str(s) => Some(s),
            Item::Bin(b) => std::str::from_utf8(b).ok(),
            _ => None,
        }
    }
}

/// The numbers of an array or nested list, with its shape and whether any is a float.
#[derive(Debug, Clone, PartialEq)]
pub struct Numbers {
    /// The values in C order.
    pub values: Vec<f64>,
    /// The shape (empty: a scalar).
    pub shape: Vec<usize>,
    /// True when the values are floats (a float dtype, or a float in a list).
    pub float: bool,
}

impl NdArray {
    /// A `uint8` array (`|u1`) of `shape` over `data`.
    ///
    /// # Panics
    ///
    /// `data` does not hold exactly the elements of `shape` (a caller's bug).
    pub fn uint8(shape: Vec<usize>, data: Vec<u8>) -> NdArray {
        assert_eq!(
            shape.iter().product::<usize>(),
            data.len(),
            "uint8 {shape:?}"
        );
        NdArray {
            dtype: "|u1".into(),
            shape,
            data,
        }
    }

    /// A little-endian `float32` array (`<f4`) of `shape` over `values`.
    ///
    /// # Panics
    ///
    /// `values` does not hold exactly the elements of `shape` (a caller's bug).
    pub fn float32(shape: Vec<usize>, values: &[f32]) -> NdArray {
        assert_eq!(
            shape.iter().product::<usize>(),
            values.len(),
            "f32 {shape:?}"
        );
        NdArray {
            dtype: "<f4".into(),
            shape,
            data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }

    /// The array as openpi encodes it: a map with bin keys.
    pub fn to_value(&self) -> Value {
        let key = |k: &str| Value::Binary(k.as_bytes().to_vec());
        Value::Map(vec![
            (key("__ndarray__"), Value::Boolean(true)),
            (key("data"), Value::Binary(self.data.clone())),
            (key("dtype"), Value::String(self.dtype.as_str().into())),
            (
                key("shape"),
                Value::Array(self.shape.iter().map(|&n| Value::from(n as u64)).collect()),
            ),
        ])
    }

    /// The elements as numbers, for the numeric dtypes (`b1`, `i1`–`i8`, `u1`–`u8`, `f2`–`f8`,
    /// either byte order).
    ///
    /// # Errors
    ///
    /// Another dtype, or data whose length does not match the shape.
    pub fn numbers(&self) -> Result<Numbers, String> {
        let bad = || format!("unsupported dtype '{}'", self.dtype);
        let (order, code) = match self.dtype.as_bytes().first() {
            Some(b'<' | b'>' | b'|' | b'=') => self.dtype.split_at(1),
            _ => ("=", self.dtype.as_str()),
        };
        let big = order == ">";
        let (kind, size) = code.split_at(code.len().min(1));
        let size: usize = size.parse().map_err(|_| bad())?;
        let word = |c: &[u8]| -> [u8; 8] {
            let mut w = [0u8; 8];
            w[..c.len()].copy_from_slice(c);
            if big {
                w[..c.len()].reverse();
            }
            w
        };
        let read: fn([u8; 8]) -> f64 = match (kind, size) {
            ("b" | "u", 1) => |w| f64::from(w[0]),
            ("u", 2) => |w| f64::from(u16::from_le_bytes([w[0], w[1]])),
            ("u", 4) => |w| f64::from(u32::from_le_bytes([w[0], w[1], w[2], w[3]])),
            ("u", 8) => |w| u64::from_le_bytes(w) as f64,
            ("i", 1) => |w| f64::from(w[0] as i8),
            ("i", 2) => |w| f64::from(i16::from_le_bytes([w[0], w[1]])),
            ("i", 4) => |w| f64::from(i32::from_le_bytes([w[0], w[1], w[2], w[3]])),
            ("i", 8) => |w| i64::from_le_bytes(w) as f64,
            ("f", 2) => |w| half_to_f64(u16::from_le_bytes([w[0], w[1]])),
            ("f", 4) => |w| f64::from(f32::from_le_bytes([w[0], w[1], w[2], w[3]])),
            ("f", 8) => |w| f64::from_le_bytes(w),
            _ => return Err(bad()),
        };
        // Checked: a hostile shape's product would otherwise wrap to match the data's length.
        let expected = self
            .shape
            .iter()
            .try_fold(size, |bytes, &n| bytes.checked_mul(n))
            .ok_or_else(|| {
                format!(
                    "array {} of shape {:?} is too large",
                    self.dtype, self.shape
                )
            })?;
        if self.data.len() != expected {
            return Err(format!(
                "array {} of shape {:?} has {} bytes, expected {expected}",
                self.dtype,
                self.shape,
                self.data.len(),
            ));
        }
        Ok(Numbers {
            values: self
                .data
                .chunks_exact(size)
                .map(|c| read(word(c)))
                .collect(),
            shape: self.shape.clone(),
            float: kind == "f",
        })
    }
}

/// An IEEE half-precision value.
fn half_to_f64(h: u16) -> f64 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = i32::from((h >> 10) & 0x1f);
    let frac = f64::from(h & 0x3ff);
    sign * match exp {
        0 => frac * 2f64.powi(-24),
        31 if frac == 0.0 => f64::INFINITY,
        31 => f64::NAN,
        e => (1.0 + frac / 1024.0) * 2f64.powi(e - 15),
    }
}

/// Encodes one message.
pub fn encode(value: &Value) -> Vec<u8> {
    let mut out = Vec::new();
    rmpv::encode::write_value(&mut out, value).expect("writing to a Vec cannot fail");
    out
}

/// Decodes one message (exactly one MessagePack value).
///
/// # Errors
///
/// Bytes that are not one MessagePack value, or a NumPy map with missing or mistyped fields.
pub fn decode(bytes: &[u8]) -> Result<Item, String> {
    let mut rest = bytes;
    let value = rmpv::decode::read_value(&mut rest)
        .map_err(|e| format!("malformed msgpack ({} bytes): {e}", bytes.len()))?;
    if !rest.is_empty() {
        return Err(format!(
            "malformed msgpack: {} bytes after the message's value",
            rest.len()
        ));
    }
    item(&value)
}

/// The text of a map key: a string, UTF-8 bytes, or the key as MessagePack prints it.
fn key_text(key: &Value) -> String {
    match key {
        Value::String(s) => s.as_str().map_or_else(|| key.to_string(), str::to_string),
        Value::Binary(b) => String::from_utf8_lossy(b).into_owned(),
        other => other.to_string(),
    }
}

/// One value as an [`Item`].
fn item(value: &Value) -> Result<Item, String> {
    Ok(match value {
        Value::Nil => Item::Nil,
        Value::Boolean(b) => Item::Bool(*b),
        Value::Integer(i) => Item::Int(
            i.as_i64()
                .map(i128::from)
                .or_else(|| i.as_u64().map(i128::from))
                .unwrap_or_default(),
        ),
        Value::F32(f) => Item::Float(f64::from(*f)),
        Value::F64(f) => Item::Float(*f),
        Value::String(s) => Item::Str(String::from_utf8_lossy(s.as_bytes()).into_owned()),
        Value::Binary(b) => Item::Bin(b.clone()),
        Value::Array(a) => Item::List(a.iter().map(item).collect::<Result<_, _>>()?),
        Value::Ext(tag, _) => return Err(format!("msgpack extension type {tag} is not read")),
        Value::Map(pairs) => {
            let pairs: Vec<(String, Item)> = pairs
                .iter()
                .map(|(k, v)| Ok((key_text(k), item(v)?)))
                .collect::<Result<_, String>>()?;
            let map = Item::Map(pairs);
            if map.get("__ndarray__").is_some() {
                Item::Array(ndarray(&map)?)
            } else if map.get("__npgeneric__").is_some() {
                match map.get("data") {
                    Some(v @ (Item::Int(_) | Item::Float(_) | Item::Bool(_))) => v.clone(),
                    other => {
                        return Err(format!(
                            "numpy scalar: data is {other:?}, expected a number"
                        ));
                    }
                }
            } else {
                map
            }
        }
    })
}

/// The array of an `__ndarray__` map.
fn ndarray(map: &Item) -> Result<NdArray, String> {
    let dtype = map
        .get("dtype")
        .and_then(Item::as_str)
        .ok_or("numpy array: no dtype string")?
        .to_string();
    let shape = match map.get("shape") {
        Some(Item::List(dims)) => dims
            .iter()
            .map(|d| match d {
                Item::Int(n) => usize::try_from(*n).ok(),
                _ => None,
            })
            .collect::<Option<Vec<usize>>>()
            .ok_or("numpy array: shape is not a list of sizes")?,
        _ => return Err("numpy array: no shape list".into()),
    };
    let Some(Item::Bin(data)) = map.get("data") else {
        return Err("numpy array: data is not bytes".into());
    };
    Ok(NdArray {
        dtype,
        shape,
        data: data.clone(),
    })
}

/// The numbers of an item: an array, a number, or a nested list of equal-length lists of
/// numbers.
///
/// # Errors
///
/// Anything else (a string, a map, ragged lists, a non-numeric dtype).
pub fn numbers(item: &Item) -> Result<Numbers, String> {
    match item {
        Item::Array(a) => a.numbers(),
        Item::Int(n) => Ok(Numbers {
            values: vec![*n as f64],
            shape: Vec::new(),
            float: false,
        }),
        Item::Float(f) => Ok(Numbers {
            values: vec![*f],
            shape: Vec::new(),
            float: true,
        }),
        Item::List(items) => {
            let parts = items.iter().map(numbers).collect::<Result<Vec<_>, _>>()?;
            let inner = parts.first().map(|p| p.shape.clone()).unwrap_or_default();
            if parts.iter().any(|p| p.shape != inner) {
                return Err("a ragged list of numbers".into());
            }
            let mut shape = vec![parts.len()];
            shape.extend(inner);
            Ok(Numbers {
                float: parts.iter().any(|p| p.float),
                values: parts.into_iter().flat_map(|p| p.values).collect(),
                shape,
            })
        }
        other => Err(format!("expected numbers, got {}", describe(other))),
    }
}

/// An item written out compactly, JSON-like (arrays as `dtype[shape]`, bytes as their count),
/// for the record's notes.
pub fn show(item: &Item) -> String {
    match item {
        Item::Str(s) => format!("{s:?}"),
        Item::List(l) => format!("[{}]", l.iter().map(show).collect::<Vec<_>>().join(", ")),
        Item::Map(m) => format!(
            "{{{}}}",
            m.iter()
                .map(|(k, v)| format!("{k:?}: {}", show(v)))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        Item::Array(a) => format!("{}{:?}", a.dtype, a.shape),
        other => describe(other),
    }
}

/// A short description of an item for messages.
pub fn describe(item: &Item) -> String {
    match item {
        Item::Nil => "nil".into(),
        Item::Bool(b) => b.to_string(),
        Item::Int(n) => n.to_string(),
        Item::Float(f) => f.to_string(),
        Item::Str(s) => format!("the string {:?}", s.chars().take(80).collect::<String>()),
        Item::Bin(b) => format!("{} bytes", b.len()),
        Item::List(l) => format!("a list of {}", l.len()),
        Item::Map(m) => format!(
            "a map with keys {}",
            m.iter()
                .map(|(k, _)| k.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ),
        Item::Array(a) => format!("a {} array of shape {:?}", a.dtype, a.shape),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_uint8_array_encodes_to_the_bytes_the_msgpack_spec_gives() {
        let a = NdArray::uint8(vec![1, 2], vec![7, 9]);
        // By hand from the MessagePack spec: fixmap of 4 (0x84); bin 8 keys (0xc4, length);
        // true 0xc3; bin8 data; fixstr "|u1" (0xa3); fixarray of 2 positive fixints.
        let mut want = vec![0x84, 0xc4, 11];
        want.extend(b"__ndarray__");
        want.push(0xc3);
        want.extend([0xc4, 4]);
        want.extend(b"data");
        want.extend([0xc4, 2, 7, 9]);
        want.extend([0xc4, 5]);
        want.extend(b"dtype");
        want.push(0xa3);
        want.extend(b"|u1");
        want.extend([0xc4, 5]);
        want.extend(b"shape");
        want.extend([0x92, 0x01, 0x02]);
        assert_eq!(encode(&a.to_value()), want);
        assert_eq!(decode(&want).unwrap(), Item::Array(a));
    }

    #[test]
    fn arrays_scalars_and_maps_round_trip() {
        let f = NdArray::float32(vec![2, 3], &[0.25, -1.0, 0.5, 3.0, 0.0, -0.125]);
        let message = Value::Map(vec![
            (Value::from("actions"), f.to_value()),
            (Value::Binary(b"k".to_vec()), Value::from("v")),
            (
                Value::from("list"),
                Value::Array(vec![Value::from(1), Value::from(-2)]),
            ),
        ]);
        let item = decode(&encode(&message)).unwrap();
        assert_eq!(item.get("actions"), Some(&Item::Array(f.clone())));
        assert_eq!(item.get("k").and_then(Item::as_str), Some("v"));
        let n = numbers(item.get("actions").unwrap()).unwrap();
        assert_eq!(n.shape, [2, 3]);
        assert_eq!(n.values, [0.25, -1.0, 0.5, 3.0, 0.0, -0.125]);
        assert!(n.float);
        let l = numbers(item.get("list").unwrap()).unwrap();
        assert_eq!(
            (l.values, l.shape, l.float),
            (vec![1.0, -2.0], vec![2], false)
        );
        // A 0-d array, big-endian and half floats, a NumPy scalar.
        let zero_d = NdArray {
            dtype: ">i2".into(),
            shape: vec![],
            data: vec![0xff, 0xfe],
        };
        assert_eq!(zero_d.numbers().unwrap().values, [-2.0]);
        let half = NdArray {
            dtype: "<f2".into(),
            shape: vec![2],
            data: vec![0x00, 0x3c, 0x00, 0xc1],
        };
        assert_eq!(half.numbers().unwrap().values, [1.0, -2.5]);
        let key = |k: &str| Value::Binary(k.as_bytes().to_vec());
        let scalar = Value::Map(vec![
            (key("__npgeneric__"), Value::Boolean(true)),
            (key("data"), Value::F64(1.5)),
            (key("dtype"), Value::from("<f8")),
        ]);
        assert_eq!(decode(&encode(&scalar)).unwrap(), Item::Float(1.5));
        assert_eq!(
            show(&item),
            r#"{"actions": <f4[2, 3], "k": "v", "list": [1, -2]}"#
        );
    }

    #[test]
    fn malformed_messages_and_arrays_are_errors() {
        assert!(decode(&[0x92, 0x01]).unwrap_err().contains("malformed"));
        assert!(decode(&[0x01, 0x02]).unwrap_err().contains("after"));
        let short = NdArray {
            dtype: "<f4".into(),
            shape: vec![2],
            data: vec![0; 5],
        };
        assert!(short.numbers().unwrap_err().contains("5 bytes"));
        // A shape whose byte count wraps to the data's length (2⁶² × 2⁶² × 4 is 0 mod 2⁶⁴).
        let wraps = NdArray {
            dtype: "<f4".into(),
            shape: vec![1 << 62, 1 << 62],
            data: Vec::new(),
        };
        assert!(wraps.numbers().unwrap_err().contains("too large"));
        let text = NdArray {
            dtype: "<U3".into(),
            shape: vec![1],
            data: vec![0; 12],
        };
        assert!(text.numbers().unwrap_err().contains("<U3"));
        let mut no_shape = NdArray::uint8(vec![1], vec![1]).to_value();
        if let Value::Map(pairs) = &mut no_shape {
            pairs.pop();
        }
        assert!(decode(&encode(&no_shape)).unwrap_err().contains("shape"));
        let ragged = Item::List(vec![
            Item::List(vec![Item::Int(1)]),
            Item::List(vec![Item::Int(1), Item::Int(2)]),
        ]);
        assert!(numbers(&ragged).unwrap_err().contains("ragged"));
    }
}
