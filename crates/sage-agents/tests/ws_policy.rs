//! The `ws:` agent against a policy server written here from GN0's protocol and openpi's
//! framing (not from the client): tungstenite on loopback, one thread per connection, msgpack
//! read with `rmpv` and NumPy maps taken apart by hand. The server checks every message it
//! receives (bin keys, dtype, shape, endpoint order, session ids, state) and scripts its
//! replies, faults included; the tests drive real episodes in a rendered synthetic scene.

use rmpv::Value;
use sage_agents::AgentKind;
use sage_env::agents::{Agent, FaultKind, run_episode};
use sage_env::{Action, Env, EnvConfig, EnvEpisode, SceneContext, SensorConfig, Termination};
use sage_nav::TrajectoryParams;
use sage_physics::{Decomposer, HullCache, SceneBodies};
use sage_synth::{SceneKind, SynthConfig, generate};
use std::io::Write;
use std::net::TcpListener;
use std::sync::{Arc, Mutex, OnceLock};
use tungstenite::protocol::CloseFrame;
use tungstenite::protocol::frame::coding::CloseCode;
use tungstenite::{Message, accept};

const W: usize = 32;
const H: usize = 24;

struct Fixture {
    ctx: Arc<SceneContext>,
    episodes: Vec<EnvEpisode>,
}

/// A small synthetic home with box bodies and planned episodes.
fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let mut scene = generate(&SynthConfig {
            seed: 5,
            kind: SceneKind::Home,
            rooms: 3,
            objects: 20,
            gaussians: 2000,
            ..SynthConfig::default()
        })
        .unwrap();
        for o in &mut scene.objects {
            o.mesh = None;
        }
        let cache = tempfile::tempdir().unwrap();
        let (bodies, _) = SceneBodies::build(
            &scene,
            &Decomposer::default(),
            &HullCache::new(cache.path()),
        )
        .unwrap();
        let params = TrajectoryParams {
            count: 4,
            seed: 1,
            ..TrajectoryParams::default()
        };
        let prep = sage_nav::trajectory::prepare(&scene, &params).unwrap();
        let (set, _) = sage_nav::trajectory::generate(&scene.name, &prep, &params).unwrap();
        let episodes = set
            .trajectories
            .iter()
            .map(|t| EnvEpisode::from_trajectory(format!("ep{}", t.id), t, "go to the goal"))
            .collect();
        let ctx = SceneContext::new(scene, bodies, &params.grid, params.cost.clone()).unwrap();
        Fixture {
            ctx: Arc::new(ctx),
            episodes,
        }
    })
}

fn env(max_steps: usize) -> Env {
    let mut config = EnvConfig {
        sensors: SensorConfig {
            width: W as u32,
            height: H as u32,
            rgb: true,
            depth: false,
            ..SensorConfig::default()
        },
        ..EnvConfig::default()
    };
    config.task.max_steps = max_steps;
    Env::new(fixture().ctx.clone(), config).unwrap()
}

/// What the server received, per message, as it understood it.
#[derive(Debug, Clone, PartialEq)]
enum Seen {
    Reset {
        conn: usize,
    },
    Infer {
        conn: usize,
        /// The images' shape (HWC or THWC).
        shape: Vec<usize>,
        session: String,
        instruction: String,
        /// `state.nav_pose`, when sent.
        state: Option<[f32; 3]>,
    },
}

/// How the server answers the n-th infer request (counted over all connections).
#[derive(Clone)]
enum Answer {
    /// A binary msgpack reply.
    Reply(Value),
    /// openpi's server on an exception: a traceback text frame, then close 1011.
    Traceback,
    /// A close frame instead of a reply.
    Close,
    /// Bytes that are not msgpack.
    Garbage,
    /// The header of a binary frame declaring 2⁶² bytes, and nothing after it.
    HugeFrame,
}

struct Server {
    port: u16,
    seen: Arc<Mutex<Vec<Seen>>>,
    violations: Arc<Mutex<Vec<String>>>,
}

fn key(k: &str) -> Value {
    Value::Binary(k.as_bytes().to_vec())
}

fn str_of(v: &Value) -> Option<&str> {
    v.as_str()
}

