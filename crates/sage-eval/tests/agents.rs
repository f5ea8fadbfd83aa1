//! The evaluator's replay and remote agents on a small generated dataset.
//!
//! Replay: the oracle's recorded actions reproduce its metrics exactly; its recorded poses,
//! driven through physics, end where it ended. Remote: real servers on loopback speak the
//! SAGE socket protocol, HTTP `/vln_step` and OpenAI-compatible chat; the test checks the
//! framing, that the images are JPEGs of the configured size and are the real recent frames,
//! and that faults are retried and recorded, or fail the episode while the run goes on.

mod common;

use base64::Engine;
use base64::engine::general_purpose::STANDARD;

use sage_env::SceneContext;
use sage_env::agents::{FaultKind, OracleAgent, run_episode};
use sage_env::{Env, EnvConfig, SensorConfig};
use sage_eval::{EvalRecord, EvalSettings, Failure, RunOutcome};
use sage_metrics::Mode;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

/// One small home and its dataset, built once per test process: (temp dir, scenes, dataset).
fn fixture() -> &'static (tempfile::TempDir, PathBuf, PathBuf) {
    static F: OnceLock<(tempfile::TempDir, PathBuf, PathBuf)> = OnceLock::new();
    F.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let (scenes, home, data) = common::small_dataset(dir.path(), 0);
        // Fill the hull cache beside the scene once: the tests' runs then only read it.
        SceneContext::load(&home, None).unwrap();
        (dir, scenes, data)
    })
}

fn settings(agent: &str) -> EvalSettings {
    let (_, scenes, data) = fixture();
    EvalSettings {
        dataset: data.clone(),
        scenes: scenes.clone(),
        split: "train".into(),
        agent: agent.parse().unwrap(),
        mode: Mode::Sage,
        dtw: Default::default(),
        seed: 0,
        preset: "sage".into(),
        device: Default::default(),
        splat_bodies: Default::default(),
    }
}

/// Runs an evaluation on one thread (episodes in file order, as the scripted servers expect)
/// and returns the outcome and the records by episode id.
fn evaluate(agent: &str, out: &Path) -> (RunOutcome, BTreeMap<String, EvalRecord>) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let outcome = pool
        .install(|| sage_eval::run(&settings(agent), out, &|_, _| {}))
        .unwrap();
    let records = std::fs::read_to_string(out.join(sage_eval::folder::RECORDS_FILE))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<EvalRecord>(l).unwrap())
        .map(|r| (r.episode_id.clone(), r))
        .collect();
    (outcome, records)
}

/// The oracle's evaluation (outcome and records), run once per test process.
fn oracle_run() -> &'static (RunOutcome, BTreeMap<String, EvalRecord>) {
    static O: OnceLock<(RunOutcome, BTreeMap<String, EvalRecord>)> = OnceLock::new();
    O.get_or_init(|| {
        evaluate(
            "oracle",
            &tempfile::tempdir().unwrap().path().join("oracle"),
        )
    })
}

/// The oracle's actions per VLN episode, from the environment directly.
fn oracle_actions() -> BTreeMap<String, Vec<sage_env::Action>> {
    let (_, scenes, data) = fixture();
    let ctx = Arc::new(SceneContext::load(&scenes.join("home1"), None).unwrap());
    let config = EnvConfig {
        sensors: SensorConfig {
            rgb: false,
            depth: false,
            ..SensorConfig::default()
        },
        ..EnvConfig::default()
    };
    let (_, episodes) = sage_dataset::folder::split_episodes(data, "train").unwrap();
    episodes
        .iter()
        .filter(|e| e.goal.is_some())
        .map(|e| {
            let mut env = Env::new(ctx.clone(), config.clone()).unwrap();
            let mut agent = OracleAgent::new(0.25);
            let trace = run_episode(&mut env, &mut agent, &e.env_episode()).unwrap();
            let actions = trace.steps.iter().map(|s| s.action).collect();
            (e.episode_id.clone(), actions)
        })
        .collect()
}

fn write_lines(path: &Path, lines: &[Value]) {
    let text: String = lines.iter().map(|l| format!("{l}\n")).collect();
    std::fs::write(path, text).unwrap();
}

