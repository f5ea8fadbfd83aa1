//! `ws:HOST:PORT`: a GN0 / openpi WebSocket policy server as the agent (GN0's remote-policy
//! protocol, `docs/evaluation.md`).
//!
//! Per episode the agent opens a connection ([`super::ws`]), takes the server's metadata if it
//! sends any, and sends `{"endpoint": "reset"}`. When its queue of actions is empty it sends
//! `{"endpoint": "infer", "images", "instruction", "session_id"}` (plus `"state.nav_pose"`,
//! float32 `[x, y, yaw]` in the W frame, with `state=1`): `images` is the current frame as a
//! uint8 HWC array on the session's first query, and after that the frames observed since the
//! previous query as THWC (one per executed action, the current one last, at most
//! `history_cap`). The reply's actions ([`parse_reply`]) are discrete codes (0 STOP, 1 FORWARD,
//! 2 LEFT, 3 RIGHT, 4 LOOK_UP, 5 LOOK_DOWN) or `nav_delta` rows `[dx, dy, dyaw]`; the first
//! `actions` of them are queued and carried out one per step, a row as one
//! [`Action::Displace`] through physics ([`row_action`]).
//!
//! A fault (see [`super::ws`]; a reply without a usable action is
//! [`FaultKind::Unparseable`], one carrying an `error` [`FaultKind::ServerError`]) drops the
//! connection; the retry opens a new one, sends `reset` again and queries with the current
//! frame as HWC, as at the session's start (the server's history of the session is gone).

use super::msgpack_numpy::{self, Item, NdArray, Numbers};
use super::parse::ReplyFault;
use super::ws::WsConnection;
use super::{RemoteSpec, check_env, with_retries};
use sage_core::{Error, Result};
use sage_env::agents::{Agent, Fault, FaultKind};
use sage_env::{Action, Env, EnvEpisode, Observation};
use std::collections::VecDeque;
use std::fmt;
use std::str::FromStr;
use std::time::Duration;

/// Reply keys that may hold the actions, in the order they are tried (GN0's).
pub const ACTION_KEYS: [&str; 5] = [
    "actions",
    "action.nav_delta",
    "action.discrete",
    "action.vlnce",
    "action",
];

/// Reply keys that may declare the actions' type, in the order they are tried.
const TYPE_KEYS: [&str; 3] = ["action_type", "action.type", "action_format"];

/// A `nav_delta` row with every component within this is STOP (GN0's threshold, compared in
/// float32 as NumPy compares a float32 row with it).
pub const STOP_EPSILON: f32 = 1e-3;

/// How a reply's actions are read (`format`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ActionFormat {
    /// The type the reply declares, else by the values: integers or a scalar are discrete
    /// codes, floats with a last dimension ≥ 3 are `nav_delta` rows.
    Auto,
    /// Discrete codes whatever the reply says.
    Discrete,
    /// `nav_delta` rows whatever the reply says.
    NavDelta,
}

/// Which heading turns a `nav_delta` row's `(dx, dy)` into the world (`rotate`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rotate {
    /// The heading when the server was queried: the rows of one reply are a path drawn from
    /// that pose (GN0's default).
    ChunkStart,
    /// The heading when the row is carried out: each row is relative to the agent.
    Current,
}

/// The options of a `ws:` agent beyond `timeout` and `retries`.
#[derive(Debug, Clone, PartialEq)]
pub struct PolicyOptions {
    /// Most actions carried out per reply (`actions`; 8, GN0's `action_num`).
    pub actions: usize,
    /// Send `state.nav_pose` (`state`; off).
    pub state: bool,
    /// How replies are read (`format`; auto).
    pub format: ActionFormat,
    /// The heading of `nav_delta` rows (`rotate`; chunk_start).
    pub rotate: Rotate,
    /// Most frames per query (`history_cap`; `None`: max(64, 4 · actions), as GN0).
    pub history_cap: Option<usize>,
    /// Seconds to wait for the server's metadata on connect (`metadata`; 2, as GN0).
    pub metadata_s: f64,
}

