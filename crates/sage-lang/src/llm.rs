//! The LLM backend (SPEC §8): any OpenAI-compatible chat-completions endpoint, asked with the
//! paper's prompt (appendix C) for a JSON array of instructions about one trajectory.
//!
//! - **Endpoint**: `POST {base_url}/chat/completions` with `model`, a system message (the
//!   prompt), a user message (text map, start and end ids, trajectory id) and `temperature`; the
//!   key is read from the environment variable named in the config (no header when unset, as
//!   local servers need none). Requests go through `sage-http`: plain HTTP always; HTTPS with
//!   the crate feature `tls`, forwarded to it.
//! - **Retry** (`sage_http::RetryPolicy`): every failure — a transport error, any HTTP status
//!   other than 200, an answer that is not a JSON array — is retried with exponential backoff
//!   (initial × 2^attempt, capped; `Retry-After` seconds are honoured up to the cap), at most
//!   `max_retries` times.
//! - **Cache**: the answer to a request is stored under the FNV-1a 64 hash of the URL and the
//!   request body; the file keeps the whole request and is used only when it matches exactly, so
//!   a hash collision is a miss, never a wrong answer. A rerun with the same cache makes no
//!   request and gives the same bytes.
//! - **Concurrency**: at most `concurrency` requests in flight across all threads.

use crate::instruction::{Instruction, InstructionType, Source};
use crate::textmap::TextMap;
use crate::validate::{RejectReason, ValidationReport, Validator};
use sage_core::{Error, Result};
use sage_http::{Failure, RetryOn, RetryPolicy, Stage};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex};
use std::time::Duration;

/// The paper's prompt for instruction generation (appendix C), as the system message.
pub const PROMPT: &str = r#"You are a specialized data annotator for robotics.

Your mission is to act as a human providing natural language instructions for a home or service robot. You will generate a diverse set of human-centric navigation instructions (of INSTRUCTION TYPE "High-Level-Deliver") based on a symbolic TEXT MAP, STARTING POINT, and END POINT.

You need to generate at least 2-4 instructions for each of the seven INSTRUCTION TYPES defined below, ensuring variety and diversity.

<Input>
1. TEXT MAP: A textual description of an environment, including named areas, objects, and their unique IDs (e.g., Bar counter_0, chair_5). This map is the single source of truth.
2. STARTING POINT: The starting point of the trajectory, represented by an Object ID (e.g., chair_5).
   Example: "starting_point": "chair_5"
3. END POINT: The endpoint of the trajectory, represented by an Object ID (e.g., sofa_0).
   Example: "end_point": "sofa_0"

<Task>
Generate multiple natural language instructions for a trajectory from the STARTING POINT to the END POINT (an optimal short path obtained via A*). Use the TEXT MAP to understand the environment.

Generate at least 2-4 instructions for each of the INSTRUCTION TYPES below, ensuring diversity.

<Principles>
1. Don't Embellish or Exaggerate: You do not know the intermediate path points or turns. Do not invent waypoints (e.g., "pass through desk_2") or directional commands (e.g., "turn left") unless explicitly stated in the map.
2. NEVER Use Internal IDs: Never include object IDs like chair_5. Instructions must be understandable to someone without the map.
3. Stay Grounded in the Map: Do not invent objects, properties, or spatial relationships not described or reasonably inferable from the TEXT MAP.
4. Be Natural and Concise: Use everyday language. Keep instructions between 5-20 words. Avoid robotic or overly formal phrasing.
5. Be Creative and Diverse: Vary sentence structure, vocabulary, and perspective. Small wording changes should yield meaningfully different instructions.
6. Avoid Repetition: Within each type, ensure instructions are semantically distinct - not just synonyms or minor rewordings.
7. Ensure Executability: Every instruction must be actionable using only the provided map.
8. Strictly Adhere to Types: Each instruction must clearly match its assigned type definition.