#[test]
fn replayed_oracle_actions_reproduce_its_metrics_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let (oracle_outcome, oracle) = oracle_run();
    let actions = oracle_actions();
    assert!(actions.len() >= 3);
    // Every notation: lower-case names, upper-case names, VLN-CE indices, action objects.
    let lines: Vec<Value> = actions
        .iter()
        .enumerate()
        .map(|(i, (id, acts))| {
            let acts: Vec<Value> = acts
                .iter()
                .map(|a| {
                    let obj = serde_json::to_value(a).unwrap();
                    let name = obj["type"].as_str().unwrap().to_string();
                    let index = ["stop", "move_forward", "turn_left", "turn_right"]
                        .iter()
                        .position(|n| *n == name)
                        .unwrap();
                    match i % 4 {
                        0 => json!(name),
                        1 => json!(name.to_uppercase()),
                        2 => json!(index),
                        _ => obj,
                    }
                })
                .collect();
            json!({"episode_id": id, "actions": acts})
        })
        .collect();
    let file = dir.path().join("actions.jsonl");
    write_lines(&file, &lines);
    let agent = format!("replay:{}", file.display());
    let (outcome, replayed) = evaluate(&agent, &dir.path().join("replay"));
    assert_eq!(outcome.summary.agent, agent);
    for (id, rec) in &replayed {
        let o = &oracle[id];
        if actions.contains_key(id) {
            assert_eq!(rec.error, None, "{id}");
            assert_eq!(rec.metrics, o.metrics, "{id}");
            assert_eq!(rec.record, o.record, "{id}");
            assert_eq!(rec.termination, o.termination, "{id}");
        } else {
            // No-goal episodes are not in the file: recorded with a clear error.
            let e = rec.error.as_deref().unwrap();
            assert!(
                e.contains("has no episode") && e.contains(id.as_str()),
                "{e}"
            );
        }
    }
    assert_eq!(outcome.summary.overall, oracle_outcome.summary.overall);
    assert_eq!(outcome.summary.slices, oracle_outcome.summary.slices);
}

#[test]
fn replayed_oracle_poses_end_where_the_oracle_ended() {
    let dir = tempfile::tempdir().unwrap();
    let (_, oracle) = oracle_run();
    let scored: Vec<&EvalRecord> = oracle.values().filter(|r| r.record.is_some()).collect();
    assert!(scored.len() >= 3);
    // Three shapes: [x, y, yaw]; [x, y, z, yaw]; the start pose first (skipped).
    let lines: Vec<Value> = scored
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let rec = r.record.as_ref().unwrap();
            let mut poses: Vec<Value> = rec
                .steps
                .iter()
                .map(|s| match i % 3 {
                    1 => json!([s.position[0], s.position[1], s.position[2], s.yaw]),
                    _ => json!([s.position[0], s.position[1], s.yaw]),
                })
                .collect();
            if i % 3 == 2 {
                poses.insert(0, json!([rec.start[0], rec.start[1], rec.start_yaw]));
            }
            json!({"episode_id": r.episode_id, "poses": poses})
        })
        .collect();
    let file = dir.path().join("poses.jsonl");
    write_lines(&file, &lines);
    let (_, replayed) = evaluate(
        &format!("replay:{}", file.display()),
        &dir.path().join("replay"),
    );
    for r in scored {
        let mine = &replayed[&r.episode_id];
        assert_eq!(mine.error, None);
        let (a, b) = (r.record.as_ref().unwrap(), mine.record.as_ref().unwrap());
        // One step per pose, then STOP; a first pose at the start (the oracle stopped at
        // once) is the start itself and is skipped.
        let at_start =
            (a.steps[0].position[0] - a.start[0]).hypot(a.steps[0].position[1] - a.start[1]) < 0.01
                && (a.steps[0].yaw - a.start_yaw).abs() < 0.017;
        assert_eq!(
            b.steps.len(),
            a.steps.len() + 1 - usize::from(at_start),
            "{}",
            r.episode_id
        );
        let (pa, pb) = (
            a.steps.last().unwrap().position,
            b.steps.last().unwrap().position,
        );
        let gap = (pa[0] - pb[0]).hypot(pa[1] - pb[1]);
        assert!(gap < 0.05, "{}: ended {gap} m away", r.episode_id);
        assert_eq!(
            mine.metrics.as_ref().unwrap().sr,
            r.metrics.as_ref().unwrap().sr
        );
    }
}

