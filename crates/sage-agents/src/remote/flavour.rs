//! Server flavours: what each model server published with SAGE-3D needs from a client beyond
//! the socket framing (`?server=navila|navid|mllm`, `docs/evaluation.md`).
//!
//! The published servers read requests differently: NaVILA's prompt holds exactly 8 image
//! tokens, so a request with fewer frames fails inside the model; NaVid keeps the frame history
//! itself, one per server process, appending the last image of each request, and forgets it
//! only on `{"action": "reset"}`; the MLLM server shows the model the first image of a request
//! only. A flavour arranges the frames, opens each episode and checks each reply so that the
//! model sees what the agent sees now and nothing a server invents is scored as the model's
//! choice.

use super::parse::ReplyFault;
use sage_core::{Error, Result};
use sage_env::agents::FaultKind;
use serde_json::Value;
use std::fmt;
use std::str::FromStr;

/// The model server a remote agent talks to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Server {
    /// Any server of the SAGE-3D protocol: the last `history` frames, current last.
    #[default]
    Generic,
    /// The published NaVILA server: exactly `history` (8) frames per request, padded at the
    /// front with copies of the oldest frame; a bare "turn left" is 30°; replies carried out in
    /// full.
    Navila,
    /// The published NaVid server: a reset per episode, the current frame only (the server
    /// keeps the history), one episode at a time; velocity replies.
    Navid,
    /// The published MLLM server (Qwen2.5-VL, LLaVA, InternVL): the current frame first, as
    /// the server reads the first image only; a bare turn is 30°.
    Mllm,
}

/// The flavour names as `?server=` takes them.
const NAMES: &str = "generic, navila, navid, mllm";

impl Server {
    /// The flavour's name as `?server=` writes it.
    pub fn as_str(self) -> &'static str {
        match self {
            Server::Generic => "generic",
            Server::Navila => "navila",
            Server::Navid => "navid",
            Server::Mllm => "mllm",
        }
    }

    /// Frames per request unless `history` says otherwise: 8 for NaVILA (its prompt) and the
    /// generic server, 1 for NaVid (it keeps its own history) and the MLLM server (it reads one).
    pub fn default_history(self) -> usize {
        match self {
            Server::Generic | Server::Navila => 8,
            Server::Navid | Server::Mllm => 1,
        }
    }

    /// The most actions queued from one reply unless `repeat` says otherwise: NaVILA's replies
    /// are carried out in full ("move forward 100 cm" is four 0.25 m steps); the others keep
    /// NaVid's cap of 3.
    pub fn default_repeat(self) -> Option<usize> {
        match self {
            Server::Navila => None,
            _ => Some(3),
        }
    }

    /// The angle of a turn named without one ("turn left"): 30° for NaVILA and the MLLMs, as
    /// the published client reads it; one turn step for the others.
    pub fn bare_turn_deg(self) -> Option<f32> {
        match self {
            Server::Navila | Server::Mllm => Some(30.0),
            Server::Generic | Server::Navid => None,
        }
    }

    /// True when the server holds one episode's state for all its clients, so episodes that
    /// use it must run one at a time (NaVid).
    pub fn serial(self) -> bool {
        self == Server::Navid
    }

    /// The message that opens an episode on the server (NaVid's reset), if any.
    pub fn episode_start(self) -> Option<Value> {
        (self == Server::Navid).then(|| serde_json::json!({"action": "reset"}))
    }

    /// The frames of one request from the episode's kept frames (`kept`, oldest first, current
    /// last) and the number the request should carry.
    pub fn arrange(self, kept: Vec<String>, history: usize) -> Vec<String> {
        match self {
            Server::Generic | Server::Navid => kept,
            Server::Navila => {
                let mut frames = kept;
                if let Some(oldest) = frames.first().cloned() {
                    let missing = history.saturating_sub(frames.len());
                    frames.splice(0..0, std::iter::repeat_n(oldest, missing));
                }
                frames
            }
            Server::Mllm => kept.into_iter().rev().collect(),
        }
    }

    /// Checks a reply for what the flavour's server does behind the model's back: NaVid
    /// replaces a model output it cannot read by a random action, and says so only by the
    /// text it sends along (`raw_response`).
    ///
    /// # Errors
    ///
    /// The fault's kind and message when the reply is not the model's own decision.
    pub fn check(self, reply: &Value) -> std::result::Result<(), ReplyFault> {
        if self != Server::Navid {
            return Ok(());
        }
        let text = ["raw_response", "text_response"]
            .iter()
            .find_map(|k| reply.get(*k).and_then(Value::as_str));
        match text {
            Some(t) if t.trim() != "Pending action" && navid_reading(t).is_none() => Err((
                FaultKind::Substituted,
                format!(
                    "the server could not read the model's output as an action and chose one at random: {}",
                    t.chars().take(120).collect::<String>()
                ),
            )),
            _ => Ok(()),
        }
    }
}