impl Default for PolicyOptions {
    fn default() -> PolicyOptions {
        PolicyOptions {
            actions: 8,
            state: false,
            format: ActionFormat::Auto,
            rotate: Rotate::ChunkStart,
            history_cap: None,
            metadata_s: 2.0,
        }
    }
}

impl PolicyOptions {
    /// The option names, in canonical order.
    pub const KEYS: [&str; 6] = [
        "actions",
        "state",
        "format",
        "rotate",
        "history_cap",
        "metadata",
    ];

    /// Most frames sent in one query.
    pub fn cap(&self) -> usize {
        self.history_cap.unwrap_or((4 * self.actions).max(64))
    }

    /// The value of option `key` as written in the canonical string.
    pub(crate) fn value(&self, key: &str) -> String {
        match key {
            "actions" => self.actions.to_string(),
            "state" => u8::from(self.state).to_string(),
            "format" => self.format.to_string(),
            "rotate" => self.rotate.to_string(),
            "history_cap" => self
                .history_cap
                .map_or_else(|| "auto".into(), |n| n.to_string()),
            _ => self.metadata_s.to_string(),
        }
    }

    /// Sets option `key` from its text, checking its range.
    pub(crate) fn set(&mut self, key: &str, v: &str) -> Result<()> {
        let bad = |want: &str| Error::invalid(format!("option {key}={v}: expected {want}"));
        let count = || {
            v.parse::<usize>()
                .ok()
                .filter(|n| (1..=4096).contains(n))
                .ok_or_else(|| bad("an integer in 1..=4096"))
        };
        match key {
            "actions" => self.actions = count()?,
            "state" => {
                self.state = match v.to_ascii_lowercase().as_str() {
                    "1" | "true" | "on" | "yes" => true,
                    "0" | "false" | "off" | "no" => false,
                    _ => return Err(bad("1 or 0")),
                }
            }
            "format" => self.format = v.parse()?,
            "rotate" => self.rotate = v.parse()?,
            "history_cap" if v.eq_ignore_ascii_case("auto") => self.history_cap = None,
            "history_cap" => self.history_cap = Some(count()?),
            _ => {
                self.metadata_s = v
                    .parse::<f64>()
                    .ok()
                    .filter(|t| t.is_finite() && (0.0..=600.0).contains(t))
                    .ok_or_else(|| bad("seconds in 0..=600"))?;
            }
        }
        Ok(())
    }
}

impl fmt::Display for ActionFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ActionFormat::Auto => "auto",
            ActionFormat::Discrete => "discrete",
            ActionFormat::NavDelta => "nav_delta",
        })
    }
}

impl FromStr for ActionFormat {
    type Err = Error;

    fn from_str(s: &str) -> Result<ActionFormat> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Ok(ActionFormat::Auto),
            "discrete" | "vlnce" => Ok(ActionFormat::Discrete),
            "nav_delta" => Ok(ActionFormat::NavDelta),
            _ => Err(Error::invalid(format!(
                "action format '{s}' is not auto, discrete or nav_delta"
            ))),
        }
    }
}

impl fmt::Display for Rotate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Rotate::ChunkStart => "chunk_start",
            Rotate::Current => "current",
        })
    }
}

impl FromStr for Rotate {
    type Err = Error;

    fn from_str(s: &str) -> Result<Rotate> {
        match s.trim().to_ascii_lowercase().as_str() {
            "chunk_start" => Ok(Rotate::ChunkStart),
            "current" => Ok(Rotate::Current),
            _ => Err(Error::invalid(format!(
                "rotate '{s}' is not chunk_start or current"
            ))),
        }
    }
}

/// One action of a reply.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// A discrete action (from its code).
    Code(Action),
    /// A `nav_delta` row `[dx forward m, dy left m, dyaw rad]`.
    Delta([f32; 3]),
}

