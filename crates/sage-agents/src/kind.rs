//! Which agent an evaluation runs, as `--agent` names it, and the maker of one agent per
//! episode.

use crate::remote::{self, RemoteSpec};
use crate::replay::{ReplayAgent, ReplayFile};
use sage_core::{Error, Result};
use sage_env::ActionSpace;
use sage_env::agents::{Agent, ForwardAgent, OracleAgent, RandomAgent};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;
use std::sync::Arc;

/// The agent of an evaluation, as named by `--agent` and stored in the run record as the same
/// string: `random`, `forward`, `oracle`, `replay:FILE`, `socket:HOST:PORT`, `http:URL`,
/// `chat:MODEL@BASE_URL`, `ws:HOST:PORT` or `human`, the remote ones with `?key=value&…` options
/// ([`RemoteSpec`]); a server's URL (`http://HOST:PORT`, `https://…`, `ws://HOST:PORT`,
/// `socket://HOST:PORT`) names the same agent as its spec ([`RemoteSpec::parse`]). Display
/// writes the canonical string (default options left out), which parses back to the same
/// kind.
#[derive(Debug, Clone, PartialEq)]
pub enum AgentKind {
    /// Uniform FORWARD / LEFT / RIGHT with a small STOP probability, seeded per episode.
    Random,
    /// FORWARD until the step limit.
    Forward,
    /// The shortest-path follower (privileged: reads the scene's path finder).
    Oracle,
    /// Replays the actions or poses recorded per episode in a JSONL file ([`ReplayFile`]).
    Replay(PathBuf),
    /// A model server or chat model queried every step with the recent frames.
    Remote(RemoteSpec),
    /// A person playing the episodes in the browser viewer (`sage3d view --play`): recorded
    /// and scored like any agent, but never built by an evaluation.
    Human,
}

/// The kinds an evaluation builds, as error messages list them; `human` is named apart, as
/// only the viewer plays it.
const KINDS: &str = "random, forward, oracle, replay:FILE, socket:HOST:PORT, http:URL, \
                     chat:MODEL@BASE_URL, ws:HOST:PORT";

impl AgentKind {
    /// Reads what the kind needs once (the replay file) and returns the maker of one agent
    /// per episode.
    ///
    /// # Errors
    ///
    /// A replay file that cannot be read or has a bad line (naming file and line).
    pub fn maker(&self) -> Result<AgentMaker> {
        let replay = match self {
            AgentKind::Replay(file) => Some(Arc::new(ReplayFile::read(file)?)),
            _ => None,
        };
        Ok(AgentMaker {
            kind: self.clone(),
            replay,
        })
    }

    /// A fresh agent of this kind (`seed` drives the random agent); reads a replay file on
    /// every call, so runs of many episodes use [`AgentKind::maker`].
    ///
    /// # Errors
    ///
    /// The agent's own parameter checks, or [`AgentKind::maker`]'s.
    pub fn build(&self, seed: u64) -> Result<Box<dyn Agent>> {
        self.maker()?.build(seed)
    }
}

/// Makes the agents of one run: a kind with its inputs loaded.
#[derive(Debug, Clone)]
pub struct AgentMaker {
    kind: AgentKind,
    replay: Option<Arc<ReplayFile>>,
}

impl AgentMaker {
    /// A fresh agent for one episode.
    ///
    /// # Errors
    ///
    /// The agent's own parameter checks; `human`, whose steps come from a person in the
    /// viewer, not from a built agent.
    pub fn build(&self, seed: u64) -> Result<Box<dyn Agent>> {
        Ok(match (&self.kind, &self.replay) {
            (AgentKind::Random, _) => Box::new(RandomAgent::new(seed, 0.02)?),
            (AgentKind::Forward, _) => Box::new(ForwardAgent::new(None)),
            (AgentKind::Oracle, _) => Box::new(OracleAgent::new(0.25)),
            (AgentKind::Replay(_), Some(file)) => Box::new(ReplayAgent::new(file.clone())),
            (AgentKind::Replay(file), None) => {
                Box::new(ReplayAgent::new(Arc::new(ReplayFile::read(file)?)))
            }
            (AgentKind::Remote(spec), _) => remote::agent(spec.clone()),
            (AgentKind::Human, _) => {
                return Err(Error::invalid(
                    "the human agent is a person: play the split in `sage3d view DATASET --play RUN`",
                ));
            }
        })
    }

    /// True when the agent's episodes must run one at a time: its server holds one episode's
    /// state for all clients (NaVid).
    pub fn serial(&self) -> bool {
        matches!(&self.kind, AgentKind::Remote(spec) if spec.options.server.serial())
    }