fn get<'a>(map: &'a [(Value, Value)], k: &str) -> Option<&'a Value> {
    map.iter()
        .find(|(key, _)| str_of(key) == Some(k))
        .map(|(_, v)| v)
}

/// An ndarray map, its keys checked to be bin as openpi writes them: (dtype, shape, bytes).
fn ndarray(v: &Value, violations: &mut Vec<String>) -> Option<(String, Vec<usize>, Vec<u8>)> {
    let Value::Map(pairs) = v else {
        violations.push(format!("expected an ndarray map, got {v}"));
        return None;
    };
    let field = |name: &str| {
        pairs
            .iter()
            .find(|(k, _)| matches!(k, Value::Binary(b) if b == name.as_bytes()))
            .map(|(_, v)| v)
    };
    if field("__ndarray__") != Some(&Value::Boolean(true)) {
        violations.push(format!("no bin key __ndarray__ = true in {v}"));
        return None;
    }
    let dtype = field("dtype")?.as_str()?.to_string();
    let shape = field("shape")?
        .as_array()?
        .iter()
        .map(|d| d.as_u64().map(|d| d as usize))
        .collect::<Option<Vec<_>>>()?;
    let data = field("data")?.as_slice()?.to_vec();
    Some((dtype, shape, data))
}

fn nav_delta_reply(rows: &[[f32; 3]]) -> Value {
    let data: Vec<u8> = rows
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let array = Value::Map(vec![
        (key("__ndarray__"), Value::Boolean(true)),
        (key("data"), Value::Binary(data)),
        (key("dtype"), Value::from("<f4")),
        (
            key("shape"),
            Value::Array(vec![Value::from(rows.len()), Value::from(3)]),
        ),
    ]);
    let zero_d = Value::Map(vec![
        (key("__ndarray__"), Value::Boolean(true)),
        (key("data"), Value::Binary(1.5f32.to_le_bytes().to_vec())),
        (key("dtype"), Value::from("<f4")),
        (key("shape"), Value::Array(vec![])),
    ]);
    Value::Map(vec![
        ("action_type".into(), "nav_delta".into()),
        ("actions".into(), array.clone()),
        ("action.nav_delta".into(), array),
        ("inference_time".into(), zero_d),
        (
            "server_timing".into(),
            Value::Map(vec![("infer_ms".into(), Value::F64(1.0))]),
        ),
    ])
}

fn discrete_reply(codes: &[i64]) -> Value {
    Value::Map(vec![
        ("action_type".into(), "discrete".into()),
        (
            "actions".into(),
            Value::Array(codes.iter().map(|&c| Value::from(c)).collect()),
        ),
    ])
}

