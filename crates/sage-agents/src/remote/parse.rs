//! The tolerant reply parser: whatever shape a model server answers in, the discrete actions
//! it means, in the environment's step sizes.
//!
//! Replies seen in the wild: free text ("The next action is move forward 75 cm", NaVILA),
//! the MLLM action words (`MOVE_FORWARD`, …), JSON objects carrying the text in `result`,
//! `text_response`, `action` or `text`, a stringified Python dict
//! (`{'status': 'success', 'result': 'MOVE_FORWARD'}`), VLN-CE action indices, sage3d
//! `Action` objects, and velocity commands (`vx`, `yaw_rate`, `duration_s`, `stop`; NaVid).
//! A reply that says the server failed (an error status, `parsed_from: "error"`, a text
//! beginning "Error") is a server fault, one with nothing recognisable an unparseable one;
//! the caller retries both.

use sage_env::Action;
use sage_env::agents::FaultKind;
use serde_json::Value;

/// The environment's discrete step sizes, and how a turn named without an angle is read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Steps {
    /// Forward step, metres.
    pub forward: f32,
    /// Turn step, degrees.
    pub turn_deg: f32,
    /// The angle of "turn left" without a number, degrees (`None`: one turn step).
    pub bare_turn_deg: Option<f32>,
}

/// The most actions one reply is read as. A reply's count comes from the server ("turn left
/// 10²³ degrees", a velocity of 10³⁰⁸ m/s): it is clamped here, before any list is built, to
/// more than an episode takes (500 actions by default) and few enough to cost nothing.
pub const MOST_ACTIONS: usize = 1024;

/// `x` steps, rounded, at least `least` and at most [`MOST_ACTIONS`].
fn step_count(x: f32, least: usize) -> usize {
    (x.round().min(MOST_ACTIONS as f32) as usize).max(least)
}

/// Why a reply gives no action: the kind of fault and its details.
pub type ReplyFault = (FaultKind, String);

/// Fields that may carry the answer, in the order they are tried.
const ANSWER_FIELDS: [&str; 8] = [
    "action",
    "result",
    "text_response",
    "text",
    "response",
    "output",
    "answer",
    "content",
];

/// Words that end the episode.
const STOP_WORDS: [&str; 9] = [
    "stop",
    "halt",
    "finish",
    "finished",
    "done",
    "complete",
    "completed",
    "arrive",
    "arrived",
];

/// Words that mean moving ahead (unless a direction follows: "move left").
const FORWARD_WORDS: [&str; 9] = [
    "forward", "forwards", "ahead", "straight", "move", "go", "walk", "proceed", "advance",
];