/// How many actions the published NaVid server makes of a model output (None: it cannot read
/// one and picks at random): "stop" anywhere is STOP; "forward" is ⌊n / 25⌋ steps and "left" /
/// "right" ⌊n / 30⌋ turns, at most 3, with n the first integer of the text (50 and 30 when
/// there is none); zero steps is unreadable too.
fn navid_reading(text: &str) -> Option<usize> {
    let lower = text.to_lowercase();
    let first_integer = || -> Option<f64> {
        let bytes = lower.as_bytes();
        let start = bytes.iter().position(u8::is_ascii_digit)?;
        let end = bytes[start..]
            .iter()
            .position(|b| !b.is_ascii_digit())
            .map_or(bytes.len(), |n| start + n);
        let negative = start > 0 && bytes[start - 1] == b'-';
        let n: f64 = lower[start..end].parse().ok()?;
        Some(if negative { -n } else { n })
    };
    let count = |per: f64, default: f64| {
        let n = first_integer().unwrap_or(default);
        let steps = (n / per).trunc().min(3.0);
        (steps >= 1.0).then_some(steps as usize)
    };
    if lower.contains("stop") {
        Some(1)
    } else if lower.contains("forward") {
        count(25.0, 50.0)
    } else if lower.contains("left") || lower.contains("right") {
        count(30.0, 30.0)
    } else {
        None
    }
}

impl fmt::Display for Server {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Server {
    type Err = Error;

    fn from_str(s: &str) -> Result<Server> {
        match s.trim().to_ascii_lowercase().as_str() {
            "generic" => Ok(Server::Generic),
            "navila" => Ok(Server::Navila),
            "navid" => Ok(Server::Navid),
            "mllm" => Ok(Server::Mllm),
            other => Err(Error::invalid(format!(
                "unknown server '{other}' (expected one of: {NAMES})"
            ))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn frames(names: &[&str]) -> Vec<String> {
        names.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn navila_pads_at_the_front_with_the_oldest_frame_and_mllm_puts_the_current_first() {
        assert_eq!(Server::Navila.arrange(frames(&["a"]), 8), frames(&["a"; 8]));
        assert_eq!(
            Server::Navila.arrange(frames(&["a", "b", "c"]), 5),
            frames(&["a", "a", "a", "b", "c"])
        );
        let eight = frames(&["a", "b", "c", "d", "e", "f", "g", "h"]);
        assert_eq!(Server::Navila.arrange(eight.clone(), 8), eight);
        assert_eq!(
            Server::Mllm.arrange(frames(&["a", "b", "c"]), 3),
            frames(&["c", "b", "a"])
        );
        assert_eq!(
            Server::Generic.arrange(frames(&["a", "b"]), 8),
            frames(&["a", "b"])
        );
    }

    #[test]
    fn navid_substitutions_are_found_by_the_servers_own_reading_rule() {
        for (text, steps) in [
            ("move forward 75 cm", Some(3)),
            ("Move forward 100 cm", Some(3)),
            ("move forward", Some(2)),
            ("move forward 20 cm", None),
            ("turn left 30 degrees", Some(1)),
            ("turn right 90 degrees", Some(3)),
            ("turn left 15 degrees", None),
            ("turn left -30 degrees", None),
            ("I will stop here", Some(1)),
            ("I am not sure", None),
            ("", None),
        ] {
            assert_eq!(navid_reading(text), steps, "{text}");
        }
        let reply = |raw: &str| json!({"vx": 0.25, "yaw_rate": 0.0, "raw_response": raw});
        assert!(Server::Navid.check(&reply("move forward 75 cm")).is_ok());
        assert!(Server::Navid.check(&reply("Pending action")).is_ok());
        let (kind, why) = Server::Navid.check(&reply("I am not sure")).unwrap_err();
        assert_eq!(kind, FaultKind::Substituted);
        assert!(why.contains("I am not sure"), "{why}");
        // Other flavours do not second-guess the reply.
        assert!(Server::Mllm.check(&reply("I am not sure")).is_ok());
    }

    #[test]
    fn names_round_trip_and_unknown_ones_list_the_valid() {
        for s in [Server::Generic, Server::Navila, Server::Navid, Server::Mllm] {
            assert_eq!(s.as_str().parse::<Server>().unwrap(), s);
        }
        let e = "habitat".parse::<Server>().unwrap_err().to_string();
        assert!(e.contains("navila, navid, mllm"), "{e}");
    }
}
