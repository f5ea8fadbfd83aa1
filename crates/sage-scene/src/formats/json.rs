//! Small helpers for reading loosely typed JSON with errors that name the field.

use glam::{Vec2, Vec3};
use sage_core::{Error, MAX_COORDINATE, Result};
use serde_json::Value;

/// Parses JSON text (a leading byte-order mark is accepted); a syntax error names its line and
/// column.
pub fn parse_text(text: &str) -> Result<Value> {
    serde_json::from_str(sage_io::files::strip_bom(text))
        .map_err(|e| sage_io::files::json_error(&e))
}

/// `v[key]`, or an error naming `key` as missing.
pub fn field<'a>(v: &'a Value, key: &str) -> Result<&'a Value> {
    v.get(key)
        .filter(|x| !x.is_null())
        .ok_or_else(|| Error::format(key, "missing"))
}

/// A number finite in single precision (1e300 is finite as f64 but not as f32).
pub fn number(v: &Value, at: &str) -> Result<f32> {
    let f = match v {
        Value::Number(n) => n.as_f64(),
        Value::String(s) => s.trim().parse::<f64>().ok(),
        _ => None,
    };
    match f.filter(|f| f.is_finite()) {
        Some(f) if (f as f32).is_finite() => Ok(f as f32),
        // Finite in the file's double precision: the error says which range it leaves.
        Some(_) => Err(Error::format(
            at,
            format!(
                "{} is out of the single-precision (f32) range of ±{:e}",
                short(v),
                f32::MAX
            ),
        )),
        None => Err(Error::format(
            at,
            format!("expected a finite number, found {}", short(v)),
        )),
    }
}

/// A string (numbers are accepted and written out, as ids often are).
pub fn string(v: &Value, at: &str) -> Result<String> {
    match v {
        Value::String(s) => Ok(s.clone()),
        Value::Number(n) => Ok(n.to_string()),
        _ => Err(Error::format(
            at,
            format!("expected a string, found {}", short(v)),
        )),
    }
}

/// An array.
pub fn array<'a>(v: &'a Value, at: &str) -> Result<&'a Vec<Value>> {
    v.as_array()
        .ok_or_else(|| Error::format(at, format!("expected an array, found {}", short(v))))
}

/// A point given as `[x, y, (z)]` or `{x, y, (z)}`; a missing z reads as 0. Each coordinate
/// must be within ±[`MAX_COORDINATE`] m: a scene far larger than any building is a broken file
/// (or one in millimetres), and maps and grids grow with it.
pub fn point3(v: &Value, at: &str) -> Result<Vec3> {
    let comps: Vec<&Value> = match v {
        Value::Array(a) if a.len() == 2 || a.len() == 3 => a.iter().collect(),
        Value::Object(o) => ["x", "y", "z"].iter().filter_map(|k| o.get(*k)).collect(),
        _ => Vec::new(),
    };
    if comps.len() < 2 {
        return Err(Error::format(
            at,
            format!(
                "expected a point [x, y, z] or {{x, y, z}}, found {}",
                short(v)
            ),
        ));
    }
    let mut p = [0.0f32; 3];
    for (i, c) in comps.iter().enumerate() {
        p[i] = number(c, &format!("{at}[{i}]"))?;
        if p[i].abs() > MAX_COORDINATE {
            return Err(Error::format(
                format!("{at}[{i}]"),
                format!(
                    "{} is beyond ±{MAX_COORDINATE} m (coordinates are metres)",
                    short(c)
                ),
            ));
        }
    }
    Ok(Vec3::from_array(p))
}

/// A floor point given as `[x, y]` or `{x, y}` (a z, if present, is ignored).
pub fn point2(v: &Value, at: &str) -> Result<Vec2> {
    point3(v, at).map(|p| p.truncate())
}

/// A short rendering of a value for error messages.
pub fn short(v: &Value) -> String {
    let s = v.to_string();
    if s.len() > 40 {
        format!(
            "{}…",
            &s[..s.char_indices().nth(40).map_or(s.len(), |c| c.0)]
        )
    } else {
        s
    }
}