/// The actions a reply asks for (at least one, all of them: the caller applies its cap).
///
/// # Errors
///
/// A server fault (the reply says the server failed) or an unparseable reply.
pub fn parse_reply(reply: &Value, steps: &Steps) -> Result<Vec<Action>, ReplyFault> {
    let actions = match reply {
        Value::String(s) => {
            if s.split(|c: char| !c.is_ascii_alphabetic())
                .find(|w| !w.is_empty())
                .is_some_and(|w| w.eq_ignore_ascii_case("error"))
            {
                let short: String = s.trim().chars().take(160).collect();
                return Err((
                    FaultKind::ServerError,
                    format!("the server answered an error: {short}"),
                ));
            }
            parse_text(s, steps)
        }
        Value::Number(n) => n.as_u64().and_then(index_action).map(|a| vec![a]),
        Value::Array(items) => {
            // Every item must parse; the list stops growing at MOST_ACTIONS.
            let mut all = Vec::new();
            items
                .iter()
                .try_for_each(|v| {
                    if all.len() < MOST_ACTIONS {
                        all.extend(parse_reply(v, steps).ok()?);
                    }
                    Some(())
                })
                .map(|()| {
                    all.truncate(MOST_ACTIONS);
                    all
                })
                .filter(|v| !v.is_empty())
        }
        Value::Object(o) => {
            if let Some(status) = o.get("status").and_then(Value::as_str)
                && !matches!(status.to_ascii_lowercase().as_str(), "success" | "ok")
            {
                let why = o
                    .get("error")
                    .or_else(|| o.get("message"))
                    .map(Value::to_string)
                    .unwrap_or_default();
                return Err((
                    FaultKind::ServerError,
                    format!("the server answered status '{status}' {why}")
                        .trim_end()
                        .to_string(),
                ));
            }
            if o.get("parsed_from").and_then(Value::as_str) == Some("error") {
                let why = ["raw_response", "text_response", "message"]
                    .iter()
                    .find_map(|k| o.get(*k).and_then(Value::as_str))
                    .unwrap_or("");
                return Err((
                    FaultKind::ServerError,
                    format!("the server marked its reply as an error: {why}")
                        .trim_end()
                        .to_string(),
                ));
            }
            if o.get("stop").and_then(Value::as_bool) == Some(true) {
                return Ok(vec![Action::Stop]);
            }
            velocity(o, steps)
                .or_else(|| {
                    serde_json::from_value::<Action>(reply.clone())
                        .ok()
                        .and_then(|a| action_object(a, steps))
                })
                .or_else(|| {
                    ANSWER_FIELDS
                        .iter()
                        .filter_map(|k| o.get(*k))
                        .find_map(|v| parse_reply(v, steps).ok())
                })
        }
        Value::Bool(_) | Value::Null => None,
    };
    match actions {
        Some(a) if !a.is_empty() => Ok(a),
        _ => {
            let text = reply.to_string();
            let short: String = text.chars().take(120).collect();
            Err((
                FaultKind::Unparseable,
                format!("unparseable reply: {short}"),
            ))
        }
    }
}

/// VLN-CE's action indices 0–5.
fn index_action(i: u64) -> Option<Action> {
    u8::try_from(i).ok().and_then(Action::from_index)
}

/// A sage3d action object: discrete ones as they are, velocities as the nearest discrete
/// actions.
fn action_object(a: Action, steps: &Steps) -> Option<Vec<Action>> {
    match a {
        Action::Velocity { vx, wz, dt, .. } => Some(nearest(vx * dt, wz * dt, steps)),
        Action::Fly { .. } => None,
        a => Some(vec![a]),
    }
}

/// A velocity reply `{vx, yaw_rate | wz, duration_s | duration | dt}` (rad/s, s; 1 s when
/// absent).
fn velocity(o: &serde_json::Map<String, Value>, steps: &Steps) -> Option<Vec<Action>> {
    let num = |keys: &[&str]| keys.iter().find_map(|k| o.get(*k).and_then(Value::as_f64));
    let vx = num(&["vx"])?;
    let wz = num(&["yaw_rate", "wz", "omega"])?;
    let dt = num(&["duration_s", "duration", "dt"]).unwrap_or(1.0);
    if !(vx.is_finite() && wz.is_finite() && dt.is_finite() && dt >= 0.0) {
        return None;
    }
    Some(nearest((vx * dt) as f32, (wz * dt) as f32, steps))
}

/// The discrete actions nearest to moving `distance` metres and turning `angle` radians:
/// whole turn steps first, then whole forward steps; a command too small for one step gives
/// the single step nearest to it, and no motion at all means STOP.
fn nearest(distance: f32, angle: f32, steps: &Steps) -> Vec<Action> {
    let turn = steps.turn_deg.to_radians().max(1e-6);
    let fwd = steps.forward.max(1e-6);
    let (n_turn, n_fwd) = (
        step_count(angle.abs() / turn, 0),
        step_count(distance.max(0.0) / fwd, 0),
    );
    let side = if angle > 0.0 {
        Action::TurnLeft
    } else {
        Action::TurnRight
    };
    if n_turn + n_fwd == 0 {
        return if distance <= 0.0 && angle == 0.0 {
            vec![Action::Stop]
        } else if angle.abs() / turn > distance.max(0.0) / fwd {
            vec![side]
        } else {
            vec![Action::MoveForward]
        };
    }
    let mut out = vec![side; n_turn];
    out.extend(std::iter::repeat_n(
        Action::MoveForward,
        n_fwd.min(MOST_ACTIONS - n_turn),
    ));
    out
}

