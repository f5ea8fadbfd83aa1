//! Remote agents: a model server or chat model decides every step from the episode's recent
//! RGB frames and the instruction (SPEC §11, `docs/evaluation.md`).
//!
//! Three protocols carry the same request: [`socket`] (the SAGE-3D socket protocol, 8-byte
//! big-endian length + JSON `{images, query}`), [`http`] (`POST /vln_step` and OpenAI-compatible
//! `/chat/completions`). A fourth, GN0's remote-policy protocol over WebSocket ([`ws`],
//! [`msgpack_numpy`]), sends raw frames and takes action chunks; its agent is [`policy`]. [`frames`] keeps the last `history` frames as base64 JPEGs — the real
//! recent frames (the published client sent copies of the first frame) — and [`flavour`]
//! arranges them as the published server behind a socket needs them (NaVILA: exactly 8, padded;
//! MLLM: current first; NaVid: a reset per episode, one episode at a time). [`parse`] turns a
//! reply into discrete actions; a reply naming several steps ("move forward 75 cm") is queued
//! and the server is asked again only when the queue is empty. Faults (refused, timeout,
//! disconnect, bad framing, a reply that says the server failed or that the server made up,
//! garbage) are retried under [`RemoteOptions::retry_policy`] (`sage_http`'s backoff, for every
//! protocol); every fault is kept for the episode's record with its kind, and a step that
//! fails every attempt fails the episode.

pub mod flavour;
pub mod frames;
pub mod http;
pub mod msgpack_numpy;
pub mod parse;
pub mod policy;
pub mod socket;
pub mod ws;

pub use flavour::Server;
use frames::FrameHistory;
use parse::Steps;
use policy::{PolicyAgent, PolicyOptions};
use sage_core::{Error, Result};
use sage_env::agents::{Agent, Fault, FaultKind};
use sage_env::{Action, ActionSpace, Env, EnvEpisode, Observation};
use sage_http::{Failure, RetryOn, RetryPolicy};
use std::cell::Cell;
use std::collections::VecDeque;
use std::fmt;
use std::time::Duration;

/// First pause between attempts; doubled per attempt up to [`BACKOFF_MAX`].
const BACKOFF: Duration = Duration::from_millis(100);
/// Longest pause between attempts.
const BACKOFF_MAX: Duration = Duration::from_secs(2);

/// Where the remote agent's decisions come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Protocol {
    /// The SAGE-3D socket protocol, a new TCP connection per step.
    Socket {
        /// Host name or address (IPv6 in brackets).
        host: String,
        /// TCP port.
        port: u16,
    },
    /// `POST` of `{images, instruction, current_yaw}` to this URL (NaVILA / NaVid servers).
    Http {
        /// Full URL, `/vln_step` appended when it named no path.
        url: String,
    },
    /// A GN0 / openpi policy server over WebSocket (`ws://HOST:PORT/`), one connection per
    /// episode.
    Ws {
        /// Host name or address (IPv6 in brackets).
        host: String,
        /// TCP port.
        port: u16,
    },
    /// OpenAI-compatible `POST BASE_URL/chat/completions` with image data URIs.
    Chat {
        /// Model name sent in the request.
        model: String,
        /// API base, e.g. `http://127.0.0.1:8000/v1`.
        base_url: String,
    },
}

/// The `?key=value` options of a remote agent.
#[derive(Debug, Clone, PartialEq)]
pub struct RemoteOptions {
    /// The published server behind a socket (`server`; generic).
    pub server: Server,
    /// Frames sent per request (`history`; 8, chat, NaVid and MLLM 1).
    pub history: usize,
    /// Seconds allowed for one request, connect to reply (`timeout`; 60).
    pub timeout_s: f64,
    /// Further attempts after a fault (`retries`; 3).
    pub retries: u32,
    /// JPEG quality 1–100 (`quality`; 90).
    pub quality: u8,
    /// Most actions queued from one reply (`repeat`; 3, as NaVid; NaVILA `all`: no cap).
    pub max_repeat: Option<usize>,
    /// Chat sampling temperature (`temperature`; 0.1, as the MLLM baselines).
    pub temperature: f32,
    /// Chat answer length limit (`max_tokens`; 64).
    pub max_tokens: u32,
    /// The options of `ws:` policy servers.
    pub policy: PolicyOptions,
}