/// Starts the server: metadata first on every connection, `{"status": "reset successful"}` to
/// each reset, `answer(n)` to the n-th infer request.
fn serve(answer: impl Fn(usize) -> Answer + Send + Sync + 'static) -> Server {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let violations = Arc::new(Mutex::new(Vec::new()));
    let answer = Arc::new(answer);
    let infers = Arc::new(Mutex::new(0usize));
    let (s, v) = (seen.clone(), violations.clone());
    std::thread::spawn(move || {
        for (conn, stream) in listener.incoming().enumerate() {
            let Ok(stream) = stream else { return };
            let (seen, violations, answer, infers) =
                (s.clone(), v.clone(), answer.clone(), infers.clone());
            std::thread::spawn(move || {
                let mut ws = accept(stream).unwrap();
                let meta = Value::Map(vec![("model_name".into(), "test-policy".into())]);
                ws.send(Message::binary(encode(&meta))).unwrap();
                let mut viol = Vec::new();
                loop {
                    let bytes = match ws.read() {
                        Ok(Message::Binary(b)) => b,
                        Ok(Message::Text(t)) => {
                            viol.push(format!("a text frame from the client: {t}"));
                            break;
                        }
                        Ok(_) => continue,
                        Err(_) => break,
                    };
                    let mut rest: &[u8] = &bytes;
                    let Ok(Value::Map(msg)) = rmpv::decode::read_value(&mut rest) else {
                        viol.push("a message that is not a msgpack map".into());
                        break;
                    };
                    match get(&msg, "endpoint").and_then(str_of) {
                        Some("reset") => {
                            seen.lock().unwrap().push(Seen::Reset { conn });
                            let ok = Value::Map(vec![("status".into(), "reset successful".into())]);
                            ws.send(Message::binary(encode(&ok))).unwrap();
                            continue;
                        }
                        Some("infer") => {}
                        other => {
                            viol.push(format!("endpoint {other:?}"));
                            break;
                        }
                    }
                    let Some((dtype, shape, data)) =
                        get(&msg, "images").and_then(|i| ndarray(i, &mut viol))
                    else {
                        viol.push("an infer request without images".into());
                        break;
                    };
                    if dtype != "|u1" || data.len() != shape.iter().product::<usize>() {
                        viol.push(format!(
                            "images {dtype} {shape:?} with {} bytes",
                            data.len()
                        ));
                    }
                    if !shape.ends_with(&[H, W, 3]) || !(3..=4).contains(&shape.len()) {
                        viol.push(format!("images of shape {shape:?}"));
                    }
                    let state = get(&msg, "state.nav_pose").map(|s| {
                        let (dtype, shape, data) = ndarray(s, &mut viol).unwrap();
                        assert_eq!((dtype.as_str(), shape.as_slice()), ("<f4", &[3][..]));
                        let f = |i: usize| {
                            f32::from_le_bytes(data[4 * i..4 * i + 4].try_into().unwrap())
                        };
                        [f(0), f(1), f(2)]
                    });
                    let text = |k: &str| get(&msg, k).and_then(str_of).unwrap_or("").to_string();
                    seen.lock().unwrap().push(Seen::Infer {
                        conn,
                        shape,
                        session: text("session_id"),
                        instruction: text("instruction"),
                        state,
                    });
                    let n = {
                        let mut n = infers.lock().unwrap();
                        *n += 1;
                        *n - 1
                    };
                    match answer(n) {
                        Answer::Reply(v) => ws.send(Message::binary(encode(&v))).unwrap(),
                        Answer::Traceback => {
                            let tb = "Traceback (most recent call last):\n  File \"policy.py\"\nValueError: boom";
                            ws.send(Message::text(tb)).unwrap();
                            let _ = ws.close(Some(CloseFrame {
                                code: CloseCode::Error,
                                reason: "Internal server error".into(),
                            }));
                            let _ = ws.flush();
                            break;
                        }
                        Answer::Close => {
                            let _ = ws.close(None);
                            let _ = ws.flush();
                            break;
                        }
                        Answer::Garbage => ws.send(Message::binary(vec![0xc1, 0x00])).unwrap(),
                        Answer::HugeFrame => {
                            let mut header = vec![0x82, 0x7f];
                            header.extend((1u64 << 62).to_be_bytes());
                            let _ = ws.get_mut().write_all(&header);
                            let _ = ws.get_mut().flush();
                            break;
                        }
                    }
                }
                violations.lock().unwrap().extend(viol);
            });
        }
    });
    Server {
        port,
        seen,
        violations,
    }
}

fn encode(v: &Value) -> Vec<u8> {
    let mut out = Vec::new();
    rmpv::encode::write_value(&mut out, v).unwrap();
    out
}

fn agent(spec: &str) -> Box<dyn Agent> {
    spec.parse::<AgentKind>().unwrap().build(0).unwrap()
}

