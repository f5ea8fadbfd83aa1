//! InteriorGS `structure.json`: `rooms[{profile, room_type}]`, `walls[{location, thickness,
//! height}]`, `holes[{profile, thickness, type}]`, `ins[{label, position, size}]`.
//!
//! Walls without `thickness` or `height` take 0.2 m and 2.8 m (the values other InteriorGS
//! readers assume). Holes may carry our optional `state` (`open`, `closed`, `half-open`).

use super::json::{array, field, number, parse_text, point2, point3, string};
use crate::floorplan::{Floorplan, Hole, HoleKind, Room, StructureItem, Wall};
use crate::object::DoorState;
use sage_core::{Error, MAX_COORDINATE, Polygon2, Result, ResultExt};
use serde_json::{Value, json};

/// Wall thickness assumed when a wall gives none.
pub const DEFAULT_WALL_THICKNESS: f32 = 0.2;
/// Wall height assumed when a wall gives none.
pub const DEFAULT_WALL_HEIGHT: f32 = 2.8;

fn list<'a>(root: &'a Value, key: &str) -> Result<&'a [Value]> {
    match root.get(key) {
        None | Some(Value::Null) => Ok(&[]),
        Some(v) => array(v, key).map(|a| a.as_slice()),
    }
}

fn each<T>(root: &Value, key: &str, parse: impl Fn(&Value) -> Result<T>) -> Result<Vec<T>> {
    list(root, key)?
        .iter()
        .enumerate()
        .map(|(i, v)| parse(v).within(format!("{key}[{i}]")))
        .collect()
}

fn optional_number(v: &Value, key: &str, default: f32) -> Result<f32> {
    match v.get(key) {
        None | Some(Value::Null) => Ok(default),
        Some(x) => number(x, key),
    }
}

fn parse_room(v: &Value) -> Result<Room> {
    let profile = array(field(v, "profile")?, "profile")?
        .iter()
        .enumerate()
        .map(|(k, p)| point2(p, &format!("profile[{k}]")))
        .collect::<Result<Vec<_>>>()?;
    if profile.len() < 3 {
        return Err(Error::format(
            "profile",
            format!("a room needs at least 3 points, found {}", profile.len()),
        ));
    }
    let room_type = match v.get("room_type") {
        Some(t) if !t.is_null() => string(t, "room_type")?,
        _ => "Room".to_string(),
    };
    Ok(Room {
        profile: Polygon2::new(profile),
        room_type,
    })
}

fn parse_wall(v: &Value) -> Result<Wall> {
    let loc = array(field(v, "location")?, "location")?;
    if loc.len() != 2 {
        return Err(Error::format(
            "location",
            format!("expected 2 end points, found {}", loc.len()),
        ));
    }
    let thickness = optional_number(v, "thickness", DEFAULT_WALL_THICKNESS)?;
    let height = optional_number(v, "height", DEFAULT_WALL_HEIGHT)?;
    if thickness < 0.0 || height < 0.0 {
        return Err(Error::format("thickness/height", "must not be negative"));
    }
    // Bounded like coordinates: a wall is part of the scene's extent.
    if thickness.max(height) > MAX_COORDINATE {
        return Err(Error::format(
            "thickness/height",
            format!("{thickness} / {height} m: beyond {MAX_COORDINATE} m"),
        ));
    }
    Ok(Wall {
        start: point2(&loc[0], "location[0]")?,
        end: point2(&loc[1], "location[1]")?,
        thickness,
        height,
    })
}

fn parse_hole(v: &Value) -> Result<Hole> {
    let profile = array(field(v, "profile")?, "profile")?
        .iter()
        .enumerate()
        .map(|(k, p)| point3(p, &format!("profile[{k}]")))
        .collect::<Result<Vec<_>>>()?;
    if profile.len() < 3 {
        return Err(Error::format(
            "profile",
            format!("a hole needs at least 3 points, found {}", profile.len()),
        ));
    }
    let kind = match string(field(v, "type")?, "type")?
        .to_ascii_uppercase()
        .as_str()
    {
        "DOOR" => HoleKind::Door,
        "WINDOW" => HoleKind::Window,
        other => {
            return Err(Error::format(
                "type",
                format!("expected DOOR or WINDOW, found '{other}'"),
            ));
        }
    };
    let state = match v.get("state") {
        None | Some(Value::Null) => None,
        Some(s) => {
            let s = string(s, "state")?;
            Some(DoorState::parse(&s).ok_or_else(|| {
                Error::format(
                    "state",
                    format!("expected open, closed or half-open, found '{s}'"),
                )
            })?)
        }
    };
    // Bounded as a wall's thickness is: the hole is cut through its wall, and its thickness
    // sizes the door leaf's body.
    let thickness = optional_number(v, "thickness", 0.0)?;
    if thickness < 0.0 {
        return Err(Error::format(
            "thickness",
            format!("{thickness} m: must not be negative"),
        ));
    }
    if thickness > MAX_COORDINATE {
        return Err(Error::format(
            "thickness",
            format!("{thickness} m: beyond {MAX_COORDINATE} m"),
        ));
    }
    Ok(Hole {
        profile,
        thickness,
        kind,
        state,
    })
}

fn parse_item(v: &Value) -> Result<StructureItem> {
    Ok(StructureItem {
        label: string(field(v, "label")?, "label")?,
        position: point3(field(v, "position")?, "position")?,
        size: point3(field(v, "size")?, "size")?,
    })
}