impl RemoteOptions {
    /// The defaults of a protocol and server flavour (chat models see the current image only;
    /// policy servers get GN0's 120 s timeout).
    pub fn defaults(protocol: &Protocol, server: Server) -> RemoteOptions {
        RemoteOptions {
            server,
            history: if matches!(protocol, Protocol::Chat { .. }) {
                1
            } else {
                server.default_history()
            },
            timeout_s: if matches!(protocol, Protocol::Ws { .. }) {
                120.0
            } else {
                60.0
            },
            retries: 3,
            quality: 90,
            max_repeat: server.default_repeat(),
            temperature: 0.1,
            max_tokens: 64,
            policy: PolicyOptions::default(),
        }
    }

    /// The option names a protocol accepts, in canonical order.
    fn keys(protocol: &Protocol) -> &'static [&'static str] {
        const SOCKET: [&str; 6] = [
            "server", "history", "timeout", "retries", "quality", "repeat",
        ];
        const COMMON: [&str; 5] = ["history", "timeout", "retries", "quality", "repeat"];
        const WS: [&str; 8] = [
            "actions",
            "state",
            "format",
            "rotate",
            "history_cap",
            "metadata",
            "timeout",
            "retries",
        ];
        const CHAT: [&str; 7] = [
            "history",
            "timeout",
            "retries",
            "quality",
            "repeat",
            "temperature",
            "max_tokens",
        ];
        match protocol {
            Protocol::Socket { .. } => &SOCKET,
            Protocol::Chat { .. } => &CHAT,
            Protocol::Http { .. } => &COMMON,
            Protocol::Ws { .. } => &WS,
        }
    }

    /// The value of option `key` as written in the canonical string.
    fn value(&self, key: &str) -> String {
        if PolicyOptions::KEYS.contains(&key) {
            return self.policy.value(key);
        }
        match key {
            "server" => self.server.to_string(),
            "history" => self.history.to_string(),
            "timeout" => self.timeout_s.to_string(),
            "retries" => self.retries.to_string(),
            "quality" => self.quality.to_string(),
            "repeat" => self
                .max_repeat
                .map_or_else(|| "all".to_string(), |n| n.to_string()),
            "temperature" => self.temperature.to_string(),
            _ => self.max_tokens.to_string(),
        }
    }

    /// Sets option `key` from its text, checking its range.
    fn set(&mut self, key: &str, v: &str) -> Result<()> {
        if PolicyOptions::KEYS.contains(&key) {
            return self.policy.set(key, v);
        }
        let bad = |want: &str| Error::invalid(format!("option {key}={v}: expected {want}"));
        let int = |lo: u64, hi: u64| {
            v.parse::<u64>()
                .ok()
                .filter(|n| (lo..=hi).contains(n))
                .ok_or_else(|| bad(&format!("an integer in {lo}..={hi}")))
        };
        match key {
            "history" => self.history = int(1, 64)? as usize,
            "timeout" => {
                self.timeout_s = v
                    .parse::<f64>()
                    .ok()
                    .filter(|t| t.is_finite() && *t > 0.0 && *t <= 86_400.0)
                    .ok_or_else(|| bad("seconds, more than 0 and at most 86400 (a day)"))?;
            }
            "retries" => self.retries = int(0, 100)? as u32,
            "quality" => self.quality = int(1, 100)? as u8,
            "repeat" if v.eq_ignore_ascii_case("all") => self.max_repeat = None,
            "repeat" => {
                self.max_repeat = Some(
                    v.parse::<usize>()
                        .ok()
                        .filter(|n| (1..=100).contains(n))
                        .ok_or_else(|| bad("an integer in 1..=100 or all"))?,
                );
            }
            "temperature" => {
                self.temperature = v
                    .parse::<f32>()
                    .ok()
                    .filter(|t| t.is_finite() && (0.0..=2.0).contains(t))
                    .ok_or_else(|| bad("a number in 0..=2"))?;
            }
            _ => self.max_tokens = int(1, 100_000)? as u32,
        }
        Ok(())
    }

    /// The time allowed for one request.
    pub fn timeout(&self) -> Duration {
        Duration::from_secs_f64(self.timeout_s)
    }

    /// How a step's request is retried: `retries` times after short, growing pauses (0.1 s
    /// doubled up to 2 s). Every fault is retried, an HTTP 4xx or a reply that does not parse
    /// included, since model servers answer wrongly now and then; faults reach the policy as
    /// the same text for every protocol, so an HTTP `Retry-After` does not change the pauses.
    pub fn retry_policy(&self) -> RetryPolicy {
        RetryPolicy {
            retries: self.retries,
            initial: BACKOFF,
            cap: BACKOFF_MAX,
            retry_on: RetryOn::Any,
        }
    }
}