<Instruction_Types>
1. Add_Object
   Description: Adds a reasonable causality object (e.g., an object to carry) to justify the movement.
   Examples:
   "Please move the book from the coffee table to the bookshelf in the study."
   "Please move the teacup from the coffee table to the bookshelf in the study."
2. Scenario_Driven
   Description: Embeds the instruction in a human-centered scenario or goal.
   Example: "I'm thirsty, please bring me a drink from the fridge."
3. Relative_Relationship
   Description: Uses relative spatial terms (e.g., "next to", "behind", "the one on the left") to identify the target.
   Example: "Move to the chair next to that table."
4. Attribute-based
   Description: Describes the target using perceivable attributes (e.g., empty, with a vase, near a window).
   Example: "Find an empty table in the dining hall."
5. Area-based
   Description: Directs the robot to a functional area rather than a specific object.
   Example: "Walk from here to the kitchen area."

<Output_Format>
For each instruction type, generate 2-4 diverse instructions. Output as a JSON array:
[
  {
    "instruction_type": "Add_Object",
    "start": "[provided_starting_object_id]",
    "end": "[provided_end_object_id]",
    "generated_instruction": "[instruction_text]"
  },
  {
    "instruction_type": "Area-based",
    "trajectory_id": "[provided_id]",
    "start": "[provided_starting_object_id]",
    "end": "[provided_end_object_id]",
    "generated_instruction": "[instruction_text]"
  },
  ...
]"#;

/// Where and how to ask.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LlmConfig {
    /// Base URL of the API (`http://127.0.0.1:8000/v1`); `/chat/completions` is appended.
    pub base_url: String,
    /// Model name.
    pub model: String,
    /// Environment variable holding the API key (default `OPENAI_API_KEY`).
    pub api_key_env: String,
    /// Sampling temperature.
    pub temperature: f32,
    /// Retries after the first attempt.
    pub max_retries: u32,
    /// First backoff, milliseconds.
    pub backoff_ms: u64,
    /// Longest backoff, milliseconds (the published generator used 16 s).
    pub backoff_max_ms: u64,
    /// Timeout of one request, seconds.
    pub timeout_s: u64,
    /// Requests in flight at most.
    pub concurrency: usize,
    /// Answer cache folder (`None`: no cache).
    pub cache_dir: Option<PathBuf>,
}

impl Default for LlmConfig {
    fn default() -> Self {
        LlmConfig {
            base_url: "http://127.0.0.1:8000/v1".into(),
            model: "gpt-4o-mini".into(),
            api_key_env: "OPENAI_API_KEY".into(),
            temperature: 0.7,
            max_retries: 5,
            backoff_ms: 500,
            backoff_max_ms: 16_000,
            timeout_s: 180,
            concurrency: 4,
            cache_dir: None,
        }
    }
}

/// One element of the answer array.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LlmItem {
    /// Type name as written by the model.
    #[serde(default)]
    pub instruction_type: String,
    /// Start id as echoed.
    #[serde(default)]
    pub start: String,
    /// End id as echoed.
    #[serde(default)]
    pub end: String,
    /// The instruction.
    #[serde(default)]
    pub generated_instruction: String,
}

/// Request counters (for reports and tests).
#[derive(Debug, Default)]
pub struct LlmStats {
    /// HTTP requests sent (retries included).
    pub requests: AtomicUsize,
    /// Answers taken from the cache.
    pub cache_hits: AtomicUsize,
    /// Retries.
    pub retries: AtomicUsize,
}

/// A counting semaphore (std has none).
#[derive(Debug)]
struct Semaphore {
    free: Mutex<usize>,
    cv: Condvar,
}

impl Semaphore {
    fn acquire(&self) -> SemaphoreGuard<'_> {
        let mut n = self.free.lock().unwrap_or_else(|e| e.into_inner());
        while *n == 0 {
            n = self.cv.wait(n).unwrap_or_else(|e| e.into_inner());
        }
        *n -= 1;
        SemaphoreGuard(self)
    }
}

struct SemaphoreGuard<'a>(&'a Semaphore);

