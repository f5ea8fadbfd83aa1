//! The LLM backend against a small OpenAI-compatible HTTP server on loopback (no network):
//! request shape, parsing, retry with backoff, the answer cache and the concurrency limit.

use sage_lang::llm::{LlmClient, LlmConfig, accept};
use sage_lang::validate::ValidationReport;
use sage_lang::{InstructionType, TextMap, Validator};
use sage_nav::trajectory::{self, TrajectoryParams};
use sage_synth::{SynthConfig, generate};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// What the server saw and how it behaves.
#[derive(Default)]
struct ServerState {
    requests: AtomicUsize,
    fail_first: AtomicUsize,
    in_flight: AtomicUsize,
    max_in_flight: AtomicUsize,
    delay_ms: AtomicUsize,
    authorization: Mutex<Option<String>>,
    bodies: Mutex<Vec<serde_json::Value>>,
}

/// Header names (lower case) and values.
type Headers = Vec<(String, String)>;

/// Reads one HTTP/1.1 request: (path, headers, body).
fn read_request(stream: &mut TcpStream) -> Option<(String, Headers, Vec<u8>)> {
    let mut reader = BufReader::new(stream.try_clone().ok()?);
    let mut line = String::new();
    reader.read_line(&mut line).ok()?;
    let path = line.split_whitespace().nth(1)?.to_string();
    let mut headers = Vec::new();
    loop {
        let mut h = String::new();
        reader.read_line(&mut h).ok()?;
        let h = h.trim_end();
        if h.is_empty() {
            break;
        }
        let (k, v) = h.split_once(':')?;
        headers.push((k.trim().to_lowercase(), v.trim().to_string()));
    }
    let len: usize = headers
        .iter()
        .find(|(k, _)| k == "content-length")?
        .1
        .parse()
        .ok()?;
    let mut body = vec![0; len];
    reader.read_exact(&mut body).ok()?;
    Some((path, headers, body))
}

fn respond(stream: &mut TcpStream, status: &str, extra: &str, body: &str) {
    let _ = write!(
        stream,
        "HTTP/1.1 {status}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n{extra}\r\n{body}",
        body.len()
    );
}

/// The model's answer: one instruction per type plus three bad ones (an id, a wrong type, a
/// wrong start), inside a code fence as chat models often write it.
fn answer(start: &str, end: &str) -> String {
    let item = |t: &str, s: &str, text: &str| serde_json::json!({"instruction_type": t, "start": s, "end": end, "generated_instruction": text});
    let items = vec![
        item(
            "Add_Object",
            start,
            "Please carry this bag over to the far side of the room.",
        ),
        item(
            "Scenario_Driven",
            start,
            "I'm tired after work, please take me somewhere to rest.",
        ),
        item(
            "Relative_Relationship",
            start,
            "Walk to the spot next to the door and wait there.",
        ),
        item(
            "Area-based",
            start,
            "Walk from here to the quiet area by the door.",
        ),
        item(
            "Area-based",
            start,
            &format!("Walk from here to {end} and wait for me there."),
        ),
        item(
            "Seventh_Type",
            start,
            "Walk from here to the quiet area by the door please.",
        ),
        item(
            "Add_Object",
            "somewhere_else",
            "Please carry this bag over to the far side of the hall.",
        ),
    ];
    format!(
        "Here you go:\n```json\n{}\n```",
        serde_json::to_string_pretty(&items).unwrap()
    )
}

fn serve(state: Arc<ServerState>) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { continue };
            let state = state.clone();
            std::thread::spawn(move || {
                let Some((path, headers, body)) = read_request(&mut stream) else {
                    return;
                };
                let n = state.requests.fetch_add(1, Ordering::SeqCst);
                let now = state.in_flight.fetch_add(1, Ordering::SeqCst) + 1;
                state.max_in_flight.fetch_max(now, Ordering::SeqCst);
                std::thread::sleep(Duration::from_millis(
                    state.delay_ms.load(Ordering::SeqCst) as u64
                ));
                *state.authorization.lock().unwrap() = headers
                    .iter()
                    .find(|(k, _)| k == "authorization")
                    .map(|(_, v)| v.clone());
                let request: serde_json::Value = serde_json::from_slice(&body).unwrap_or_default();
                state.bodies.lock().unwrap().push(request.clone());
                state.in_flight.fetch_sub(1, Ordering::SeqCst);
                if path != "/v1/chat/completions" {
                    return respond(&mut stream, "404 Not Found", "", "{}");
                }
                if n < state.fail_first.load(Ordering::SeqCst) {
                    return respond(
                        &mut stream,
                        "503 Service Unavailable",
                        "Retry-After: 0\r\n",
                        "{\"error\":\"busy\"}",
                    );
                }
                let user = request
                    .pointer("/messages/1/content")
                    .and_then(|c| c.as_str())
                    .unwrap_or("");
                let id_after = |key: &str| {
                    user.split(key)
                        .nth(1)
                        .and_then(|r| r.split('"').nth(3))
                        .unwrap_or("")
                        .to_string()
                };
                let content = answer(&id_after("STARTING POINT:"), &id_after("END POINT:"));
                let body = serde_json::json!({"id": "x", "object": "chat.completion", "choices": [{"index": 0, "message": {"role": "assistant", "content": content}, "finish_reason": "stop"}]});
                respond(&mut stream, "200 OK", "", &body.to_string());
            });
        }
    });
    format!("http://{addr}/v1")
}

fn text_map() -> TextMap {
    let s = generate(&SynthConfig {
        seed: 7,
        rooms: 4,
        objects: 40,
        gaussians: 1000,
        ..SynthConfig::default()
    })
    .unwrap();
    let prep = trajectory::prepare(&s, &TrajectoryParams::default()).unwrap();
    TextMap::build(&s, &prep.map, &prep.endpoints)
}