/// A remote agent as named on the command line: protocol, address and options.
#[derive(Debug, Clone, PartialEq)]
pub struct RemoteSpec {
    /// The protocol and address.
    pub protocol: Protocol,
    /// The options.
    pub options: RemoteOptions,
}

impl RemoteSpec {
    /// Parses the part after `socket:`, `ws:`, `http:` or `chat:` (`kind`). The URL spelling
    /// of a server, `ws://HOST:PORT/`, `socket://HOST:PORT` or `http://HOST:PORT/PATH` (the
    /// scheme taken for the kind, so `rest` starts with `//`), names the same agent as
    /// `ws:HOST:PORT`, `socket:HOST:PORT` or `http:http://HOST:PORT/PATH`: no address of these
    /// kinds starts with `//`, so the two spellings never meet.
    ///
    /// # Errors
    ///
    /// A malformed address, an unknown option (the valid ones listed) or a value out of range.
    pub fn parse(kind: &str, rest: &str) -> Result<RemoteSpec> {
        let (address, query) = match rest.split_once('?') {
            Some((a, q)) => (a.trim(), Some(q)),
            None => (rest.trim(), None),
        };
        let url;
        let address = match (kind, address.strip_prefix("//")) {
            ("http", Some(_)) => {
                url = format!("http:{address}");
                url.as_str()
            }
            // The servers' root, as `ws://HOST:PORT/` names it; any other path is no port.
            ("socket" | "ws", Some(host_port)) => host_port.strip_suffix('/').unwrap_or(host_port),
            _ => address,
        };
        let host_port = || {
            let (host, port) = address
                .rsplit_once(':')
                .filter(|(h, _)| !h.is_empty())
                .ok_or_else(|| {
                    Error::invalid(format!("{kind}:{rest}: expected {kind}:HOST:PORT"))
                })?;
            let port = port.parse::<u16>().ok().filter(|p| *p > 0).ok_or_else(|| {
                Error::invalid(format!("{kind}:{rest}: port '{port}' is not 1–65535"))
            })?;
            Ok::<_, Error>((host.to_string(), port))
        };
        let protocol = match kind {
            "socket" => {
                let (host, port) = host_port()?;
                Protocol::Socket { host, port }
            }
            "ws" => {
                let (host, port) = host_port()?;
                Protocol::Ws { host, port }
            }
            "http" => Protocol::Http {
                url: http::step_url(address)?,
            },
            _ => {
                let (model, base) = address
                    .split_once('@')
                    .filter(|(m, b)| !m.trim().is_empty() && !b.trim().is_empty())
                    .ok_or_else(|| {
                        Error::invalid(format!("chat:{rest}: expected chat:MODEL@BASE_URL"))
                    })?;
                Protocol::Chat {
                    model: model.trim().to_string(),
                    base_url: http::base_url(base)?,
                }
            }
        };
        let keys = RemoteOptions::keys(&protocol);
        let mut pairs = Vec::new();
        for pair in query.into_iter().flat_map(|q| q.split('&')) {
            if pair.is_empty() {
                continue;
            }
            let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
            let k = k.trim().to_ascii_lowercase();
            if !keys.contains(&k.as_str()) {
                let why = if k == "server" {
                    " (server flavours are for socket agents: the published servers speak the socket protocol)"
                } else {
                    ""
                };
                return Err(Error::invalid(format!(
                    "{kind} agent: unknown option '{k}'{why} (expected: {})",
                    keys.join(", ")
                )));
            }
            pairs.push((k, v.trim()));
        }
        // The flavour sets the other options' defaults, so it is read first.
        let server = match pairs.iter().find(|(k, _)| k == "server") {
            Some((_, v)) => v
                .parse()
                .map_err(|e: Error| e.within(format!("{kind} agent option server")))?,
            None => Server::Generic,
        };
        let mut options = RemoteOptions::defaults(&protocol, server);
        for (k, v) in pairs.iter().filter(|(k, _)| k != "server") {
            options.set(k, v)?;
        }
        Ok(RemoteSpec { protocol, options })
    }