#[test]
fn bad_replay_files_name_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad.jsonl");
    for (lines, says) in [
        (
            "{\"episode_id\": \"a\", \"actions\": [\"stop\"]}\n{\"episode_id\": \"b\", \"actions\": [\"fly_away\"]}\n",
            "line 2, actions[0]",
        ),
        (
            "{\"episode_id\": \"a\", \"poses\": [[1, 2]]}\n",
            "line 1, poses[0]",
        ),
        ("{\"actions\": []}\n", "line 1, episode_id"),
        ("not json\n", "line 1"),
        (
            "{\"episode_id\": \"a\", \"actions\": [1]}\n{\"episode_id\": \"a\", \"actions\": [2]}\n",
            "given twice",
        ),
        (
            "{\"episode_id\": \"a\", \"actions\": [1]}\n{\"episode_id\": \"b\", \"poses\": [[0, 0, 0]]}\n",
            "one action space",
        ),
    ] {
        std::fs::write(&file, lines).unwrap();
        let agent = format!("replay:{}", file.display());
        let e = sage_eval::run(&settings(&agent), &dir.path().join("run"), &|_, _| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("bad.jsonl") && e.contains(says), "{says}: {e}");
    }
}

// ---- Remote agents: real servers on loopback. ----

/// One request as a server saw it: the JSON body (or the chat request) and its images decoded.
#[derive(Debug, Clone)]
struct Seen {
    body: Value,
    images: Vec<String>,
}

/// Decodes a base64 JPEG; returns (width, height).
fn jpeg_size(b64: &str) -> (usize, usize) {
    let bytes = STANDARD.decode(b64).expect("base64");
    let mut d = zune_jpeg::JpegDecoder::new(&bytes);
    d.decode().expect("a JPEG");
    let (w, h) = d.dimensions().unwrap();
    (w, h)
}

/// A scripted navigator: per episode (a request with one image starts one) the replies in
/// order, the last repeated.
fn script(seen: &Mutex<Vec<Seen>>, replies: &[Value]) -> Value {
    let seen = seen.lock().unwrap();
    let k = seen.iter().rev().take_while(|s| s.images.len() > 1).count();
    replies[k.min(replies.len() - 1)].clone()
}

/// Reads one socket-protocol frame.
fn read_frame(s: &mut TcpStream) -> Option<Vec<u8>> {
    let mut len = [0u8; 8];
    s.read_exact(&mut len).ok()?;
    let mut body = vec![0u8; u64::from_be_bytes(len) as usize];
    s.read_exact(&mut body).ok()?;
    Some(body)
}

fn write_frame(s: &mut TcpStream, body: &[u8]) {
    let _ = s.write_all(&(body.len() as u64).to_be_bytes());
    let _ = s.write_all(body);
}

/// What a socket server does with the n-th connection.
#[derive(Clone, Copy, Debug)]
enum Fault {
    CloseEarly,
    HugeLength,
    NotJson,
    /// Never answer: hold the connection until the client gives up and closes it.
    Silent,
    Serve,
}

/// A SAGE socket-protocol server on loopback; `fault(n)` says how it treats connection n.
fn socket_server(
    replies: Vec<Value>,
    fault: impl Fn(usize) -> Fault + Send + 'static,
) -> (u16, Arc<Mutex<Vec<Seen>>>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let state = seen.clone();
    std::thread::spawn(move || {
        for (n, stream) in listener.incoming().enumerate() {
            let Ok(mut s) = stream else { continue };
            let Some(body) = read_frame(&mut s) else {
                continue;
            };
            let body: Value = serde_json::from_slice(&body).expect("the request is JSON");
            let fault = fault(n);
            if let Fault::Silent = fault {
                // Wait on its own thread for the client to close (its timeout), so the retry is
                // served at once; no clock of this side decides anything.
                std::thread::spawn(move || {
                    let mut sink = [0u8; 64];
                    while matches!(s.read(&mut sink), Ok(n) if n > 0) {}
                });
                continue;
            }
            match fault {
                Fault::CloseEarly => {
                    let _ = s.write_all(&[0, 0, 0]);
                    continue;
                }
                Fault::HugeLength => {
                    let _ = s.write_all(&u64::MAX.to_be_bytes());
                    continue;
                }
                Fault::NotJson => {
                    write_frame(&mut s, b"<html>busy</html>");
                    continue;
                }
                Fault::Silent | Fault::Serve => {}
            }
            let images: Vec<String> = body["images"]
                .as_array()
                .unwrap()
                .iter()
                .map(|i| i.as_str().unwrap().to_string())
                .collect();
            state.lock().unwrap().push(Seen { body, images });
            let reply = script(&state, &replies);
            write_frame(&mut s, reply.to_string().as_bytes());
        }
    });
    (port, seen)
}