    /// True when the agent reads RGB images (the remote agents, and a person); the others run
    /// blind.
    pub fn reads_images(&self) -> bool {
        matches!(self.kind, AgentKind::Remote(_) | AgentKind::Human)
    }

    /// The action space the agent needs instead of the preset's: the ground-velocity space
    /// for pose replays and velocity actions.
    pub fn action_space(&self) -> Option<ActionSpace> {
        self.replay.as_ref().and_then(|r| r.action_space())
    }
}

impl fmt::Display for AgentKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AgentKind::Random => f.write_str("random"),
            AgentKind::Forward => f.write_str("forward"),
            AgentKind::Oracle => f.write_str("oracle"),
            AgentKind::Replay(file) => write!(f, "replay:{}", file.display()),
            AgentKind::Remote(spec) => spec.fmt(f),
            AgentKind::Human => f.write_str("human"),
        }
    }
}

impl FromStr for AgentKind {
    type Err = Error;

    fn from_str(s: &str) -> Result<AgentKind> {
        let s = s.trim();
        let (kind, rest) = match s.split_once(':') {
            Some((k, r)) => (k.to_ascii_lowercase(), Some(r)),
            None => (s.to_ascii_lowercase(), None),
        };
        match (kind.as_str(), rest) {
            ("random", None) => Ok(AgentKind::Random),
            ("forward", None) => Ok(AgentKind::Forward),
            ("oracle", None) => Ok(AgentKind::Oracle),
            ("human", None) => Ok(AgentKind::Human),
            ("replay", Some(file)) if !file.trim().is_empty() => {
                Ok(AgentKind::Replay(PathBuf::from(file.trim())))
            }
            ("socket" | "http" | "chat" | "ws", Some(rest)) => {
                Ok(AgentKind::Remote(RemoteSpec::parse(&kind, rest)?))
            }
            // An `https://` URL is an `http:` agent's (`http:https://…`).
            ("https", Some(rest)) if rest.starts_with("//") => {
                Ok(AgentKind::Remote(RemoteSpec::parse("http", s)?))
            }
            _ => Err(Error::invalid(format!(
                "unknown agent '{s}' (expected one of: {KINDS}; `human`, a person, plays \
                 only in `sage3d view DATASET --play RUN`)"
            ))),
        }
    }
}