    /// The server's address for messages: `HOST:PORT`, the URL, or `MODEL@BASE_URL`.
    pub fn server(&self) -> String {
        match &self.protocol {
            Protocol::Socket { host, port } | Protocol::Ws { host, port } => {
                format!("{host}:{port}")
            }
            Protocol::Http { url } => url.clone(),
            Protocol::Chat { model, base_url } => format!("{model}@{base_url}"),
        }
    }
}

impl fmt::Display for RemoteSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = match self.protocol {
            Protocol::Socket { .. } => "socket",
            Protocol::Ws { .. } => "ws",
            Protocol::Http { .. } => "http",
            Protocol::Chat { .. } => "chat",
        };
        write!(f, "{kind}:{}", self.server())?;
        // The flavour's own defaults are left out; the flavour itself unless generic.
        let defaults = RemoteOptions {
            server: Server::Generic,
            ..RemoteOptions::defaults(&self.protocol, self.options.server)
        };
        let mut sep = '?';
        for key in RemoteOptions::keys(&self.protocol) {
            let v = self.options.value(key);
            if v != defaults.value(key) {
                write!(f, "{sep}{key}={v}")?;
                sep = '&';
            }
        }
        Ok(())
    }
}

/// One request to a server: the frames (base64 JPEGs) and the instruction; the reply as JSON
/// (chat and non-JSON HTTP bodies as a JSON string), or the fault.
trait Transport: Send {
    fn ask(
        &mut self,
        images: &[String],
        instruction: &str,
    ) -> std::result::Result<serde_json::Value, String>;

    /// Sends `message` outside the step protocol (an episode's opening, NaVid's reset) and
    /// returns the reply; only the socket protocol has such messages.
    fn send(
        &mut self,
        message: &serde_json::Value,
    ) -> std::result::Result<serde_json::Value, String> {
        Err(format!("this protocol cannot send {message}"))
    }
}

/// An agent whose decisions come from a remote model (see the module doc).
pub struct RemoteAgent {
    spec: RemoteSpec,
    name: String,
    transport: Box<dyn Transport>,
    frames: FrameHistory,
    queue: VecDeque<Action>,
    steps: Steps,
    instruction: String,
    faults: Vec<Fault>,
    notes: Vec<String>,
}

/// The agent of `spec`: a [`PolicyAgent`] for `ws:`, else a [`RemoteAgent`] over the
/// protocol's client (connections are opened per request or episode, not here).
pub fn agent(spec: RemoteSpec) -> Box<dyn Agent> {
    let o = &spec.options;
    let transport: Box<dyn Transport> = match &spec.protocol {
        Protocol::Socket { host, port } => {
            Box::new(socket::SocketClient::new(host, *port, o.timeout()))
        }
        Protocol::Http { url } => Box::new(http::StepClient::new(url, o.timeout())),
        Protocol::Chat { model, base_url } => Box::new(http::ChatClient::new(
            model,
            base_url,
            o.timeout(),
            o.temperature,
            o.max_tokens,
        )),
        Protocol::Ws { .. } => return Box::new(PolicyAgent::new(spec)),
    };
    Box::new(RemoteAgent::new(spec, transport))
}

/// Checks that `env` suits a remote agent (the discrete action space and RGB images) and
/// returns the discrete forward step (m) and turn step (degrees).
///
/// # Errors
///
/// Another action space, or no RGB sensor.
fn check_env(env: &Env) -> Result<(f32, f32)> {
    let ActionSpace::Discrete {
        forward, turn_deg, ..
    } = env.config().actions
    else {
        return Err(Error::invalid(
            "remote agents need the discrete action space",
        ));
    };
    if !env.config().sensors.rgb {
        return Err(Error::invalid(
            "remote agents need RGB images (the environment renders none)",
        ));
    }
    Ok((forward, turn_deg))
}