/// The navigator of the remote tests: NaVILA's text (3 forward steps), then a turn, then STOP.
fn navila() -> Vec<Value> {
    vec![
        json!({"status": "success", "result": "The next action is move forward 75 cm."}),
        json!({"status": "success", "result": "The next action is turn left 30 degrees."}),
        json!({"status": "success", "result": "The next action is stop."}),
    ]
}

/// Checks the requests of one episode-by-episode run: instruction, JPEG sizes, history growth
/// (current frame last) and that the frames are the real, changing views.
fn check_history(seen: &[Seen], instructions: &[String], history: usize) {
    let (mut episodes, mut moved) = (0, 0);
    let mut episode: Vec<&Seen> = Vec::new();
    for s in seen.iter().chain(std::iter::once(&Seen {
        body: Value::Null,
        images: vec![],
    })) {
        if s.images.len() <= 1 && !episode.is_empty() {
            // Requests at steps 0, 3 (after three forwards) and 5 (after two turns); a
            // no-goal episode may end sooner, at its first collision.
            let counts: Vec<usize> = episode.iter().map(|s| s.images.len()).collect();
            assert_eq!(counts, [1, 4.min(history), 6.min(history)][..counts.len()]);
            let first = &episode[0].images[0];
            assert!(instructions.contains(&query(&episode[0].body)));
            for s in &episode {
                assert_eq!(query(&s.body), query(&episode[0].body));
                for img in &s.images {
                    assert_eq!(jpeg_size(img), (224, 224));
                }
            }
            // The oldest frame of the second request is the first frame; the current one
            // differs after moving (unless a wall was in the way) and always after turning.
            if let [_, second, third] = &episode[..] {
                episodes += 1;
                if history >= 4 {
                    assert_eq!(&second.images[0], first);
                }
                moved += usize::from(second.images.last() != Some(first));
                assert_ne!(third.images.last(), second.images.last());
                // Step 3's frame sits two before the current one (step 5).
                let n = third.images.len();
                if n >= 3 {
                    assert_eq!(third.images[n - 3], *second.images.last().unwrap());
                }
            }
            episode.clear();
        }
        episode.push(s);
    }
    assert!(
        episodes >= 3 && moved >= 2,
        "{episodes} episodes, {moved} moved"
    );
}

fn query(body: &Value) -> String {
    body.get("query")
        .or_else(|| body.get("instruction"))
        .and_then(Value::as_str)
        .unwrap()
        .to_string()
}

fn instructions() -> Vec<String> {
    let (_, episodes) = sage_dataset::folder::split_episodes(&fixture().2, "train").unwrap();
    episodes.iter().map(|e| e.instruction.clone()).collect()
}

/// Every episode ran 3 forwards, 2 left turns and STOP.
fn check_scripted_records(records: &BTreeMap<String, EvalRecord>) {
    for r in records.values() {
        assert_eq!(r.error, None, "{}", r.episode_id);
        let steps = &r.record.as_ref().unwrap().steps;
        if r.task == sage_dataset::Task::Vln {
            assert_eq!(r.termination, Some(sage_env::Termination::Stop));
            assert_eq!(steps.len(), 6, "{}", r.episode_id);
        }
    }
}

#[test]
fn socket_agent_sends_framed_jpeg_history_and_follows_the_replies() {
    let (port, seen) = socket_server(navila(), |_| Fault::Serve);
    let dir = tempfile::tempdir().unwrap();
    let (outcome, records) = evaluate(
        &format!("socket:127.0.0.1:{port}?history=5"),
        &dir.path().join("run"),
    );
    assert_eq!(outcome.summary.failed, Vec::<String>::new());
    check_scripted_records(&records);
    assert!(records.values().all(|r| r.faults.is_empty()));
    check_history(&seen.lock().unwrap(), &instructions(), 5);
}