/// The actions of a reply, all of them (the caller keeps the first `actions`).
///
/// # Errors
///
/// A server error (a reply with an `error` and no actions) or an unparseable reply: no action
/// key, no actions, codes outside 0–5, rows that are not `(N, ≥3)` finite floats, a declared
/// type that is neither `discrete` nor `nav_delta`.
pub fn parse_reply(
    reply: &Item,
    format: ActionFormat,
) -> std::result::Result<Vec<Step>, ReplyFault> {
    let unparseable = |m: String| (FaultKind::Unparseable, m);
    let Item::Map(_) = reply else {
        return Err(unparseable(format!(
            "the reply is {}, expected a map",
            msgpack_numpy::describe(reply)
        )));
    };
    let Some((key, value)) = ACTION_KEYS
        .iter()
        .find_map(|k| reply.get(k).map(|v| (*k, v)))
    else {
        if let Some(error) = reply.get("error") {
            let text = error
                .as_str()
                .map_or_else(|| msgpack_numpy::describe(error), str::to_string);
            return Err((
                FaultKind::ServerError,
                format!("the server answered an error: {text}"),
            ));
        }
        return Err(unparseable(format!(
            "no action key ({}) in {}",
            ACTION_KEYS.join(", "),
            msgpack_numpy::describe(reply)
        )));
    };
    let declared = match format {
        ActionFormat::Auto => match TYPE_KEYS.iter().find_map(|k| reply.get(k)) {
            Some(t) => Some(
                t.as_str()
                    .ok_or_else(|| {
                        unparseable(format!("the action type is {}", msgpack_numpy::describe(t)))
                    })?
                    .parse::<ActionFormat>()
                    .map_err(|e| unparseable(e.message().to_string()))?,
            )
            .filter(|f| *f != ActionFormat::Auto),
            None => match key {
                "action.nav_delta" => Some(ActionFormat::NavDelta),
                "action.discrete" | "action.vlnce" => Some(ActionFormat::Discrete),
                _ => None,
            },
        },
        forced => Some(forced),
    };
    let n = msgpack_numpy::numbers(value).map_err(|e| unparseable(format!("{key}: {e}")))?;
    if n.values.is_empty() {
        return Err(unparseable(format!(
            "{key}: the reply holds no action (shape {:?})",
            n.shape
        )));
    }
    let rows = n.shape.last().is_some_and(|&k| k >= 3);
    let kind = declared.unwrap_or(if n.float && rows {
        ActionFormat::NavDelta
    } else if !n.float || n.shape.is_empty() {
        ActionFormat::Discrete
    } else {
        return Err(unparseable(format!(
            "{key}: floats of shape {:?} are neither discrete codes nor nav_delta rows (N, 3)",
            n.shape
        )));
    });
    match kind {
        ActionFormat::NavDelta => delta_rows(key, &n),
        _ => n
            .values
            .iter()
            .map(|&c| {
                (c.fract() == 0.0 && (0.0..=255.0).contains(&c))
                    .then(|| Action::from_index(c as u8))
                    .flatten()
                    .map(Step::Code)
                    .ok_or_else(|| {
                        unparseable(format!("{key}: {c} is not a discrete action code 0–5"))
                    })
            })
            .collect(),
    }
}

/// The rows of a `nav_delta` array: `(k,)` or `(N, k)` with k ≥ 3 (columns beyond the third
/// are ignored).
fn delta_rows(key: &str, n: &Numbers) -> std::result::Result<Vec<Step>, ReplyFault> {
    let width = match n.shape.as_slice() {
        [k] | [_, k] if *k >= 3 => *k,
        shape => {
            return Err((
                FaultKind::Unparseable,
                format!("{key}: nav_delta rows must have shape (N, 3), got {shape:?}"),
            ));
        }
    };
    if let Some(v) = n.values.iter().find(|v| !v.is_finite()) {
        return Err((
            FaultKind::Unparseable,
            format!("{key}: nav_delta holds {v}"),
        ));
    }
    Ok(n.values
        .chunks_exact(width)
        .map(|r| Step::Delta([r[0] as f32, r[1] as f32, r[2] as f32]))
        .collect())
}