/// Runs `attempt` under `spec`'s retry policy for the request of `step`, recording each
/// failed attempt in `faults` with its kind (marked recovered when a later attempt succeeds).
///
/// # Errors
///
/// Every attempt failed: the server, the step and the last fault.
fn with_retries<T>(
    spec: &RemoteSpec,
    faults: &mut Vec<Fault>,
    step: usize,
    what: &str,
    mut attempt: impl FnMut() -> std::result::Result<T, parse::ReplyFault>,
) -> Result<T> {
    let first = faults.len();
    let kind = Cell::new(FaultKind::Transport);
    let result = spec.options.retry_policy().run(
        |_| {
            attempt().map_err(|(k, message)| {
                kind.set(k);
                Failure::new(message)
            })
        },
        |n, f| {
            faults.push(Fault {
                step,
                attempt: n + 1,
                kind: kind.get(),
                message: f.message.clone(),
                recovered: false,
            });
        },
        std::thread::sleep,
    );
    match result {
        Ok(value) => {
            for f in &mut faults[first..] {
                f.recovered = true;
            }
            Ok(value)
        }
        Err(gave_up) => Err(Error::invalid(format!(
            "{}: no usable {what} at step {step} after {} attempts: {}",
            spec.server(),
            gave_up.attempts,
            gave_up.last.message
        ))),
    }
}

impl RemoteAgent {
    /// An agent speaking `spec`'s protocol through `transport`.
    fn new(spec: RemoteSpec, transport: Box<dyn Transport>) -> RemoteAgent {
        let o = &spec.options;
        RemoteAgent {
            name: spec.to_string(),
            frames: FrameHistory::new(o.history, o.quality),
            steps: Steps {
                forward: 0.25,
                turn_deg: 15.0,
                bare_turn_deg: o.server.bare_turn_deg(),
            },
            spec,
            transport,
            queue: VecDeque::new(),
            instruction: String::new(),
            faults: Vec::new(),
            notes: Vec::new(),
        }
    }
}

impl Agent for RemoteAgent {
    fn name(&self) -> &str {
        &self.name
    }

    fn reset(&mut self, env: &Env, episode: &EnvEpisode) -> Result<()> {
        let (forward, turn_deg) = check_env(env)?;
        self.steps.forward = forward;
        self.steps.turn_deg = turn_deg;
        self.frames.clear();
        self.queue.clear();
        self.faults.clear();
        self.notes.clear();
        self.instruction = episode.instruction.clone();
        if let Some(message) = self.spec.options.server.episode_start() {
            let transport = &mut self.transport;
            with_retries(
                &self.spec,
                &mut self.faults,
                0,
                "reply to the episode's reset",
                || {
                    transport
                        .send(&message)
                        .map_err(|e| (FaultKind::Transport, e))
                },
            )?;
        }
        Ok(())
    }

    fn act(&mut self, obs: &Observation) -> Result<Action> {
        self.frames.push(obs)?;
        if let Some(a) = self.queue.pop_front() {
            return Ok(a);
        }
        let options = &self.spec.options;
        let images = options
            .server
            .arrange(self.frames.frames(), options.history);
        let (server, steps, instruction) = (options.server, self.steps, self.instruction.clone());
        let transport = &mut self.transport;
        let mut actions = with_retries(&self.spec, &mut self.faults, obs.step, "reply", || {
            let reply = transport
                .ask(&images, &instruction)
                .map_err(|e| (FaultKind::Transport, e))?;
            // A reply that says the server failed is that, whatever else it holds.
            let actions = parse::parse_reply(&reply, &steps)?;
            server.check(&reply)?;
            Ok(actions)
        })?;
        if let Some(cap) = self.spec.options.max_repeat
            && actions.len() > cap
        {
            let asked = if actions.len() >= parse::MOST_ACTIONS {
                format!("{} or more", parse::MOST_ACTIONS)
            } else {
                actions.len().to_string()
            };
            self.notes.push(format!(
                "step {}: the reply asked for {asked} actions; repeat={cap} carried out the first {cap}",
                obs.step
            ));
            actions.truncate(cap);
        }
        self.queue.extend(actions);
        Ok(self.queue.pop_front().unwrap_or(Action::Stop))
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

    #[test]
    fn every_fault_is_retried_after_a_pause_doubling_from_0_1_s_to_2_s() {
        let spec = RemoteSpec::parse("socket", "h:1?retries=7").unwrap();
        let policy = spec.options.retry_policy();
        assert_eq!((policy.retries, policy.retry_on), (7, RetryOn::Any));
        let waits: Vec<u128> = (0..7).map(|n| policy.wait(n, None).as_millis()).collect();
        assert_eq!(waits, [100, 200, 400, 800, 1600, 2000, 2000]);
    }
}