#[test]
fn nav_delta_chunks_send_hwc_then_the_frames_since_the_last_query() {
    let rows = [[0.1f32, 0.0, 0.2]; 8];
    let server = serve(move |_| Answer::Reply(nav_delta_reply(&rows)));
    let mut env = env(8);
    let mut a = agent(&format!("ws:127.0.0.1:{}?actions=3&state=1", server.port));
    let e = &fixture().episodes[0];
    let trace = run_episode(&mut env, a.as_mut(), e).unwrap();
    assert!(
        server.violations.lock().unwrap().is_empty(),
        "{:?}",
        server.violations
    );
    assert_eq!(trace.steps.len(), 8);
    assert_eq!(trace.termination, Some(Termination::MaxSteps));
    let seen = server.seen.lock().unwrap().clone();
    // reset, then a query every 3 steps: HWC first, then the 3 frames since the last query.
    let shapes: Vec<_> = seen
        .iter()
        .map(|s| match s {
            Seen::Reset { .. } => vec![],
            Seen::Infer { shape, .. } => shape.clone(),
        })
        .collect();
    assert_eq!(
        shapes,
        [vec![], vec![H, W, 3], vec![3, H, W, 3], vec![3, H, W, 3]]
    );
    // The state is the pose at each query, in the W frame.
    let poses: Vec<[f32; 3]> = std::iter::once(e.start)
        .chain(trace.steps.iter().map(|s| s.pose))
        .map(|p| [p.position.x, p.position.y, p.yaw])
        .collect();
    for (k, s) in seen[1..].iter().enumerate() {
        let Seen::Infer {
            session,
            instruction,
            state,
            conn,
            ..
        } = s
        else {
            panic!("{s:?}")
        };
        assert_eq!(
            (session.as_str(), instruction.as_str(), *conn),
            (e.id.as_str(), e.instruction.as_str(), 0)
        );
        let want = poses[3 * k];
        let got = state.unwrap();
        assert!(
            (0..3).all(|i| (got[i] - want[i]).abs() < 1e-4),
            "{got:?} {want:?}"
        );
    }
    // Within a chunk every row moves along the heading of its query (chunk_start) while the
    // heading turns by dyaw each step.
    let mut checked = 0;
    for (k, s) in trace.steps.iter().enumerate() {
        let before = poses[k];
        let chunk_yaw = poses[k - k % 3][2];
        assert!((sage_core::wrap_angle(s.pose.yaw - before[2] - 0.2)).abs() < 1e-4);
        // A step that touched something slid along it.
        if s.touched.is_empty() {
            checked += 1;
            let moved =
                glam::Vec2::new(s.pose.position.x - before[0], s.pose.position.y - before[1]);
            let want = 0.1 * glam::Vec2::new(chunk_yaw.cos(), chunk_yaw.sin());
            assert!(moved.distance(want) < 1e-4, "step {k}: {moved} vs {want}");
        }
    }
    assert!(checked >= 4, "only {checked} free steps");
    let notes = a.take_notes();
    assert!(notes.iter().any(|n| n.contains("test-policy")), "{notes:?}");
    assert!(
        notes
            .iter()
            .any(|n| n.contains("held 8 actions; actions=3")),
        "{notes:?}"
    );
    assert!(a.take_faults().is_empty());
}

#[test]
fn a_discrete_stop_ends_the_episode() {
    let server = serve(|_| Answer::Reply(discrete_reply(&[1, 2, 3, 0, 1])));
    let mut env = env(50);
    let mut a = agent(&format!("ws:127.0.0.1:{}", server.port));
    let trace = run_episode(&mut env, a.as_mut(), &fixture().episodes[1]).unwrap();
    let actions: Vec<Action> = trace.steps.iter().map(|s| s.action).collect();
    assert_eq!(
        actions,
        [
            Action::MoveForward,
            Action::TurnLeft,
            Action::TurnRight,
            Action::Stop
        ]
    );
    assert_eq!(trace.termination, Some(Termination::Stop));
    assert_eq!(server.seen.lock().unwrap().len(), 2);
}