/// The environment action of a reply's step: a code as it is; a `nav_delta` row is STOP when
/// every component is within [`STOP_EPSILON`], else an [`Action::Displace`] whose body-frame
/// `(dx, dy)` is the row's, turned from the heading `chunk_yaw` (the query's) into the current
/// `yaw` with [`Rotate::ChunkStart`], as it is with [`Rotate::Current`].
pub fn row_action(step: Step, rotate: Rotate, chunk_yaw: f32, yaw: f32) -> Action {
    let [dx, dy, dyaw] = match step {
        Step::Code(a) => return a,
        Step::Delta(d) => d,
    };
    if [dx, dy, dyaw].iter().all(|v| v.abs() <= STOP_EPSILON) {
        return Action::Stop;
    }
    let (dx, dy) = match rotate {
        Rotate::Current => (dx, dy),
        Rotate::ChunkStart => {
            let (s, c) = (chunk_yaw - yaw).sin_cos();
            (c * dx - s * dy, s * dx + c * dy)
        }
    };
    Action::Displace { dx, dy, dyaw }
}

/// One observed frame, RGB row-major.
struct Frame {
    rgb: Vec<u8>,
    width: usize,
    height: usize,
}

/// The connection of an episode and where its session stands.
struct Link {
    host: String,
    port: u16,
    timeout: Duration,
    metadata_wait: Duration,
    conn: Option<WsConnection>,
    /// The next query is the first of the session on this connection (HWC, current frame).
    first: bool,
}

impl Link {
    /// The open connection with the episode's session reset on it, opening one (and sending
    /// `reset`) when there is none; `notes` gets the metadata of a new connection.
    fn ready(&mut self, notes: &mut Vec<String>) -> std::result::Result<(), ReplyFault> {
        if self.conn.is_some() {
            return Ok(());
        }
        let mut conn = WsConnection::open(&self.host, self.port, self.timeout, self.metadata_wait)?;
        if let Some(m) = &conn.metadata {
            let text: String = msgpack_numpy::show(m).chars().take(300).collect();
            notes.push(format!("server metadata: {text}"));
        }
        let reset = rmpv::Value::Map(vec![("endpoint".into(), "reset".into())]);
        conn.exchange(&msgpack_numpy::encode(&reset), self.timeout)?;
        self.conn = Some(conn);
        self.first = true;
        Ok(())
    }

    /// One exchange on the ready connection; a fault drops the connection.
    fn ask(
        &mut self,
        notes: &mut Vec<String>,
        request: impl FnOnce(bool) -> rmpv::Value,
    ) -> std::result::Result<Item, ReplyFault> {
        self.ready(notes)?;
        let message = msgpack_numpy::encode(&request(self.first));
        let conn = self.conn.as_mut().expect("ready opened it");
        let reply = conn.exchange(&message, self.timeout);
        if reply.is_err() {
            self.conn = None;
        }
        reply
    }
}

/// The `infer` request of a query: the current frame as an HWC array when `first` (the
/// session's first query on this connection), else the frames since the last query as THWC.
fn infer_request(
    pending: &VecDeque<Frame>,
    first: bool,
    instruction: &str,
    session: &str,
    state: Option<&NdArray>,
) -> rmpv::Value {
    let current = pending.back().expect("the current frame is pending");
    let hwc = vec![current.height, current.width, 3];
    let images = if first {
        NdArray::uint8(hwc, current.rgb.clone())
    } else {
        let mut shape = vec![pending.len()];
        shape.extend(hwc);
        NdArray::uint8(
            shape,
            pending.iter().flat_map(|f| f.rgb.iter().copied()).collect(),
        )
    };
    let mut map = vec![
        ("endpoint".into(), "infer".into()),
        ("images".into(), images.to_value()),
        ("instruction".into(), instruction.into()),
        ("session_id".into(), session.into()),
    ];
    if let Some(state) = state {
        map.push(("state.nav_pose".into(), state.to_value()));
    }
    rmpv::Value::Map(map)
}