impl Serialize for AgentKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for AgentKind {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<AgentKind, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agent_specs_round_trip_and_unknown_names_list_the_valid_ones() {
        for spec in [
            "random",
            "forward",
            "oracle",
            "replay:runs/actions.jsonl",
            "socket:127.0.0.1:54321",
            "socket:127.0.0.1:54321?history=4&timeout=0.5&retries=0",
            "http:http://127.0.0.1:8000/vln_step",
            "http:http://127.0.0.1:8000/v1/step?quality=75&repeat=1",
            "chat:qwen2.5-vl@http://127.0.0.1:8000/v1?history=2&temperature=0&max_tokens=16",
            "socket:127.0.0.1:54321?server=navila",
            "socket:127.0.0.1:4321?server=navid&timeout=5",
            "socket:127.0.0.1:7777?server=mllm&history=3",
            "socket:127.0.0.1:54321?server=navila&repeat=3",
            "socket:127.0.0.1:9?repeat=all",
            "ws:127.0.0.1:8000",
            "ws:127.0.0.1:8000?actions=4&state=1&format=nav_delta&rotate=current&history_cap=16&metadata=0&timeout=5&retries=1",
            "ws:[::1]:8001?format=discrete",
            "human",
        ] {
            let k: AgentKind = spec.parse().unwrap();
            assert_eq!(k.to_string(), spec);
            let json = serde_json::to_string(&k).unwrap();
            assert_eq!(json, format!("\"{spec}\""));
            assert_eq!(serde_json::from_str::<AgentKind>(&json).unwrap(), k);
        }
        assert_eq!(" Oracle ".parse::<AgentKind>().unwrap(), AgentKind::Oracle);
        // Defaults are left out of the canonical string; a bare host gets http:// and /vln_step.
        let k: AgentKind = "socket:localhost:9?history=8&retries=3".parse().unwrap();
        assert_eq!(k.to_string(), "socket:localhost:9");
        // A flavour's own defaults are left out too, and it sets them.
        let k: AgentKind = "socket:h:9?history=8&server=NaVILA&repeat=all"
            .parse()
            .unwrap();
        assert_eq!(k.to_string(), "socket:h:9?server=navila");
        let AgentKind::Remote(spec) = &k else {
            panic!("{k:?}")
        };
        assert_eq!((spec.options.history, spec.options.max_repeat), (8, None));
        let k: AgentKind = "socket:h:9?server=navid".parse().unwrap();
        assert!(k.maker().unwrap().serial());
        assert!(
            !"socket:h:9?server=mllm"
                .parse::<AgentKind>()
                .unwrap()
                .maker()
                .unwrap()
                .serial()
        );
        // GN0's defaults: 8 actions, 120 s, the frame cap max(64, 4 · actions).
        let k: AgentKind = "ws:h:1?timeout=120&actions=8&format=auto&state=off&history_cap=auto"
            .parse()
            .unwrap();
        assert_eq!(k.to_string(), "ws:h:1");
        let AgentKind::Remote(spec) = "ws:h:1?actions=32".parse::<AgentKind>().unwrap() else {
            panic!()
        };
        assert_eq!(spec.options.policy.cap(), 128);
        assert!(k.maker().unwrap().reads_images() && !k.maker().unwrap().serial());
        let k: AgentKind = "http:127.0.0.1:8000".parse().unwrap();
        assert_eq!(k.to_string(), "http:http://127.0.0.1:8000/vln_step");
        for (bad, says) in [
            (
                "genius",
                "random, forward, oracle, replay:FILE, socket:HOST:PORT",
            ),
            ("replay:", "replay:FILE"),
            ("socket:localhost", "HOST:PORT"),
            ("socket:localhost:99999", "port"),
            (
                "socket:h:1?colour=red",
                "history, timeout, retries, quality, repeat",
            ),
            ("socket:h:1?history=0", "history"),
            ("ws:h", "ws:HOST:PORT"),
            (
                "ws:h:1?history=3",
                "actions, state, format, rotate, history_cap",
            ),
            ("ws:h:1?format=joint", "auto, discrete or nav_delta"),
            ("ws:h:1?rotate=world", "chunk_start or current"),
            ("ws:h:1?state=maybe", "1 or 0"),
            ("ws:h:1?actions=0", "1..=4096"),
            ("socket:h:1?actions=3", "server, history"),
            ("socket:h:1?server=habitat", "navila, navid, mllm"),
            ("http:127.0.0.1:8000?server=navid", "socket protocol"),
            ("socket:h:1?repeat=many", "or all"),
            ("chat:@http://x", "MODEL@BASE_URL"),
            ("http:ftp://x", "http://"),
            (
                "socket:h:1?temperature=1",
                "history, timeout, retries, quality, repeat",
            ),
        ] {
            let e = bad.parse::<AgentKind>().unwrap_err().to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
        // `human` is not offered as an agent to evaluate: the message says where it plays.
        let e = "foo".parse::<AgentKind>().unwrap_err().to_string();
        assert_eq!(
            e,
            "unknown agent 'foo' (expected one of: random, forward, oracle, replay:FILE, \
             socket:HOST:PORT, http:URL, chat:MODEL@BASE_URL, ws:HOST:PORT; `human`, a person, \
             plays only in `sage3d view DATASET --play RUN`)"
        );
    }

    #[test]
    fn a_servers_url_names_the_same_agent_as_its_spec() {
        for (url, spec) in [
            ("http://127.0.0.1:18765", "http:127.0.0.1:18765"),
            ("HTTP://127.0.0.1:18765/", "http:127.0.0.1:18765"),
            (
                "http://127.0.0.1:8000/v1/step?timeout=5",
                "http:http://127.0.0.1:8000/v1/step?timeout=5",
            ),
            (
                "https://models.example:443",
                "http:https://models.example:443",
            ),
            ("ws://127.0.0.1:8000", "ws:127.0.0.1:8000"),
            (
                "ws://127.0.0.1:8000/?actions=4",
                "ws:127.0.0.1:8000?actions=4",
            ),
            ("ws://[::1]:8001/", "ws:[::1]:8001"),
            (
                "socket://127.0.0.1:54321?server=navila",
                "socket:127.0.0.1:54321?server=navila",
            ),
        ] {
            let from_url: AgentKind = url.parse().unwrap();
            assert_eq!(from_url, spec.parse::<AgentKind>().unwrap(), "{url}");
            assert_eq!(
                from_url.to_string().parse::<AgentKind>().unwrap(),
                from_url,
                "{url}"
            );
        }
        assert_eq!(
            "http://127.0.0.1:18765"
                .parse::<AgentKind>()
                .unwrap()
                .to_string(),
            "http:http://127.0.0.1:18765/vln_step"
        );
        // A path on a ws or socket server is no port of theirs; a TLS WebSocket is not spoken.
        for (bad, says) in [
            ("ws://h:1/policy", "port '1/policy'"),
            ("socket://h", "socket:HOST:PORT"),
            ("wss://h:1", "unknown agent"),
        ] {
            let e = bad.parse::<AgentKind>().unwrap_err().to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }
}