/// A word or a number of a reply's text.
#[derive(Debug, Clone, PartialEq)]
enum Token {
    Word(String),
    Number(f32),
}

/// Lower-case words (underscores split them: `MOVE_FORWARD` → move, forward), numbers and
/// the degree sign.
fn tokens(text: &str) -> Vec<Token> {
    let mut out = Vec::new();
    let mut chars = text.chars().peekable();
    while let Some(&c) = chars.peek() {
        if c.is_ascii_alphabetic() {
            let mut w = String::new();
            while let Some(&c) = chars.peek().filter(|c| c.is_ascii_alphabetic()) {
                w.push(c.to_ascii_lowercase());
                chars.next();
            }
            out.push(Token::Word(w));
        } else if c.is_ascii_digit() {
            let mut n = String::new();
            while let Some(&c) = chars.peek().filter(|c| c.is_ascii_digit() || **c == '.') {
                n.push(c);
                chars.next();
            }
            // An exponent ("1e30", "2.5E-3") belongs to the number: "1e30 m" is not "30 m".
            let mut ahead = chars.clone();
            if ahead.next().is_some_and(|e| e == 'e' || e == 'E') {
                let sign = ahead.peek().copied().filter(|c| *c == '+' || *c == '-');
                if sign.is_some() {
                    ahead.next();
                }
                if ahead.peek().is_some_and(char::is_ascii_digit) {
                    n.push('e');
                    n.extend(sign);
                    while let Some(d) = ahead.next_if(char::is_ascii_digit) {
                        n.push(d);
                    }
                    chars = ahead;
                }
            }
            if let Ok(v) = n.trim_end_matches('.').parse() {
                out.push(Token::Number(v));
            }
        } else {
            if c == '°' {
                out.push(Token::Word("deg".into()));
            }
            chars.next();
        }
    }
    out
}

/// The first number in `window` followed by one of `units` (its scale applied).
fn amount(window: &[Token], units: &[(&str, f32)]) -> Option<f32> {
    window.windows(2).find_map(|w| match w {
        [Token::Number(v), Token::Word(u)] => units
            .iter()
            .find(|(name, _)| *name == u.as_str())
            .map(|(_, scale)| v * scale),
        _ => None,
    })
}

/// Free text: the first action word decides; a distance ("75 cm", "0.5 m", "2 steps") or
/// angle ("30 degrees", "45°") after it sets how many steps; a bare index 0–5 is VLN-CE's;
/// text holding a JSON object or a Python dict is parsed as that.
pub fn parse_text(text: &str, steps: &Steps) -> Option<Vec<Action>> {
    let t = text.trim();
    if let Ok(i) = t.parse::<u64>() {
        return index_action(i).map(|a| vec![a]);
    }
    if let (Some(a), Some(b)) = (t.find('{'), t.rfind('}'))
        && a < b
        && let Some(v) = dict_value(&t[a..=b])
    {
        // A structured answer is read as such, never scanned for words in its keys.
        return parse_reply(&v, steps).ok();
    }
    let toks = tokens(t);
    let word = |i: usize| match toks.get(i) {
        Some(Token::Word(w)) => w.as_str(),
        _ => "",
    };
    let side_of = |w: &str| match w {
        "left" => Some(Action::TurnLeft),
        "right" => Some(Action::TurnRight),
        _ => None,
    };
    let turn = |at: usize, side: Action| {
        let window = &toks[at..toks.len().min(at + 8)];
        let units = [
            ("degree", 1.0),
            ("degrees", 1.0),
            ("deg", 1.0),
            ("degs", 1.0),
        ];
        let turns = |deg: f32| step_count(deg / steps.turn_deg.max(1e-6), 1);
        let n = amount(window, &units)
            .or(steps.bare_turn_deg)
            .map_or(1, turns);
        Some(vec![side; n])
    };
    for i in 0..toks.len() {
        let w = word(i);
        if STOP_WORDS.contains(&w) {
            return Some(vec![Action::Stop]);
        }
        if let Some(side) = side_of(w) {
            return turn(i, side);
        }
        if w == "turn" || w == "rotate" {
            let side = (i + 1..toks.len().min(i + 6)).find_map(|j| side_of(word(j)));
            if let Some(side) = side {
                return turn(i, side);
            }
            continue;
        }
        if FORWARD_WORDS.contains(&w) {
            if let Some(side) = side_of(word(i + 1)) {
                return turn(i + 1, side);
            }
            let window = &toks[i..toks.len().min(i + 8)];
            let units = [
                ("m", 1.0),
                ("meter", 1.0),
                ("meters", 1.0),
                ("metre", 1.0),
                ("metres", 1.0),
                ("cm", 0.01),
                ("centimeter", 0.01),
                ("centimeters", 0.01),
                ("centimetre", 0.01),
                ("centimetres", 0.01),
                ("step", steps.forward),
                ("steps", steps.forward),
            ];
            let n =
                amount(window, &units).map_or(1, |d| step_count(d / steps.forward.max(1e-6), 1));
            return Some(vec![Action::MoveForward; n]);
        }
    }
    None
}