/// A GN0 / openpi policy server as the agent (see the module doc).
pub struct PolicyAgent {
    spec: RemoteSpec,
    name: String,
    link: Link,
    /// The episode id, sent as `session_id`.
    session: String,
    instruction: String,
    /// Frames observed since the last query, oldest first.
    pending: VecDeque<Frame>,
    queue: VecDeque<Step>,
    chunk_yaw: f32,
    faults: Vec<Fault>,
    notes: Vec<String>,
}

impl PolicyAgent {
    /// An agent of the `ws:HOST:PORT` server of `spec`.
    ///
    /// # Panics
    ///
    /// `spec` is not a `ws:` spec (a caller's bug).
    pub fn new(spec: RemoteSpec) -> PolicyAgent {
        let super::Protocol::Ws { host, port } = &spec.protocol else {
            panic!("PolicyAgent of a {spec} spec");
        };
        PolicyAgent {
            name: spec.to_string(),
            link: Link {
                host: host.clone(),
                port: *port,
                timeout: spec.options.timeout(),
                metadata_wait: Duration::from_secs_f64(spec.options.policy.metadata_s),
                conn: None,
                first: true,
            },
            spec,
            session: String::new(),
            instruction: String::new(),
            pending: VecDeque::new(),
            queue: VecDeque::new(),
            chunk_yaw: 0.0,
            faults: Vec::new(),
            notes: Vec::new(),
        }
    }
}

impl Agent for PolicyAgent {
    fn name(&self) -> &str {
        &self.name
    }

    fn reset(&mut self, env: &Env, episode: &EnvEpisode) -> Result<()> {
        check_env(env)?;
        self.pending.clear();
        self.queue.clear();
        self.faults.clear();
        self.notes.clear();
        self.instruction = episode.instruction.clone();
        self.session = episode.id.clone();
        self.link.conn = None;
        let (link, notes) = (&mut self.link, &mut self.notes);
        with_retries(
            &self.spec,
            &mut self.faults,
            0,
            "reply to the episode's reset",
            || link.ready(notes),
        )
    }

    fn act(&mut self, obs: &Observation) -> Result<Action> {
        let images = obs.images.as_ref();
        let Some((rgb, width, height)) =
            images.and_then(|i| Some((i.rgb.as_ref()?, i.width, i.height)))
        else {
            return Err(Error::invalid(
                "ws agents need RGB images (the observation has none)",
            ));
        };
        let options = &self.spec.options.policy;
        if self.pending.len() == options.cap() {
            self.pending.pop_front();
        }
        self.pending.push_back(Frame {
            rgb: rgb.clone(),
            width,
            height,
        });
        if self.queue.is_empty() {
            let state = options.state.then(|| {
                let p = obs.pose;
                NdArray::float32(vec![3], &[p.position.x, p.position.y, p.yaw])
            });
            let format = options.format;
            let (pending, instruction) = (&self.pending, self.instruction.as_str());
            let session = self.session.as_str();
            let (link, notes) = (&mut self.link, &mut self.notes);
            let mut steps = with_retries(&self.spec, &mut self.faults, obs.step, "reply", || {
                let reply = link.ask(notes, |first| {
                    infer_request(pending, first, instruction, session, state.as_ref())
                })?;
                // The server has taken the frames; the retry starts the session afresh.
                parse_reply(&reply, format).inspect_err(|_| link.conn = None)
            })?;
            let cap = self.spec.options.policy.actions;
            if steps.len() > cap {
                self.notes.push(format!(
                    "step {}: the reply held {} actions; actions={cap} carried out the first {cap}",
                    obs.step,
                    steps.len()
                ));
                steps.truncate(cap);
            }
            self.pending.clear();
            self.link.first = false;
            self.chunk_yaw = obs.pose.yaw;
            self.queue.extend(steps);
        }
        let step = self.queue.pop_front().expect("a reply holds an action");
        Ok(row_action(
            step,
            self.spec.options.policy.rotate,
            self.chunk_yaw,
            obs.pose.yaw,
        ))
    }

    fn take_faults(&mut self) -> Vec<Fault> {
        std::mem::take(&mut self.faults)
    }