impl Drop for SemaphoreGuard<'_> {
    fn drop(&mut self) {
        *self.0.free.lock().unwrap_or_else(|e| e.into_inner()) += 1;
        self.0.cv.notify_one();
    }
}

/// A cached answer.
#[derive(Serialize, Deserialize)]
struct CacheEntry {
    url: String,
    request: serde_json::Value,
    content: String,
}

/// The client (share one across threads).
#[derive(Debug)]
pub struct LlmClient {
    config: LlmConfig,
    http: sage_http::Client,
    gate: Semaphore,
    /// Counters.
    pub stats: LlmStats,
}

/// Parses the model's answer: the JSON array in it (code fences and prose around it ignored).
pub fn parse_answer(content: &str) -> Option<Vec<LlmItem>> {
    let (a, b) = (content.find('[')?, content.rfind(']')?);
    let values: Vec<serde_json::Value> = serde_json::from_str(content.get(a..=b)?).ok()?;
    Some(
        values
            .into_iter()
            .map(|v| serde_json::from_value(v).unwrap_or_default())
            .collect(),
    )
}

impl LlmClient {
    /// A client for `config`.
    ///
    /// # Errors
    ///
    /// An `invalid` error for an empty URL or model, or a zero concurrency.
    pub fn new(config: LlmConfig) -> Result<LlmClient> {
        if config.base_url.trim().is_empty() || config.model.trim().is_empty() {
            return Err(Error::invalid("llm: base_url and model must be set"));
        }
        if config.concurrency == 0 {
            return Err(Error::invalid("llm: concurrency must be at least 1"));
        }
        let http = sage_http::Client::new(Duration::from_secs(config.timeout_s.max(1)));
        Ok(LlmClient {
            gate: Semaphore {
                free: Mutex::new(config.concurrency),
                cv: Condvar::new(),
            },
            config,
            http,
            stats: LlmStats::default(),
        })
    }

    /// The chat-completions URL.
    pub fn url(&self) -> String {
        format!(
            "{}/chat/completions",
            self.config.base_url.trim_end_matches('/')
        )
    }

    /// The request body for a trajectory.
    pub fn request_body(
        &self,
        tm: &TextMap,
        start: &str,
        end: &str,
        trajectory_id: &str,
    ) -> serde_json::Value {
        let user = format!(
            "TEXT MAP:\n{}\nSTARTING POINT: \"starting_point\": \"{start}\"\nEND POINT: \"end_point\": \"{end}\"\nTRAJECTORY ID: \"{trajectory_id}\"\n",
            tm.to_text()
        );
        // The f32's shortest decimal: widened, 0.7 would go out as 0.699999988079071.
        let t = self.config.temperature;
        let temperature: f64 = t.to_string().parse().unwrap_or_else(|_| f64::from(t));
        serde_json::json!({
            "model": self.config.model,
            "temperature": temperature,
            "messages": [
                {"role": "system", "content": PROMPT},
                {"role": "user", "content": user},
            ],
        })
    }

    fn cache_path(&self, url: &str, body: &str) -> Option<PathBuf> {
        let dir = self.config.cache_dir.as_ref()?;
        let key = sage_io::hash::fnv1a64(format!("{url}\n{body}").as_bytes());
        Some(dir.join(format!("{key:016x}.json")))
    }