#[test]
fn socket_faults_are_retried_and_recorded_and_a_dead_server_fails_episodes_not_the_run() {
    // The first episode's first request meets every fault once, then a good reply.
    let faults = [
        Fault::CloseEarly,
        Fault::HugeLength,
        Fault::NotJson,
        Fault::Silent,
    ];
    let (port, _) = socket_server(navila(), move |n| {
        faults.get(n).copied().unwrap_or(Fault::Serve)
    });
    let dir = tempfile::tempdir().unwrap();
    let (_, records) = evaluate(
        // A timeout far above any reply time of a loaded machine: only the silent connection
        // reaches it.
        &format!("socket:127.0.0.1:{port}?timeout=5&retries=4"),
        &dir.path().join("run"),
    );
    check_scripted_records(&records);
    let faulty: Vec<&EvalRecord> = records.values().filter(|r| !r.faults.is_empty()).collect();
    assert_eq!(faulty.len(), 1);
    let f = &faulty[0].faults;
    assert_eq!(f.len(), 4, "{f:?}");
    for (fault, says) in f
        .iter()
        .zip(["disconnected", "bad framing", "not JSON", "timed out"])
    {
        assert!(fault.message.contains(says) && fault.step == 0, "{fault}");
        assert_eq!(fault.kind, FaultKind::Transport, "{fault}");
        assert!(fault.recovered, "a later attempt succeeded: {fault}");
    }
    assert_eq!(faulty[0].failure, None);

    // Garbage every time: each episode fails naming the server; the run still finishes.
    let (port, _) = socket_server(vec![json!({"result": "I would rather not."})], |_| {
        Fault::Serve
    });
    let (outcome, records) = evaluate(
        &format!("socket:127.0.0.1:{port}?retries=1"),
        &dir.path().join("garbage"),
    );
    assert_eq!(outcome.summary.failed.len(), records.len());
    for r in records.values() {
        let e = r.error.as_deref().unwrap();
        assert!(
            e.contains(&format!("127.0.0.1:{port}"))
                && e.contains("after 2 attempts")
                && e.contains("unparseable"),
            "{e}"
        );
        assert_eq!(r.faults.len(), 2);
        assert!(
            r.faults
                .iter()
                .all(|f| f.kind == FaultKind::Unparseable && !f.recovered)
        );
        assert_eq!(r.failure, Some(Failure::ModelServer));
    }
    assert_eq!(
        outcome.summary.failures,
        [(Failure::ModelServer, records.len())].into()
    );
    assert_eq!(
        outcome.summary.faults,
        [(FaultKind::Unparseable, 2 * records.len())].into()
    );
    // Nothing was scored: the run did not do what was asked, strict or not.
    assert!(outcome.verdict(false).is_err());

    // Nobody listening: connection refused.
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let (_, records) = evaluate(
        &format!("socket:127.0.0.1:{port}?retries=0"),
        &dir.path().join("refused"),
    );
    assert!(
        records
            .values()
            .all(|r| r.error.as_deref().unwrap().contains("connect"))
    );
}

/// Reads one HTTP/1.1 request: (path, authorization header, body).
fn read_request(stream: &mut TcpStream) -> Option<(String, Vec<u8>)> {
    let mut reader = BufReader::new(stream.try_clone().ok()?);
    let mut line = String::new();
    reader.read_line(&mut line).ok()?;
    let path = line.split_whitespace().nth(1)?.to_string();
    let mut len = 0;
    loop {
        let mut h = String::new();
        reader.read_line(&mut h).ok()?;
        let h = h.trim_end();
        if h.is_empty() {
            break;
        }
        if let Some((k, v)) = h.split_once(':')
            && k.eq_ignore_ascii_case("content-length")
        {
            len = v.trim().parse().ok()?;
        }
    }
    let mut body = vec![0; len];
    reader.read_exact(&mut body).ok()?;
    Some((path, body))
}