/// Parses `structure.json`.
pub fn parse(text: &str) -> Result<Floorplan> {
    let root = parse_text(text)?;
    if !root.is_object() {
        return Err(Error::format(
            "(top level)",
            "expected an object with rooms, walls, holes, ins",
        ));
    }
    Ok(Floorplan {
        rooms: each(&root, "rooms", parse_room)?,
        walls: each(&root, "walls", parse_wall)?,
        holes: each(&root, "holes", parse_hole)?,
        items: each(&root, "ins", parse_item)?,
        ceiling: None,
    })
}

/// The floorplan as `structure.json`.
pub fn to_json(f: &Floorplan) -> Value {
    let rooms: Vec<Value> = f
        .rooms
        .iter()
        .map(|r| json!({"profile": r.profile.points.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>(), "room_type": r.room_type}))
        .collect();
    let walls: Vec<Value> = f
        .walls
        .iter()
        .map(|w| json!({"location": [[w.start.x, w.start.y], [w.end.x, w.end.y]], "thickness": w.thickness, "height": w.height}))
        .collect();
    let holes: Vec<Value> = f
        .holes
        .iter()
        .map(|h| {
            let mut v = json!({
                "profile": h.profile.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
                "thickness": h.thickness,
                "type": match h.kind { HoleKind::Door => "DOOR", HoleKind::Window => "WINDOW" },
            });
            if let Some(s) = h.state {
                v["state"] = json!(s.as_str());
            }
            v
        })
        .collect();
    let items: Vec<Value> = f
        .items
        .iter()
        .map(|i| json!({"label": i.label, "position": i.position.to_array(), "size": i.size.to_array()}))
        .collect();
    json!({"rooms": rooms, "walls": walls, "holes": holes, "ins": items})
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = r#"{
        "rooms": [{"profile": [[0,0],[4,0],[4,3],[0,3]], "room_type": "Living Room"}],
        "walls": [{"location": [[0,0],[4,0]], "thickness": 0.2, "height": 2.8},
                  {"location": [[4,0],[4,3]]}],
        "holes": [{"profile": [[1,0,0],[2,0,0],[2,0,2],[1,0,2]], "thickness": 0.2, "type": "DOOR", "state": "half-open"},
                  {"profile": [[3,0,1],[3.5,0,1],[3.5,0,2]], "thickness": 0.2, "type": "WINDOW"}],
        "ins": [{"label": "beam", "position": [1,1,2.7], "size": [4,0.2,0.2]}],
        "extra_unknown_key": 1
    }"#;

    #[test]
    fn parses_and_round_trips() {
        let f = parse(SAMPLE).unwrap();
        assert_eq!(f.rooms[0].room_type, "Living Room");
        assert_eq!(f.walls[1].thickness, DEFAULT_WALL_THICKNESS);
        assert_eq!(f.holes[0].state, Some(DoorState::HalfOpen));
        assert_eq!(f.holes[1].kind, HoleKind::Window);
        assert_eq!(parse(&to_json(&f).to_string()).unwrap(), f);
    }

    #[test]
    fn errors_name_the_field() {
        let e = parse(r#"{"walls":[{"location":[[0,0]]}]}"#).unwrap_err();
        assert_eq!(
            e.to_string(),
            "walls[0].location: expected 2 end points, found 1"
        );
        let e = parse(r#"{"holes":[{"profile":[[0,0,0],[1,0,0],[1,0,1]],"type":"ARCH"}]}"#)
            .unwrap_err();
        assert!(
            e.to_string()
                .starts_with("holes[0].type: expected DOOR or WINDOW")
        );
        let e = parse(r#"{"rooms":[{"profile":[[0,0],[1,-1e7],[1,1]]}]}"#).unwrap_err();
        assert_eq!(
            e.to_string(),
            "rooms[0].profile[1][1]: -10000000.0 is beyond ±10000 m (coordinates are metres)"
        );
        let e = parse(r#"{"walls":[{"location":[[0,0],[1,0]],"height":1e9}]}"#).unwrap_err();
        assert!(
            e.to_string().starts_with("walls[0].thickness/height: "),
            "{e}"
        );
        // A hole's thickness is held to a wall's rules, its index and field named.
        let hole = |t: &str| {
            format!(
                r#"{{"holes":[{{"profile":[[0,0,0],[1,0,0],[1,0,1]],"type":"DOOR"}},
                   {{"profile":[[0,0,0],[1,0,0],[1,0,1]],"type":"DOOR","thickness":{t}}}]}}"#
            )
        };
        let e = parse(&hole("-0.1")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "holes[1].thickness: -0.1 m: must not be negative"
        );
        let e = parse(&hole("1e9")).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("holes[1].thickness: 1000000000 m: beyond 10000 m"),
            "{e}"
        );
        // Finite in the file's double precision, beyond single precision: said as such.
        let e = parse(&hole("1e300")).unwrap_err();
        assert!(
            e.to_string().starts_with(
                "holes[1].thickness: 1e+300 is out of the single-precision (f32) range"
            ),
            "{e}"
        );
        assert_eq!(parse(&hole("0.3")).unwrap().holes[1].thickness, 0.3);
        let e = parse(r#"{"rooms":[{"profile":[[0,0],[1,"x"],[1,1]]}]}"#).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("rooms[0].profile[1][1]: expected a finite number"),
            "{e}"
        );
    }
}