    /// Asks for the instructions of one trajectory (cache first); returns the parsed array.
    ///
    /// # Errors
    ///
    /// When every attempt failed: the last HTTP status or transport error, naming the URL.
    pub fn ask(
        &self,
        tm: &TextMap,
        start: &str,
        end: &str,
        trajectory_id: &str,
    ) -> Result<Vec<LlmItem>> {
        let url = self.url();
        let request = self.request_body(tm, start, end, trajectory_id);
        let body = request.to_string();
        let cache = self.cache_path(&url, &body);
        if let Some(path) = &cache
            && let Ok(text) = std::fs::read_to_string(path)
            && let Ok(entry) = serde_json::from_str::<CacheEntry>(&text)
            && entry.url == url
            && entry.request == request
            && let Some(items) = parse_answer(&entry.content)
        {
            self.stats.cache_hits.fetch_add(1, Ordering::Relaxed);
            return Ok(items);
        }
        let (content, items) = self
            .retry_policy()
            .run(
                |attempt| {
                    if attempt > 0 {
                        self.stats.retries.fetch_add(1, Ordering::Relaxed);
                    }
                    let content = {
                        let _permit = self.gate.acquire();
                        self.stats.requests.fetch_add(1, Ordering::Relaxed);
                        self.post(&url, &body)?
                    };
                    let items = parse_answer(&content)
                        .ok_or_else(|| Failure::new("the answer holds no JSON array"))?;
                    Ok((content, items))
                },
                |_, _| {},
                std::thread::sleep,
            )
            .map_err(|gave_up| {
                Error::invalid(format!(
                    "llm: {url}: no usable answer after {} attempts: {}",
                    gave_up.attempts, gave_up.last.message
                ))
            })?;
        if let Some(path) = &cache {
            if let Some(dir) = path.parent() {
                std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            }
            sage_io::files::write_json(
                path,
                &CacheEntry {
                    url,
                    request,
                    content,
                },
            )?;
        }
        Ok(items)
    }

    /// The retry policy of the config. Every failure is tried again, a 4xx included: a model
    /// server behind a proxy or still loading answers wrongly now and then, and a request that
    /// is really wrong fails after `max_retries` all the same.
    fn retry_policy(&self) -> RetryPolicy {
        RetryPolicy {
            retries: self.config.max_retries,
            initial: Duration::from_millis(self.config.backoff_ms),
            cap: Duration::from_millis(self.config.backoff_max_ms),
            retry_on: RetryOn::Any,
        }
    }

    /// One POST; the message content, or the failure (with the server's `Retry-After`).
    fn post(&self, url: &str, body: &str) -> std::result::Result<String, Failure> {
        let key = std::env::var(&self.config.api_key_env)
            .ok()
            .filter(|k| !k.is_empty());
        let text = self
            .http
            .post_json(url, body, key.as_deref())
            .map_err(|e| {
                let stage = match e.stage {
                    Stage::Request => "transport",
                    Stage::Body => "reading the answer",
                };
                e.failure(format!("{stage}: {e}"))
            })?
            .into_ok()?;
        serde_json::from_str::<serde_json::Value>(&text)
            .ok()
            .and_then(|v| {
                v.pointer("/choices/0/message/content")
                    .and_then(|c| c.as_str())
                    .map(str::to_string)
            })
            .ok_or_else(|| Failure::new("the answer has no choices[0].message.content"))
    }
}

/// Turns the parsed answer into instructions: known high-level type, the asked start and end,
/// valid text, no duplicate; every item is counted in `report`.
pub fn accept(
    items: &[LlmItem],
    start: &str,
    end: &str,
    validator: &Validator,
    report: &mut ValidationReport,
) -> Vec<Instruction> {
    let mut seen = BTreeSet::new();
    let mut out = Vec::new();
    for item in items {
        let kind = InstructionType::parse(&item.instruction_type)
            .filter(|k| InstructionType::HIGH.contains(k));
        let outcome = match kind {
            None => Err(RejectReason::UnknownType),
            Some(_) if item.start.trim() != start || item.end.trim() != end => {
                Err(RejectReason::EndpointMismatch)
            }
            Some(k) => validator
                .check(&item.generated_instruction, k)
                .and_then(|()| {
                    if seen.insert(item.generated_instruction.trim().to_lowercase()) {
                        Ok(())
                    } else {
                        Err(RejectReason::Duplicate)
                    }
                }),
        };
        report.record(outcome);
        if let (Ok(()), Some(kind)) = (outcome, kind) {
            out.push(Instruction {
                text: item.generated_instruction.trim().to_string(),
                kind,
                subtype: None,
                source: Source::Llm,
            });
        }
    }
    out
}