fn respond(stream: &mut TcpStream, status: &str, body: &str) {
    let _ = write!(
        stream,
        "HTTP/1.1 {status}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
}

/// An HTTP server on loopback answering `path`; `images` finds the request's images and
/// `reply` wraps the scripted answer. The first `fail_first` requests get a 503.
fn http_server(
    path: &'static str,
    replies: Vec<Value>,
    images: fn(&Value) -> Vec<String>,
    reply: fn(&Value) -> Value,
    fail_first: usize,
) -> (String, Arc<Mutex<Vec<Seen>>>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let state = seen.clone();
    let count = AtomicUsize::new(0);
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut s) = stream else { continue };
            let Some((p, body)) = read_request(&mut s) else {
                continue;
            };
            if p != path {
                respond(&mut s, "404 Not Found", "{}");
                continue;
            }
            if count.fetch_add(1, Ordering::SeqCst) < fail_first {
                respond(
                    &mut s,
                    "503 Service Unavailable",
                    "{\"error\": \"loading\"}",
                );
                continue;
            }
            let body: Value = serde_json::from_slice(&body).expect("JSON request");
            let imgs = images(&body);
            state.lock().unwrap().push(Seen { body, images: imgs });
            let answer = reply(&script(&state, &replies));
            respond(&mut s, "200 OK", &answer.to_string());
        }
    });
    (format!("http://{addr}"), seen)
}

#[test]
fn http_vln_step_agent_posts_images_and_instruction() {
    let (url, seen) = http_server(
        "/vln_step",
        navila(),
        |b| {
            b["images"]
                .as_array()
                .unwrap()
                .iter()
                .map(|i| i.as_str().unwrap().to_string())
                .collect()
        },
        |r| json!({"result": r["result"]}),
        1,
    );
    let dir = tempfile::tempdir().unwrap();
    let (_, records) = evaluate(&format!("http:{url}"), &dir.path().join("run"));
    check_scripted_records(&records);
    let seen = seen.lock().unwrap();
    assert!(seen.iter().all(|s| s.body["current_yaw"] == 0.0));
    check_history(&seen, &instructions(), 8);
    // The 503 was retried and recorded on the first episode.
    let faults: Vec<&sage_env::agents::Fault> = records.values().flat_map(|r| &r.faults).collect();
    assert_eq!(faults.len(), 1);
    assert!(faults[0].message.contains("HTTP 503"), "{faults:?}");
    assert_eq!(faults[0].kind, FaultKind::Transport);
}

#[test]
fn chat_agent_sends_the_prompt_and_current_image_and_reads_action_words() {
    let replies = vec![
        json!("MOVE_FORWARD"),
        json!("MOVE_FORWARD"),
        json!("MOVE_FORWARD"),
        json!("TURN_LEFT"),
        json!("Action: TURN_LEFT"),
        json!("STOP"),
    ];
    let (url, seen) = http_server(
        "/v1/chat/completions",
        replies,
        |b| {
            b["messages"][1]["content"]
                .as_array()
                .unwrap()
                .iter()
                .filter_map(|c| c["image_url"]["url"].as_str())
                .map(|u| {
                    u.strip_prefix("data:image/jpeg;base64,")
                        .unwrap()
                        .to_string()
                })
                .collect()
        },
        |r| json!({"choices": [{"index": 0, "message": {"role": "assistant", "content": r}}]}),
        0,
    );
    let dir = tempfile::tempdir().unwrap();
    let (_, records) = evaluate(
        &format!("chat:test-vl@{url}/v1?history=2&max_tokens=8"),
        &dir.path().join("run"),
    );
    check_scripted_records(&records);
    let seen = seen.lock().unwrap();
    let instr = instructions();
    for s in seen.iter() {
        assert_eq!(s.body["model"], "test-vl");
        assert_eq!(s.body["max_tokens"], 8);
        let system = s.body["messages"][0]["content"].as_str().unwrap();
        assert!(system.contains("MOVE_FORWARD") && system.contains("STOP"));
        let text = s.body["messages"][1]["content"][0]["text"]
            .as_str()
            .unwrap();
        assert!(instr.iter().any(|i| text.contains(i.as_str())));
        assert!((1..=2).contains(&s.images.len()));
        for img in &s.images {
            assert_eq!(jpeg_size(img), (224, 224));
        }
    }
    // One request per step, the previous step's frame first.
    for w in seen.windows(2) {
        if w[1].images.len() == 2 {
            assert_eq!(w[1].images[0], *w[0].images.last().unwrap());
        }
    }
}
