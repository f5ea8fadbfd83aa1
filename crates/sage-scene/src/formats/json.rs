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

/// A point given as `[x, y, (z)]` or `{"x", "y", ("z")}` (keys in any order, others ignored); a
/// missing z reads as 0 in either form, a missing x or y is an error naming it (`at.y`). Each
/// coordinate must be within ±[`MAX_COORDINATE`] m: a scene far larger than any building is a
/// broken file (or one in millimetres), and maps and grids grow with it. Errors name an array's
/// coordinate by index (`at[1]`) and an object's by key (`at.y`), as the file does.
pub fn point3(v: &Value, at: &str) -> Result<Vec3> {
    let mut p = [0.0f32; 3];
    match v {
        Value::Array(a) if a.len() == 2 || a.len() == 3 => {
            for (i, c) in a.iter().enumerate() {
                p[i] = coordinate(c, &format!("{at}[{i}]"))?;
            }
        }
        Value::Object(o) => {
            for (i, key) in ["x", "y", "z"].into_iter().enumerate() {
                match o.get(key).filter(|c| !c.is_null()) {
                    Some(c) => p[i] = coordinate(c, &format!("{at}.{key}"))?,
                    // As in `[x, y]`, a point without z lies at z = 0.
                    None if key == "z" => {}
                    None => {
                        return Err(Error::format(
                            format!("{at}.{key}"),
                            format!("missing: a point needs x and y, found {}", short(v)),
                        ));
                    }
                }
            }
        }
        _ => {
            return Err(Error::format(
                at,
                format!(
                    "expected a point [x, y, z] or {{x, y, z}}, found {}",
                    short(v)
                ),
            ));
        }
    }
    Ok(Vec3::from_array(p))
}

/// One coordinate of a point: a finite number within ±[`MAX_COORDINATE`] m.
fn coordinate(c: &Value, at: &str) -> Result<f32> {
    let x = number(c, at)?;
    if x.abs() > MAX_COORDINATE {
        return Err(Error::format(
            at,
            format!(
                "{} is beyond ±{MAX_COORDINATE} m (coordinates are metres)",
                short(c)
            ),
        ));
    }
    Ok(x)
}

/// A floor point given as `[x, y]` or `{"x", "y"}` (a z, if present, is checked as
/// [`point3`] checks it and dropped).
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

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn a_point_object_is_read_by_key_and_a_missing_x_or_y_is_named() {
        let p = |v: Value| point3(&v, "p");
        assert_eq!(
            p(json!({"z": 3, "y": 2, "x": 1})).unwrap(),
            Vec3::new(1.0, 2.0, 3.0)
        );
        // No z lies on the floor, in either form.
        assert_eq!(
            p(json!({"x": 1, "y": 2})).unwrap(),
            Vec3::new(1.0, 2.0, 0.0)
        );
        assert_eq!(p(json!([1, 2])).unwrap(), Vec3::new(1.0, 2.0, 0.0));
        assert_eq!(
            p(json!({"x": 1, "y": 2, "z": null, "w": 9})).unwrap(),
            Vec3::new(1.0, 2.0, 0.0)
        );
        // The z of {x, z} is not taken for a y.
        let e = p(json!({"x": 1, "z": 2})).unwrap_err();
        assert_eq!(
            e.to_string(),
            r#"p.y: missing: a point needs x and y, found {"x":1,"z":2}"#
        );
        let e = p(json!({"y": 1, "z": 2})).unwrap_err();
        assert_eq!(e.location(), "p.x", "{e}");
        let e = point2(&json!({"x": 1}), "profile[3]").unwrap_err();
        assert_eq!(e.location(), "profile[3].y", "{e}");
        // A bad coordinate is named by its key in an object, by its index in an array.
        let e = p(json!({"x": 1, "y": "a", "z": 0})).unwrap_err();
        assert_eq!(e.location(), "p.y", "{e}");
        let e = p(json!({"x": 1, "y": 0, "z": 2e4})).unwrap_err();
        assert_eq!(e.location(), "p.z", "{e}");
        assert!(e.message().contains("beyond ±10000 m"), "{e}");
        let e = p(json!([1, "a", 0])).unwrap_err();
        assert_eq!(e.location(), "p[1]", "{e}");
        for bad in [json!([1]), json!([1, 2, 3, 4]), json!(5), json!("1,2")] {
            let e = p(bad.clone()).unwrap_err();
            assert!(e.message().starts_with("expected a point"), "{bad}: {e}");
        }
    }
}