/// A JSON object, or a Python dict literal as `str(dict)` writes it (single quotes,
/// `True`/`False`/`None`).
pub(crate) fn dict_value(text: &str) -> Option<Value> {
    if let Ok(v) = serde_json::from_str(text) {
        return Some(v);
    }
    let mut json = String::with_capacity(text.len());
    let mut quote: Option<char> = None;
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match (quote, c) {
            (Some(_), '\\') => match chars.next() {
                Some('\'') => json.push('\''),
                Some(n) => {
                    json.push('\\');
                    json.push(n);
                }
                None => {}
            },
            (Some(q), c) if c == q => {
                json.push('"');
                quote = None;
            }
            (Some(_), '"') => json.push_str("\\\""),
            (Some(_), c) => json.push(c),
            (None, '\'' | '"') => {
                json.push('"');
                quote = Some(c);
            }
            (None, c) if c.is_ascii_alphabetic() => {
                let mut w = String::from(c);
                while let Some(&n) = chars.peek().filter(|n| n.is_ascii_alphanumeric()) {
                    w.push(n);
                    chars.next();
                }
                json.push_str(match w.as_str() {
                    "True" => "true",
                    "False" => "false",
                    "None" => "null",
                    other => other,
                });
            }
            (None, c) => json.push(c),
        }
    }
    serde_json::from_str(&json).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use sage_env::Action::{MoveForward as F, Stop as S, TurnLeft as L, TurnRight as R};
    use serde_json::json;

    const STEPS: Steps = Steps {
        forward: 0.25,
        turn_deg: 15.0,
        bare_turn_deg: None,
    };

    fn text(s: &str) -> Result<Vec<Action>, ReplyFault> {
        parse_reply(&Value::String(s.into()), &STEPS)
    }

    #[test]
    fn free_text_with_distances_and_angles() {
        assert_eq!(
            text("The next action is move forward 75 cm.").unwrap(),
            [F, F, F]
        );
        assert_eq!(text("move forward 0.5 m").unwrap(), [F, F]);
        assert_eq!(text("Go straight ahead 2 steps").unwrap(), [F, F]);
        // Every step a reply asks for (the agent applies its cap and notes the cut).
        assert_eq!(text("move forward 10 meters").unwrap(), vec![F; 40]);
        assert_eq!(text("Move forward").unwrap(), [F]);
        assert_eq!(
            text("The next action is turn left 30 degrees").unwrap(),
            [L, L]
        );
        assert_eq!(text("turn 45° to the right").unwrap(), [R, R, R]);
        assert_eq!(text("turn right 15deg").unwrap(), [R]);
        assert_eq!(text("go left").unwrap(), [L]);
        assert_eq!(text("The next action is stop.").unwrap(), [S]);
        assert_eq!(text("I have arrived, halting").unwrap(), [S]);
        // The first action word decides.
        assert_eq!(
            text("turn left 15 degrees, then move forward 1 m").unwrap(),
            [L]
        );
        assert_eq!(text("Move forward 25 cm and then stop").unwrap(), [F]);
    }

    #[test]
    fn counts_a_reply_asks_for_are_clamped_before_any_list_is_built() {
        // Each of these once built its whole list (10²³ turns: a capacity overflow, a panic).
        for reply in [
            json!("turn left 1e23 degrees"),
            json!("move forward 1e23 cm"),
            json!("turn right 100000000000 degrees"),
            json!({"vx": 1e308, "yaw_rate": 0, "duration_s": 1}),
            json!({"vx": 0, "yaw_rate": -1e308, "duration_s": 1}),
            json!({"vx": 1e308, "yaw_rate": 1e308, "duration_s": 1}),
            json!(vec!["move forward 1e23 m"; 1000]),
            json!(vec![1; 100_000]),
        ] {
            let got = parse_reply(&reply, &STEPS).unwrap();
            assert_eq!(got.len(), MOST_ACTIONS, "{reply}");
        }
        // An exponent belongs to its number.
        assert_eq!(text("move forward 1e30 m").unwrap().len(), MOST_ACTIONS);
        assert_eq!(text("move forward 2.5e-1 m").unwrap(), [F]);
        assert_eq!(text("move forward 1E2 cm").unwrap(), [F, F, F, F]);
        assert_eq!(text("turn left 3e1 degrees").unwrap(), [L, L]);
        // A letter e after a number that is no exponent is a word.
        assert_eq!(text("move forward 2 each").unwrap(), [F]);
    }

    #[test]
    fn mllm_tokens_indices_and_dicts() {
        assert_eq!(text("MOVE_FORWARD").unwrap(), [F]);
        assert_eq!(text(" TURN_LEFT\n").unwrap(), [L]);
        assert_eq!(text("Answer: TURN_RIGHT").unwrap(), [R]);
        assert_eq!(text("STOP").unwrap(), [S]);
        assert_eq!(text("2").unwrap(), [L]);
        assert_eq!(parse_reply(&json!(0), &STEPS).unwrap(), [S]);
        assert_eq!(parse_reply(&json!([1, 3]), &STEPS).unwrap(), [F, R]);
        let py = "{'status': 'success', 'result': 'MOVE_FORWARD', 'inference_time': 0.41, 'ok': True, 'extra': None}";
        assert_eq!(text(py).unwrap(), [F]);
        assert_eq!(text("{'result': \"it's TURN_LEFT\"}").unwrap(), [L]);
        assert_eq!(
            text("```json\n{\"action\": \"TURN_RIGHT\"}\n```").unwrap(),
            [R]
        );
    }

    #[test]
    fn json_objects_and_velocities() {
        for (reply, want) in [
            (
                json!({"result": "The next action is move forward 50 cm"}),
                vec![F, F],
            ),
            (
                json!({"text_response": "turn right 30 degrees"}),
                vec![R, R],
            ),
            (json!({"action": "move_forward"}), vec![F]),
            (json!({"action": 3}), vec![R]),
            (json!({"text": "stop"}), vec![S]),
            (json!({"type": "turn_left"}), vec![L]),
            (
                json!({"type": "velocity", "vx": 0.5, "vy": 0.0, "wz": 0.0, "dt": 1.0}),
                vec![F, F],
            ),
            // NaVid: the velocity fields are this step's action, whatever the text says.
            (
                json!({"vx": 0.25, "yaw_rate": 0.0, "duration": 1.0, "text_response": "Pending action"}),
                vec![F],
            ),
            (
                json!({"vx": 0.0, "yaw_rate": 0.5, "duration": 1.0}),
                vec![L, L],
            ),
            (
                json!({"vx": 0.0, "yaw_rate": -0.1, "duration": 1.0}),
                vec![R],
            ),
            (json!({"vx": 0.0, "yaw_rate": 0.0}), vec![S]),
            (
                json!({"vx": 0.3, "yaw_rate": 0.2618, "duration": 1.0}),
                vec![L, F],
            ),
        ] {
            assert_eq!(parse_reply(&reply, &STEPS).unwrap(), want, "{reply}");
        }
    }

    #[test]
    fn garbage_and_error_statuses_are_faults() {
        for reply in [
            json!("I am not sure what to do."),
            json!(""),
            json!(9),
            json!(null),
            json!({"foo": "bar"}),
            json!([]),
            json!("{'result': 'no idea'}"),
        ] {
            let (kind, e) = parse_reply(&reply, &STEPS).unwrap_err();
            assert_eq!(kind, FaultKind::Unparseable, "{reply}");
            assert!(e.starts_with("unparseable reply"), "{reply}: {e}");
        }
        let (kind, e) = parse_reply(
            &json!({"status": "error", "error": "CUDA out of memory"}),
            &STEPS,
        )
        .unwrap_err();
        assert_eq!(kind, FaultKind::ServerError);
        assert!(
            e.contains("'error'") && e.contains("CUDA out of memory"),
            "{e}"
        );
    }

    #[test]
    fn replies_that_say_the_server_failed_are_server_faults_never_actions() {
        for (reply, says) in [
            // The MLLM server's failure reply still names an action.
            (
                json!({"status": "error", "message": "VLN query failed: boom", "result": "MOVE_FORWARD"}),
                "VLN query failed: boom",
            ),
            // NaVid's exception reply asks for STOP and reports success.
            (
                json!({"vx": 0.0, "vy": 0.0, "yaw_rate": 0.0, "duration_s": 0.0, "stop": true,
                       "raw_response": "Error: boom", "parsed_from": "error", "status": "success"}),
                "Error: boom",
            ),
            // NaVILA's reply when the model raised.
            (
                json!("Error processing request: list index out of range"),
                "list index out of range",
            ),
            (json!("error: move forward"), "error: move forward"),
        ] {
            let (kind, why) = parse_reply(&reply, &STEPS).unwrap_err();
            assert_eq!(kind, FaultKind::ServerError, "{reply}");
            assert!(why.contains(says), "{reply}: {why}");
        }
        // A word that merely starts like it is no error.
        assert_eq!(text("Errorless: move forward").unwrap(), [F]);
    }

    #[test]
    fn navid_velocity_replies_read_duration_s_and_stop() {
        let navid = |vx: f64, yaw: f64, dur: f64, stop: bool| {
            json!({"vx": vx, "vy": 0.0, "yaw_rate": yaw, "duration_s": dur, "stop": stop,
                   "raw_response": "move forward 75 cm", "parsed_from": "navid", "status": "success"})
        };
        let thirty = 30f64.to_radians();
        assert_eq!(
            parse_reply(&navid(0.25, 0.0, 1.0, false), &STEPS).unwrap(),
            [F]
        );
        assert_eq!(
            parse_reply(&navid(0.25, 0.0, 2.0, false), &STEPS).unwrap(),
            [F, F]
        );
        assert_eq!(
            parse_reply(&navid(0.0, thirty, 1.0, false), &STEPS).unwrap(),
            [L, L]
        );
        assert_eq!(
            parse_reply(&navid(0.0, -thirty, 1.0, false), &STEPS).unwrap(),
            [R, R]
        );
        assert_eq!(
            parse_reply(&navid(0.0, 0.0, 0.0, true), &STEPS).unwrap(),
            [S]
        );
        // `stop` wins over any velocity sent with it.
        assert_eq!(
            parse_reply(&navid(0.25, 0.0, 1.0, true), &STEPS).unwrap(),
            [S]
        );
    }

    #[test]
    fn a_bare_turn_is_the_flavours_angle() {
        let thirty = Steps {
            bare_turn_deg: Some(30.0),
            ..STEPS
        };
        assert_eq!(parse_reply(&json!("turn left"), &thirty).unwrap(), [L, L]);
        assert_eq!(parse_reply(&json!("TURN_RIGHT"), &thirty).unwrap(), [R, R]);
        assert_eq!(
            parse_reply(&json!("turn left 15 degrees"), &thirty).unwrap(),
            [L]
        );
        assert_eq!(text("turn left").unwrap(), [L]);
    }
}