    fn take_notes(&mut self) -> Vec<String> {
        std::mem::take(&mut self.notes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(pairs: Vec<(&str, Item)>) -> Item {
        Item::Map(pairs.into_iter().map(|(k, v)| (k.to_string(), v)).collect())
    }

    fn ints(v: &[i128]) -> Item {
        Item::List(v.iter().map(|&n| Item::Int(n)).collect())
    }

    fn rows(v: &[[f32; 3]]) -> Item {
        Item::Array(NdArray::float32(
            vec![v.len(), 3],
            &v.iter().flatten().copied().collect::<Vec<_>>(),
        ))
    }

    fn codes(steps: &[Step]) -> Vec<Action> {
        steps
            .iter()
            .map(|s| match s {
                Step::Code(a) => *a,
                Step::Delta(d) => panic!("a row {d:?}"),
            })
            .collect()
    }

    #[test]
    fn every_action_key_is_read_in_gn0s_order_and_typed_by_declaration_or_values() {
        use ActionFormat::{Auto, Discrete, NavDelta};
        let d = [[0.25, 0.0, 0.1], [0.0, 0.1, -0.2]];
        // The preferred form, both types, with openpi's extras.
        let r = map(vec![
            ("action_type", Item::Str("discrete".into())),
            ("actions", ints(&[1, 2, 0])),
            ("server_timing", map(vec![("infer_ms", Item::Float(3.0))])),
        ]);
        let want = [Action::MoveForward, Action::TurnLeft, Action::Stop];
        assert_eq!(codes(&parse_reply(&r, Auto).unwrap()), want);
        let r = map(vec![
            ("action_type", Item::Str("nav_delta".into())),
            ("actions", rows(&d)),
            ("action.nav_delta_scaled", rows(&[[9.0, 9.0, 9.0]])),
            ("server_timing", Item::Float(0.5)),
        ]);
        assert_eq!(
            parse_reply(&r, Auto).unwrap(),
            [Step::Delta(d[0]), Step::Delta(d[1])]
        );
        // Each legacy key alone, typed by its name or its values; `actions` wins over the rest.
        for (key, value, want) in [
            ("action.nav_delta", rows(&d[..1]), vec![Step::Delta(d[0])]),
            (
                "action.discrete",
                ints(&[3]),
                vec![Step::Code(Action::TurnRight)],
            ),
            ("action.vlnce", Item::Int(0), vec![Step::Code(Action::Stop)]),
            (
                "action",
                Item::Array(NdArray::uint8(vec![2], vec![1, 1])),
                vec![Step::Code(Action::MoveForward); 2],
            ),
            ("action", rows(&d[1..]), vec![Step::Delta(d[1])]),
        ] {
            assert_eq!(
                parse_reply(&map(vec![(key, value.clone())]), Auto).unwrap(),
                want,
                "{key}"
            );
            let both = map(vec![(key, value), ("actions", ints(&[2]))]);
            assert_eq!(
                codes(&parse_reply(&both, Auto).unwrap()),
                [Action::TurnLeft]
            );
        }
        // Auto typing: a float scalar is a code; 1-D floats of 3+ are one row.
        let r = map(vec![("actions", Item::Float(1.0))]);
        assert_eq!(
            codes(&parse_reply(&r, Auto).unwrap()),
            [Action::MoveForward]
        );
        let one = Item::List(vec![Item::Float(0.1), Item::Float(0.0), Item::Float(0.0)]);
        assert_eq!(
            parse_reply(&map(vec![("actions", one.clone())]), Auto).unwrap(),
            [Step::Delta([0.1, 0.0, 0.0])]
        );
        // The option overrides what the reply declares and what the values suggest.
        let r = map(vec![
            ("action_type", Item::Str("nav_delta".into())),
            ("actions", ints(&[1])),
        ]);
        assert_eq!(
            codes(&parse_reply(&r, Discrete).unwrap()),
            [Action::MoveForward]
        );
        assert!(parse_reply(&r, NavDelta).is_err());
        assert_eq!(
            parse_reply(&map(vec![("actions", ints(&[1, 0, 0]))]), NavDelta).unwrap(),
            [Step::Delta([1.0, 0.0, 0.0])]
        );
    }

    #[test]
    fn replies_without_a_usable_action_are_faults_of_their_kind() {
        let auto = ActionFormat::Auto;
        for (reply, kind, says) in [
            (
                map(vec![("status", Item::Str("reset successful".into()))]),
                FaultKind::Unparseable,
                "no action key",
            ),
            (
                map(vec![("error", Item::Str("CUDA out of memory".into()))]),
                FaultKind::ServerError,
                "CUDA out of memory",
            ),
            (ints(&[1]), FaultKind::Unparseable, "expected a map"),
            (
                map(vec![("actions", ints(&[]))]),
                FaultKind::Unparseable,
                "no action",
            ),
            (
                map(vec![("actions", ints(&[7]))]),
                FaultKind::Unparseable,
                "7 is not",
            ),
            (
                map(vec![("actions", Item::Str("forward".into()))]),
                FaultKind::Unparseable,
                "expected numbers",
            ),
            (
                map(vec![(
                    "actions",
                    Item::List(vec![Item::Float(0.5), Item::Float(0.5)]),
                )]),
                FaultKind::Unparseable,
                "neither",
            ),
            (
                map(vec![(
                    "actions",
                    Item::Array(NdArray::float32(vec![1, 1, 3], &[0.1, 0.0, 0.0])),
                )]),
                FaultKind::Unparseable,
                "(N, 3)",
            ),
            (
                map(vec![("actions", rows(&[[f32::NAN, 0.0, 0.0]]))]),
                FaultKind::Unparseable,
                "NaN",
            ),
            (
                map(vec![
                    ("action_type", Item::Str("joint".into())),
                    ("actions", ints(&[1])),
                ]),
                FaultKind::Unparseable,
                "joint",
            ),
            (
                map(vec![(
                    "actions",
                    Item::Array(NdArray {
                        dtype: "<U1".into(),
                        shape: vec![1],
                        data: vec![0; 4],
                    }),
                )]),
                FaultKind::Unparseable,
                "dtype",
            ),
        ] {
            let (k, message) = parse_reply(&reply, auto).unwrap_err();
            assert_eq!(k, kind, "{message}");
            assert!(message.contains(says), "{message}");
        }
    }

    #[test]
    fn rows_turn_from_the_query_heading_and_tiny_rows_stop() {
        let row = Step::Delta([0.2, 0.1, 0.3]);
        // With the heading unchanged since the query, the row is the body displacement.
        assert_eq!(
            row_action(row, Rotate::ChunkStart, 1.0, 1.0),
            Action::Displace {
                dx: 0.2,
                dy: 0.1,
                dyaw: 0.3
            }
        );
        // After a quarter turn left, the query's forward is the agent's right.
        let Action::Displace { dx, dy, dyaw } =
            row_action(row, Rotate::ChunkStart, 0.0, std::f32::consts::FRAC_PI_2)
        else {
            panic!()
        };
        assert!((dx - 0.1).abs() < 1e-6 && (dy + 0.2).abs() < 1e-6 && dyaw == 0.3);
        assert_eq!(
            row_action(row, Rotate::Current, 0.0, 1.5),
            Action::Displace {
                dx: 0.2,
                dy: 0.1,
                dyaw: 0.3
            }
        );
        let tiny = Step::Delta([1e-3, -1e-3, 5e-4]);
        assert_eq!(row_action(tiny, Rotate::Current, 0.0, 0.0), Action::Stop);
        let small = Step::Delta([0.0, 0.0, 2e-3]);
        assert!(matches!(
            row_action(small, Rotate::Current, 0.0, 0.0),
            Action::Displace { .. }
        ));
        let code = Step::Code(Action::TurnLeft);
        assert_eq!(
            row_action(code, Rotate::ChunkStart, 0.0, 2.0),
            Action::TurnLeft
        );
    }
}