fn config(url: String, cache: Option<std::path::PathBuf>) -> LlmConfig {
    LlmConfig {
        base_url: url,
        model: "test-model".into(),
        api_key_env: "SAGE3D_LLM_TEST_KEY".into(),
        backoff_ms: 1,
        backoff_max_ms: 5,
        cache_dir: cache,
        ..LlmConfig::default()
    }
}

#[test]
fn asks_with_the_prompt_parses_and_validates() {
    let state = Arc::new(ServerState::default());
    let client = LlmClient::new(config(serve(state.clone()), None)).unwrap();
    let tm = text_map();
    let (start, end) = (tm.objects[0].item_id.clone(), tm.objects[1].item_id.clone());
    let items = client.ask(&tm, &start, &end, "4").unwrap();
    assert_eq!(items.len(), 7);
    let body = state.bodies.lock().unwrap()[0].clone();
    assert_eq!(body["model"], "test-model");
    assert_eq!(body["temperature"], 0.7);
    assert_eq!(body["messages"][0]["content"], sage_lang::llm::PROMPT);
    let user = body["messages"][1]["content"].as_str().unwrap();
    assert!(
        user.contains(&tm.to_text()) && user.contains(&format!("\"starting_point\": \"{start}\""))
    );
    let mut report = ValidationReport::default();
    let got = accept(&items, &start, &end, &Validator::new(&tm), &mut report);
    let kinds: Vec<InstructionType> = got.iter().map(|i| i.kind).collect();
    assert_eq!(
        kinds,
        [
            InstructionType::AddObject,
            InstructionType::ScenarioDriven,
            InstructionType::RelativeRelationship,
            InstructionType::AreaBased
        ]
    );
    assert_eq!((report.checked, report.accepted), (7, 4));
    assert_eq!(report.rejected.get("internal_id"), Some(&1));
    assert_eq!(report.rejected.get("unknown_type"), Some(&1));
    assert_eq!(report.rejected.get("endpoint_mismatch"), Some(&1));
}

#[test]
fn retries_server_errors_then_succeeds_and_sends_the_key() {
    let state = Arc::new(ServerState::default());
    state.fail_first.store(2, Ordering::SeqCst);
    // SAFETY: the variable is read only by the clients of this test.
    unsafe { std::env::set_var("SAGE3D_LLM_TEST_KEY", "sk-test") };
    let client = LlmClient::new(config(serve(state.clone()), None)).unwrap();
    let tm = text_map();
    let items = client.ask(&tm, "a", "b", "0").unwrap();
    assert_eq!(items.len(), 7);
    assert_eq!(state.requests.load(Ordering::SeqCst), 3);
    assert_eq!(client.stats.retries.load(Ordering::SeqCst), 2);
    assert_eq!(
        state.authorization.lock().unwrap().as_deref(),
        Some("Bearer sk-test")
    );

    let always = Arc::new(ServerState::default());
    always.fail_first.store(usize::MAX, Ordering::SeqCst);
    let url = serve(always.clone());
    let client = LlmClient::new(LlmConfig {
        max_retries: 2,
        ..config(url.clone(), None)
    })
    .unwrap();
    let e = client.ask(&tm, "a", "b", "0").unwrap_err().to_string();
    assert!(
        e.contains(&url) && e.contains("503") && e.contains("3 attempts"),
        "{e}"
    );
    assert_eq!(always.requests.load(Ordering::SeqCst), 3);
}

#[test]
fn cached_answers_make_no_request() {
    let state = Arc::new(ServerState::default());
    let url = serve(state.clone());
    let dir = tempfile::tempdir().unwrap();
    let tm = text_map();
    let first = LlmClient::new(config(url.clone(), Some(dir.path().into()))).unwrap();
    let a = first.ask(&tm, "a", "b", "0").unwrap();
    assert_eq!(state.requests.load(Ordering::SeqCst), 1);
    let second = LlmClient::new(config(url.clone(), Some(dir.path().into()))).unwrap();
    assert_eq!(second.ask(&tm, "a", "b", "0").unwrap(), a);
    assert_eq!(state.requests.load(Ordering::SeqCst), 1);
    assert_eq!(second.stats.cache_hits.load(Ordering::SeqCst), 1);
    second.ask(&tm, "a", "c", "0").unwrap();
    assert_eq!(state.requests.load(Ordering::SeqCst), 2);
    // A different model is a different request.
    let third = LlmClient::new(LlmConfig {
        model: "other".into(),
        ..config(url, Some(dir.path().into()))
    })
    .unwrap();
    third.ask(&tm, "a", "b", "0").unwrap();
    assert_eq!(state.requests.load(Ordering::SeqCst), 3);
}

#[test]
fn never_more_requests_in_flight_than_the_limit() {
    let state = Arc::new(ServerState::default());
    state.delay_ms.store(60, Ordering::SeqCst);
    let client = Arc::new(
        LlmClient::new(LlmConfig {
            concurrency: 2,
            ..config(serve(state.clone()), None)
        })
        .unwrap(),
    );
    let tm = Arc::new(text_map());
    let handles: Vec<_> = (0..6)
        .map(|i| {
            let (client, tm) = (client.clone(), tm.clone());
            std::thread::spawn(move || client.ask(&tm, "a", &format!("g{i}"), "0").unwrap().len())
        })
        .collect();
    for h in handles {
        assert_eq!(h.join().unwrap(), 7);
    }
    assert_eq!(state.requests.load(Ordering::SeqCst), 6);
    assert!(state.max_in_flight.load(Ordering::SeqCst) <= 2);
}