#[test]
fn faults_reconnect_reset_and_retry_and_are_never_moves() {
    // Query 1 fine; then a traceback, a close, garbage, a reply without actions, a wrong
    // dtype, before the retry that works.
    let wrong_dtype = Value::Map(vec![(
        "actions".into(),
        Value::Map(vec![
            (key("__ndarray__"), Value::Boolean(true)),
            (key("data"), Value::Binary(vec![0; 8])),
            (key("dtype"), Value::from("<U2")),
            (key("shape"), Value::Array(vec![Value::from(1)])),
        ]),
    )]);
    let script = [
        Answer::Reply(discrete_reply(&[1, 1])),
        Answer::Traceback,
        Answer::Close,
        Answer::Garbage,
        Answer::Reply(Value::Map(vec![("status".into(), "ok".into())])),
        Answer::Reply(wrong_dtype),
        Answer::Reply(discrete_reply(&[0])),
    ];
    let server = serve(move |n| script[n.min(script.len() - 1)].clone());
    let mut env = env(50);
    let mut a = agent(&format!("ws:127.0.0.1:{}?retries=5", server.port));
    let e = &fixture().episodes[2];
    let trace = run_episode(&mut env, a.as_mut(), e).unwrap();
    assert!(
        server.violations.lock().unwrap().is_empty(),
        "{:?}",
        server.violations
    );
    let actions: Vec<Action> = trace.steps.iter().map(|s| s.action).collect();
    assert_eq!(
        actions,
        [Action::MoveForward, Action::MoveForward, Action::Stop]
    );
    let faults = a.take_faults();
    let kinds: Vec<_> = faults
        .iter()
        .map(|f| (f.step, f.attempt, f.kind, f.recovered))
        .collect();
    assert_eq!(
        kinds,
        [
            (2, 1, FaultKind::ServerError, true),
            (2, 2, FaultKind::Transport, true),
            (2, 3, FaultKind::Transport, true),
            (2, 4, FaultKind::Unparseable, true),
            (2, 5, FaultKind::Unparseable, true),
        ]
    );
    assert!(
        faults[0].message.contains("ValueError: boom"),
        "{}",
        faults[0].message
    );
    assert!(
        faults[1].message.contains("closed"),
        "{}",
        faults[1].message
    );
    assert!(
        faults[2].message.contains("msgpack"),
        "{}",
        faults[2].message
    );
    assert!(faults[4].message.contains("<U2"), "{}", faults[4].message);
    // Each fault dropped the connection; each new one was reset and queried with the current
    // frame as HWC.
    let seen = server.seen.lock().unwrap().clone();
    let order: Vec<(usize, &str, usize)> = seen
        .iter()
        .map(|s| match s {
            Seen::Reset { conn } => (*conn, "reset", 0),
            Seen::Infer { conn, shape, .. } => (*conn, "infer", shape.len()),
        })
        .collect();
    assert_eq!(
        order,
        [
            (0, "reset", 0),
            (0, "infer", 3),
            (0, "infer", 4),
            (1, "reset", 0),
            (1, "infer", 3),
            (2, "reset", 0),
            (2, "infer", 3),
            (3, "reset", 0),
            (3, "infer", 3),
            (4, "reset", 0),
            (4, "infer", 3),
            (5, "reset", 0),
            (5, "infer", 3),
        ]
    );
}

#[test]
fn a_frame_declaring_more_than_the_reply_limit_is_a_fault_not_an_allocation() {
    // The client once allocated what the header declared (2⁶² bytes: an abort).
    let server = serve(|n| {
        if n == 0 {
            Answer::HugeFrame
        } else {
            Answer::Reply(discrete_reply(&[0]))
        }
    });
    let mut env = env(50);
    let mut a = agent(&format!("ws:127.0.0.1:{}?retries=1", server.port));
    let trace = run_episode(&mut env, a.as_mut(), &fixture().episodes[0]).unwrap();
    assert_eq!(trace.steps.last().map(|s| s.action), Some(Action::Stop));
    let faults = a.take_faults();
    assert_eq!(faults.len(), 1, "{faults:?}");
    assert_eq!(faults[0].kind, FaultKind::Transport);
    assert!(
        faults[0].message.contains("too long"),
        "{}",
        faults[0].message
    );
}

#[test]
fn exhausted_retries_and_a_dead_server_fail_the_episode() {
    let server = serve(|_| Answer::Traceback);
    let mut env = env(50);
    let mut a = agent(&format!("ws:127.0.0.1:{}?retries=1", server.port));
    let err = run_episode(&mut env, a.as_mut(), &fixture().episodes[0]).unwrap_err();
    assert!(err.to_string().contains("after 2 attempts"), "{err}");
    let faults = a.take_faults();
    assert_eq!(faults.len(), 2);
    assert!(
        faults
            .iter()
            .all(|f| f.kind == FaultKind::ServerError && !f.recovered)
    );
    let port = {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let mut a = agent(&format!("ws:127.0.0.1:{port}?retries=0&timeout=1"));
    let err = run_episode(&mut env, a.as_mut(), &fixture().episodes[0]).unwrap_err();
    assert!(err.to_string().contains("reset"), "{err}");
    assert_eq!(a.take_faults()[0].kind, FaultKind::Transport);
}
