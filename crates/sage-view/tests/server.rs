//! The viewer's server over real HTTP on loopback: every route, the guard (host, token, paths
//! that try to leave the folders), explore sessions through the environment, and human play
//! recorded exactly as `sage3d eval` scores the same actions.

use sage_dataset::build::{self, AssembleParams, SceneParams};
use sage_dataset::split::SplitParams;
use sage_eval::{EvalRecord, EvalSettings};
use sage_synth::{SynthConfig, generate};
use sage_view::ViewOptions;
use serde_json::{Value, json};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock, mpsc};

/// A generated 3-room home and its dataset: (temp dir, scenes folder, dataset folder).
fn fixture() -> &'static (tempfile::TempDir, PathBuf, PathBuf) {
    static F: OnceLock<(tempfile::TempDir, PathBuf, PathBuf)> = OnceLock::new();
    F.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let scenes = dir.path().join("scenes");
        let home = scenes.join("home1");
        generate(&SynthConfig {
            seed: 4,
            rooms: 3,
            objects: 24,
            gaussians: 3000,
            ..SynthConfig::default()
        })
        .unwrap()
        .save(&home, sage_scene::SplatLayout::Compressed)
        .unwrap();
        let data = dir.path().join("data");
        let assemble = AssembleParams {
            seed: 3,
            split: SplitParams::default(),
            balanced: 0,
        };
        build::build(
            std::slice::from_ref(&home),
            &data,
            &SceneParams::new(3, 2),
            &assemble,
            &|_| {},
        )
        .unwrap();
        (dir, scenes, data)
    })
}

/// A running viewer; stops when dropped.
struct Viewer {
    addr: SocketAddr,
    url: String,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<sage_core::Result<()>>>,
}

impl Drop for Viewer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            t.join().unwrap().unwrap();
        }
    }
}

fn start(opts: ViewOptions) -> Viewer {
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel();
    let flag = stop.clone();
    let thread = std::thread::spawn(move || {
        let tx2 = tx.clone();
        let r = sage_view::serve(
            &opts,
            move |s| tx.send(Ok(s.clone())).unwrap(),
            move || !flag.load(Ordering::SeqCst),
        );
        if let Err(e) = &r {
            let _ = tx2.send(Err(e.to_string()));
        }
        r
    });
    let server = rx.recv().unwrap().unwrap();
    Viewer {
        addr: server.addr,
        url: server.url,
        stop,
        thread: Some(thread),
    }
}

fn options(path: &Path) -> ViewOptions {
    ViewOptions {
        port: 0,
        ..ViewOptions::new(path)
    }
}

/// One request through the viewer's client; returns the status and the body.
fn request(
    addr: SocketAddr,
    method: &str,
    target: &str,
    body: Option<&Value>,
    headers: &[(&str, &str)],
) -> (u16, Vec<u8>) {
    let reply = sage_view::client::request(addr, method, target, body, headers).unwrap();
    assert!(
        !reply
            .headers
            .iter()
            .any(|(k, v)| k == "transfer-encoding" && v.contains("chunked")),
        "bodies have a length"
    );
    (reply.status, reply.body)
}

fn get_json(v: &Viewer, target: &str) -> Value {
    let (status, body) = request(v.addr, "GET", target, None, &[]);
    let json: Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(status, 200, "{target}: {json}");
    json
}

fn post_json(v: &Viewer, target: &str, body: Value) -> Value {
    let (status, reply) = request(v.addr, "POST", target, Some(&body), &[]);
    let json: Value = serde_json::from_slice(&reply).unwrap();
    assert_eq!(status, 200, "{target} {body}: {json}");
    json
}

#[test]
fn scenes_map_frames_and_explore_sessions_through_physics() {
    let (_, scenes, _) = fixture();
    let v = start(options(scenes));
    assert!(v.url.starts_with("http://127.0.0.1:") && !v.url.contains("token"));
    let info = get_json(&v, "/api/info");
    assert_eq!(info["kind"], "scenes");
    assert_eq!(info["scenes"], json!(["home1"]));
    let (status, page) = request(v.addr, "GET", "/", None, &[]);
    assert_eq!(status, 200);
    assert!(String::from_utf8(page).unwrap().contains("app.js"));
    // The map: its PNG is as large as its frame says, and it lists the scene's objects.
    let map = get_json(&v, "/api/scenes/home1/map");
    let (status, png) = request(v.addr, "GET", "/api/scenes/home1/map.png", None, &[]);
    assert_eq!(status, 200);
    let decoder = png::Decoder::new(std::io::Cursor::new(png));
    let reader = decoder.read_info().unwrap();
    assert_eq!(
        (reader.info().width as u64, reader.info().height as u64),
        (
            map["width"].as_u64().unwrap(),
            map["height"].as_u64().unwrap()
        )
    );
    let ctx = sage_env::SceneContext::load(&scenes.join("home1"), None).unwrap();
    let ids: Vec<&str> = map["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["id"].as_str().unwrap())
        .collect();
    let expected: Vec<&str> = ctx
        .semantic
        .items
        .iter()
        .map(|i| i.item_id.as_str())
        .collect();
    assert_eq!(ids, expected);
    assert!(!ids.is_empty());
    // An explore session steps through the environment: forward moves the preset's step
    // along the heading (or less against a body), a turn turns the preset's angle.
    let s0 = post_json(&v, "/api/sessions", json!({}));
    let id = s0["session"].as_str().unwrap().to_string();
    let s1 = post_json(
        &v,
        &format!("/api/sessions/{id}/step"),
        json!({"action": "left"}),
    );
    let turned = s1["pose"]["yaw"].as_f64().unwrap() - s0["pose"]["yaw"].as_f64().unwrap();
    assert!((turned - 15f64.to_radians()).abs() < 1e-4, "{turned}");
    let s2 = post_json(
        &v,
        &format!("/api/sessions/{id}/step"),
        json!({"action": "forward"}),
    );
    let moved = ((s2["pose"]["x"].as_f64().unwrap() - s1["pose"]["x"].as_f64().unwrap()).powi(2)
        + (s2["pose"]["y"].as_f64().unwrap() - s1["pose"]["y"].as_f64().unwrap()).powi(2))
    .sqrt();
    assert!(moved <= 0.25 + 1e-4 && (moved > 0.2 || s2["contact"] == true));
    assert_eq!(s2["step"], 2);
    assert_eq!(s2["path"].as_array().unwrap().len(), 3);
    // A walk without an episode has no goal, and so no distance to one.
    assert!(
        s2["goal"].is_null() && s2["distance_to_goal"].is_null(),
        "{s2}"
    );
    // Placing snaps to navigable floor; far off the map is refused with the reason.
    let p = post_json(
        &v,
        &format!("/api/sessions/{id}/place"),
        json!({"x": s0["pose"]["x"], "y": s0["pose"]["y"], "yaw": 1.0}),
    );
    assert_eq!(p["step"], 0);
    assert!((p["pose"]["yaw"].as_f64().unwrap() - 1.0).abs() < 1e-5);
    let (status, body) = request(
        v.addr,
        "POST",
        &format!("/api/sessions/{id}/place"),
        Some(&json!({"x": 1e4, "y": 1e4})),
        &[],
    );
    assert_eq!(status, 400);
    assert!(String::from_utf8_lossy(&body).contains("no navigable floor"));
    let (status, body) = request(
        v.addr,
        "POST",
        &format!("/api/sessions/{id}/place"),
        Some(&json!({"x": s0["pose"]["x"], "y": s0["pose"]["y"], "yaw": 3.4e38})),
        &[],
    );
    assert_eq!(status, 400);
    assert!(String::from_utf8_lossy(&body).contains("within ±10000"));
    let (status, body) = request(
        v.addr,
        "POST",
        &format!("/api/sessions/{id}/step"),
        Some(&json!({"action": "jump"})),
        &[],
    );
    assert_eq!(status, 400);
    assert!(String::from_utf8_lossy(&body).contains("forward, left, right, stop"));
    // Frames: each layer at the requested size, as PNG and JPEG; a bad size is refused.
    let pose = &p["pose"];
    let q = |layer: &str, format: &str| {
        format!(
            "/api/scenes/home1/frame?x={}&y={}&z={}&yaw={}&width=160&height=120&layer={layer}&format={format}",
            pose["x"], pose["y"], pose["z"], pose["yaw"]
        )
    };
    for layer in ["rgb", "depth", "semantic", "instance"] {
        let (status, bytes) = request(v.addr, "GET", &q(layer, "png"), None, &[]);
        assert_eq!(status, 200, "{layer}");
        let reader = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        assert_eq!((reader.info().width, reader.info().height), (160, 120));
    }
    let (status, jpeg) = request(v.addr, "GET", &q("rgb", "jpeg"), None, &[]);
    assert_eq!((status, &jpeg[..2]), (200, &[0xff, 0xd8][..]));
    // Requests at once render at once (on the CPU each borrows a renderer from the scene's
    // pool) and give the bytes of the same frame alone.
    let (_, alone) = request(v.addr, "GET", &q("rgb", "png"), None, &[]);
    let together: Vec<Vec<u8>> = std::thread::scope(|s| {
        let tasks: Vec<_> = (0..4)
            .map(|_| s.spawn(|| request(v.addr, "GET", &q("rgb", "png"), None, &[]).1))
            .collect();
        tasks.into_iter().map(|t| t.join().unwrap()).collect()
    });
    assert!(together.iter().all(|b| *b == alone));
    let (status, _) = request(
        v.addr,
        "GET",
        "/api/scenes/home1/frame?x=0&y=0&z=0&yaw=0&width=0",
        None,
        &[],
    );
    assert_eq!(status, 400);
    // A number past f32's range names itself and the range.
    let (status, body) = request(
        v.addr,
        "GET",
        "/api/scenes/home1/frame?x=1e308&y=0&z=0&yaw=0",
        None,
        &[],
    );
    let body = String::from_utf8_lossy(&body);
    assert_eq!(status, 400, "{body}");
    assert!(
        body.contains("x: inf is not a number within ±10000"),
        "{body}"
    );
    // So is an angle whose degrees would not be a number in the `render` command answered.
    let (status, body) = request(
        v.addr,
        "GET",
        "/api/scenes/home1/frame?x=1&y=0&z=0&yaw=0&pitch=3e38",
        None,
        &[],
    );
    let body = String::from_utf8_lossy(&body);
    assert_eq!(status, 400, "{body}");
    assert!(
        body.contains("pitch: 300000000000000000000000000000000000000 is not a number"),
        "{body}"
    );
}

#[test]
fn only_its_own_routes_and_only_for_localhost() {
    let (_, scenes, _) = fixture();
    let v = start(options(scenes));
    for target in [
        "/../../etc/passwd",
        "/%2e%2e/%2e%2e/etc/passwd",
        "//etc/passwd",
        "/etc/passwd",
        "/api/scenes/..%2F..%2Fetc/map",
        "/api/scenes/%2Fetc%2Fpasswd/map.png",
        "/api/scenes/home1/..%2F..%2Fsage3d_run.json",
        "/api/scenes/..%5Chome1/map",
        "/api/episodes/..%2Fepisodes.jsonl",
        "/home1/3dgs_compressed.ply",
        "/api/scenes/home1/3dgs_compressed.ply",
    ] {
        let (status, body) = request(v.addr, "GET", target, None, &[]);
        assert_eq!(status, 404, "{target}: {}", String::from_utf8_lossy(&body));
    }
    // A page of another site reaching the viewer through a name that resolves to 127.0.0.1.
    let (status, _) = request(
        v.addr,
        "GET",
        "/api/info",
        None,
        &[("Host", "attacker.example:80")],
    );
    assert_eq!(status, 403);
    let (status, _) = request(v.addr, "GET", "/api/info", None, &[("Host", "localhost")]);
    assert_eq!(status, 200);
}

#[test]
fn a_public_viewer_needs_its_token_and_other_addresses_need_the_flag() {
    let (_, scenes, _) = fixture();
    let err = sage_view::serve(
        &ViewOptions {
            host: "0.0.0.0".parse().unwrap(),
            ..options(scenes)
        },
        |_| panic!("must not start"),
        || false,
    )
    .unwrap_err();
    assert!(err.to_string().contains("`public`"), "{err}");
    let v = start(ViewOptions {
        public: true,
        ..options(scenes)
    });
    let token = v.url.split("token=").nth(1).unwrap().to_string();
    assert_eq!(token.len(), 32);
    for target in ["/", "/api/info", "/api/scenes/home1/map.png"] {
        let (status, _) = request(v.addr, "GET", target, None, &[]);
        assert_eq!(status, 403, "{target}");
        // The token with its first digit changed.
        let wrong = if token.starts_with('0') { "1" } else { "0" };
        let (status, _) = request(
            v.addr,
            "GET",
            &format!("{target}?token={wrong}{}", &token[1..]),
            None,
            &[],
        );
        assert_eq!(status, 403, "{target} with a wrong token");
        let (status, _) = request(v.addr, "GET", &format!("{target}?token={token}"), None, &[]);
        assert_eq!(status, 200, "{target}");
    }
    let (status, _) = request(
        v.addr,
        "GET",
        "/api/info",
        None,
        &[("X-Sage3d-Token", token.as_str())],
    );
    assert_eq!(status, 200);
    // The script and style sheet hold no data and load without it.
    assert_eq!(request(v.addr, "GET", "/app.js", None, &[]).0, 200);
}

/// Sends `bytes` as they are and reads what comes back until the server closes.
fn raw(addr: SocketAddr, bytes: &[u8]) -> String {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(std::time::Duration::from_secs(120)))
        .unwrap();
    s.write_all(bytes).unwrap();
    let mut reply = Vec::new();
    s.read_to_end(&mut reply).unwrap();
    String::from_utf8_lossy(&reply).into_owned()
}

/// A `POST` of `body` with `headers` (one per line, `\r\n`-ended), closing the connection.
fn raw_post(addr: SocketAddr, target: &str, headers: &str, body: &str) -> String {
    raw(
        addr,
        format!(
            "POST {target} HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nConnection: close\r\nContent-Length: {}\r\n{headers}\r\n{body}",
            addr.port(),
            body.len()
        )
        .as_bytes(),
    )
}

#[test]
fn other_sites_forms_oversized_bodies_and_idle_connections_are_refused() {
    let (_, scenes, _) = fixture();
    let v = start(options(scenes));
    let json = "Content-Type: application/json\r\n";
    let own = format!("Origin: http://127.0.0.1:{}\r\n", v.addr.port());
    let opened = raw_post(v.addr, "/api/sessions", &format!("{json}{own}"), "{}");
    assert!(opened.starts_with("HTTP/1.1 200"), "{opened}");
    // A form another site's page posts (it needs no preflight), and no body at all.
    for (headers, body) in [
        ("Content-Type: application/x-www-form-urlencoded\r\n", "a=1"),
        ("Content-Type: text/plain\r\n", "{}"),
        ("", ""),
    ] {
        let reply = raw_post(v.addr, "/api/sessions/1/map", headers, body);
        assert!(reply.starts_with("HTTP/1.1 415"), "{headers}: {reply}");
        assert!(reply.contains("application/json"), "{reply}");
    }
    // JSON from another site's script, or from a sandboxed page.
    for origin in ["http://attacker.example", "null", "http://127.0.0.1:1"] {
        let reply = raw_post(
            v.addr,
            "/api/sessions",
            &format!("{json}Origin: {origin}\r\n"),
            "{}",
        );
        assert!(reply.starts_with("HTTP/1.1 403"), "{origin}: {reply}");
        assert!(reply.contains("not the viewer's own"), "{reply}");
    }
    let big = format!(
        "{{\"scene\": \"{}\"}}",
        "a".repeat(sage_view::server::MAX_BODY)
    );
    let reply = raw_post(v.addr, "/api/sessions", json, &big);
    assert!(reply.starts_with("HTTP/1.1 413"), "{reply:.80}");
    // A connection that never sends a request, and one that stops halfway through its head,
    // are closed by the server (after its head timeout): reading them ends, with no answer.
    let addr = v.addr;
    let idle = std::thread::spawn(move || raw(addr, b""));
    let halfway = raw(v.addr, b"GET /api/info HTTP/1.1\r\nHost: 127.0.0.1\r\n");
    for reply in [idle.join().unwrap(), halfway] {
        assert!(!reply.contains("200 OK"), "{reply}");
    }
}

#[test]
fn a_viewer_on_every_interface_prints_a_url_that_opens_here() {
    let (_, scenes, _) = fixture();
    let v = start(ViewOptions {
        host: "0.0.0.0".parse().unwrap(),
        public: true,
        ..options(scenes)
    });
    assert!(v.url.starts_with("http://127.0.0.1:"), "{}", v.url);
    let server = sage_view::Server {
        addr: v.addr,
        url: v.url.clone(),
    };
    assert!(server.announcement().contains("every interface"));
    let (status, _) = request(
        v.addr,
        "GET",
        &format!("/api/info?{}", v.url.split('?').nth(1).unwrap()),
        None,
        &[],
    );
    assert_eq!(status, 200);
}

/// The records of a run folder by episode id.
/// The evaluation of `agent` over the fixture's train split, as `sage3d eval` runs it.
fn train_settings(agent: &str) -> EvalSettings {
    let (_, scenes, data) = fixture();
    EvalSettings {
        dataset: data.clone(),
        scenes: scenes.clone(),
        split: "train".into(),
        agent: agent.parse().unwrap(),
        mode: Default::default(),
        dtw: Default::default(),
        seed: 0,
        preset: "sage".into(),
        device: Default::default(),
        splat_bodies: Default::default(),
    }
}

fn records(run: &Path) -> std::collections::BTreeMap<String, EvalRecord> {
    std::fs::read_to_string(run.join("episodes.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<EvalRecord>(l).unwrap())
        .map(|r| (r.episode_id.clone(), r))
        .collect()
}

#[test]
fn human_play_is_recorded_and_scored_as_eval_scores_the_same_actions() {
    let (dir, scenes, data) = fixture();
    let run = dir.path().join("human");
    let opts = ViewOptions {
        play: Some(run.clone()),
        scenes: Some(scenes.clone()),
        split: Some("train".into()),
        ..options(data)
    };
    let played: Vec<(String, Vec<&str>)>;
    {
        let v = start(opts.clone());
        let info = get_json(&v, "/api/info");
        assert_eq!(info["kind"], "play");
        assert_eq!(info["play"]["played"], 0);
        let episodes: Vec<Value> = info["episodes"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|e| e["task"] == "vln")
            .take(2)
            .cloned()
            .collect();
        assert_eq!(episodes.len(), 2);
        // Exploring is not playing: a play session needs an episode.
        let (status, _) = request(
            v.addr,
            "POST",
            "/api/sessions",
            Some(&json!({"play": true})),
            &[],
        );
        assert_eq!(status, 400);
        let moves = [
            vec!["forward", "forward", "left", "forward", "stop"],
            vec!["right", "forward", "forward", "stop"],
        ];
        played = episodes
            .iter()
            .zip(moves)
            .enumerate()
            .map(|(k, (e, moves))| {
                let id = e["id"].as_str().unwrap().to_string();
                let s = post_json(&v, "/api/sessions", json!({"episode": id, "play": true}));
                let sid = s["session"].as_str().unwrap().to_string();
                // The person sees what an agent sees: no goal, no reference path.
                assert!(s["goal"].is_null() && s["reference_path"] == json!([]));
                if k == 1 {
                    post_json(&v, &format!("/api/sessions/{sid}/map"), json!({}));
                }
                let mut last = Value::Null;
                for m in &moves {
                    last = post_json(
                        &v,
                        &format!("/api/sessions/{sid}/step"),
                        json!({"action": m}),
                    );
                }
                assert_eq!(last["done"], true);
                assert_eq!(last["played"], k + 1);
                assert_eq!(last["record"]["id"], json!(id));
                // A played episode is not played twice.
                let (status, _) = request(
                    v.addr,
                    "POST",
                    "/api/sessions",
                    Some(&json!({"episode": id, "play": true})),
                    &[],
                );
                assert_eq!(status, 400);
                (id, moves)
            })
            .collect();
        let detail = get_json(&v, &format!("/api/episodes/{}", played[0].0));
        let actions: Vec<&str> = detail["steps"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s["action"].as_str().unwrap())
            .collect();
        assert_eq!(actions, played[0].1);
    }
    // The server is gone; the records are on disk, and a new sitting resumes them.
    let v = start(opts);
    assert_eq!(get_json(&v, "/api/info")["play"]["played"], 2);
    drop(v);
    let human = records(&run);
    assert_eq!(human.len(), 2);
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["episodes"], 2);
    // The same actions replayed by the evaluator score the same, bit for bit.
    let replay = dir.path().join("replay.jsonl");
    let lines: Vec<String> = played
        .iter()
        .map(|(id, moves)| {
            let names: Vec<&str> = moves
                .iter()
                .map(|m| match *m {
                    "forward" => "MOVE_FORWARD",
                    "left" => "TURN_LEFT",
                    "right" => "TURN_RIGHT",
                    _ => "STOP",
                })
                .collect();
            json!({"episode_id": id, "actions": names}).to_string()
        })
        .collect();
    std::fs::write(&replay, lines.join("\n") + "\n").unwrap();
    let out = dir.path().join("replayed");
    let settings = train_settings(&format!("replay:{}", replay.display()));
    sage_eval::run(&settings, &out, &|_, _| {}).unwrap();
    let evaluated = records(&out);
    for (id, _) in &played {
        let (h, e) = (&human[id], &evaluated[id]);
        assert_eq!(h.agent, "human");
        assert_eq!(h.metrics, e.metrics, "{id}");
        assert_eq!(h.record, e.record, "{id}");
        assert_eq!(h.termination, e.termination, "{id}");
    }
    // A human run never writes into another run's folder.
    let err = sage_view::serve(
        &ViewOptions {
            play: Some(out.clone()),
            scenes: Some(scenes.clone()),
            split: Some("train".into()),
            ..options(data)
        },
        |_| panic!("must not start"),
        || false,
    )
    .unwrap_err();
    assert!(err.to_string().contains("other settings"), "{err}");
    assert!(human[&played[0].0].notes.is_empty());
    assert_eq!(human[&played[1].0].notes, vec!["map shown".to_string()]);
}

#[test]
fn a_run_is_viewed_in_the_environment_it_recorded() {
    let (dir, _, _) = fixture();
    let out = dir.path().join("run-in-its-env");
    let settings = train_settings("forward");
    sage_eval::run(&settings, &out, &|_, _| {}).unwrap();
    // The environment a Python run with overrides records: not the preset's.
    let record_path = out.join(sage_io::run::RUN_RECORD);
    let mut record: Value =
        serde_json::from_str(&std::fs::read_to_string(&record_path).unwrap()).unwrap();
    record["env"]["task"]["max_steps"] = json!(77);
    record["env"]["sensors"]["hfov_deg"] = json!(70.0);
    std::fs::write(&record_path, record.to_string()).unwrap();
    let v = start(options(&out));
    let info = get_json(&v, "/api/info");
    assert_eq!(info["kind"], "run");
    assert_eq!(info["preset"]["max_steps"], 77, "{info}");
    assert_eq!(info["preset"]["hfov_deg"], 70.0, "{info}");
    drop(v);
    // A run that moved by velocities has no step for the keys: its preset's steps drive
    // exploring, its camera and task stay.
    record["env"]["actions"] = json!({"kind": "ground", "max_dt": 0.5});
    std::fs::write(&record_path, record.to_string()).unwrap();
    let v = start(options(&out));
    let info = get_json(&v, "/api/info");
    assert_eq!(info["preset"]["forward"], 0.25, "{info}");
    assert_eq!(info["preset"]["max_steps"], 77, "{info}");
}

/// The `error` of a JSON error answer, which must be one.
fn error_of(status: u16, body: &[u8], want: u16) -> String {
    let text = String::from_utf8_lossy(body);
    assert_eq!(status, want, "{text}");
    let json: Value = serde_json::from_slice(body).unwrap_or_else(|e| panic!("{e}: {text}"));
    json["error"]
        .as_str()
        .unwrap_or_else(|| panic!("{json}"))
        .to_string()
}

#[test]
fn a_run_on_other_bodies_is_explored_on_them() {
    let (dir, _, _) = fixture();
    let out = dir.path().join("run-never-bodies");
    let settings = EvalSettings {
        splat_bodies: sage_physics::SplatBodies::Never,
        ..train_settings("forward")
    };
    sage_eval::run(&settings, &out, &|_, _| {}).unwrap();
    let v = start(options(&out));
    let info = get_json(&v, "/api/info");
    assert_eq!(info["preset"]["splat_bodies"], "never", "{info}");
    let id = info["episodes"][0]["id"].as_str().unwrap().to_string();
    // The environment refuses a scene loaded on other bodies: these open only when the scene
    // was loaded with the run's choice.
    let s = post_json(&v, "/api/sessions", json!({"episode": id}));
    assert_eq!(s["splat_bodies"], "never", "{s}");
    let sid = s["session"].as_str().unwrap();
    let s1 = post_json(
        &v,
        &format!("/api/sessions/{sid}/step"),
        json!({"action": "forward"}),
    );
    assert_eq!(s1["step"], 1);
    let walk = post_json(&v, "/api/sessions", json!({"scene": "home1"}));
    assert_eq!(walk["splat_bodies"], "never", "{walk}");
}

#[test]
fn the_scene_cache_loads_each_choice_of_bodies_apart() {
    use sage_physics::SplatBodies;
    let (_, scenes, _) = fixture();
    let dirs = [("home1".to_string(), scenes.join("home1"))].into();
    let cache = sage_view::scenes::SceneCache::new(dirs, sage_splat::Device::Cpu);
    let never = cache.get("home1", SplatBodies::Never).unwrap();
    let auto = cache.get("home1", SplatBodies::Auto).unwrap();
    assert_eq!(never.ctx.splat_bodies, Some(SplatBodies::Never));
    assert_eq!(auto.ctx.splat_bodies, Some(SplatBodies::Auto));
    assert!(!std::sync::Arc::ptr_eq(&never, &auto));
    // Each choice is loaded once.
    let again = cache.get("home1", SplatBodies::Never).unwrap();
    assert!(std::sync::Arc::ptr_eq(&never, &again));
    let err = cache.get("home2", SplatBodies::Auto).err().unwrap();
    assert!(err.to_string().contains("no scene 'home2'"), "{err}");
}

#[test]
fn in_human_play_an_episode_is_explored_only_once_played() {
    let (dir, scenes, data) = fixture();
    let v = start(ViewOptions {
        play: Some(dir.path().join("human-explore")),
        scenes: Some(scenes.clone()),
        split: Some("train".into()),
        ..options(data)
    });
    let info = get_json(&v, "/api/info");
    let id = info["episodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["task"] == "vln")
        .unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    // Exploring it first would show its goal, reference path and distance to the goal.
    let (status, body) = request(
        v.addr,
        "POST",
        "/api/sessions",
        Some(&json!({"episode": id})),
        &[],
    );
    let error = error_of(status, &body, 403);
    assert!(error.contains("not played yet"), "{error}");
    // Walking a scene shows no episode's goal, and stays open.
    let walk = post_json(&v, "/api/sessions", json!({"scene": "home1"}));
    assert!(walk["goal"].is_null(), "{walk}");
    let s = post_json(&v, "/api/sessions", json!({"episode": id, "play": true}));
    let sid = s["session"].as_str().unwrap();
    let end = post_json(
        &v,
        &format!("/api/sessions/{sid}/step"),
        json!({"action": "stop"}),
    );
    assert_eq!(end["played"], 1, "{end}");
    // Played and recorded: now it may be explored, goal and way shown.
    let e = post_json(&v, "/api/sessions", json!({"episode": id}));
    assert_eq!(e["purpose"], "explore");
    assert!(e["goal"].is_array(), "{e}");
    assert!(!e["reference_path"].as_array().unwrap().is_empty(), "{e}");
}

#[test]
fn requests_of_the_wrong_form_get_json_errors() {
    let (_, scenes, _) = fixture();
    let v = start(options(scenes));
    let s = post_json(&v, "/api/sessions", json!({}));
    assert_eq!(s["session"], "1");
    // A session id that is not a number.
    let (status, body) = request(
        v.addr,
        "POST",
        "/api/sessions/first/step",
        Some(&json!({"action": "left"})),
        &[],
    );
    let error = error_of(status, &body, 400);
    assert!(error.contains("first"), "{error}");
    // A frame query missing a field.
    let (status, body) = request(
        v.addr,
        "GET",
        "/api/scenes/home1/frame?x=1&y=0&yaw=0",
        None,
        &[],
    );
    let error = error_of(status, &body, 400);
    assert!(error.contains("missing field `z`"), "{error}");
    // A body that is not the route's JSON.
    let (status, body) = request(
        v.addr,
        "POST",
        "/api/sessions/1/step",
        Some(&json!({"move": "left"})),
        &[],
    );
    let error = error_of(status, &body, 422);
    assert!(error.contains("action"), "{error}");
    // A route that does not exist, and a route asked with the wrong method (its `Allow` kept).
    let (status, body) = request(v.addr, "GET", "/api/nothing", None, &[]);
    let error = error_of(status, &body, 404);
    assert!(error.contains("GET /api/nothing"), "{error}");
    let reply =
        sage_view::client::request(v.addr, "GET", "/api/sessions/1/step", None, &[]).unwrap();
    let error = error_of(reply.status, &reply.body, 405);
    assert!(error.contains("Method Not Allowed"), "{error}");
    assert!(
        reply
            .headers
            .iter()
            .any(|(k, v)| k == "allow" && v.contains("POST")),
        "{:?}",
        reply.headers
    );
    // The session is untouched by the refused requests.
    let after = post_json(
        &v,
        "/api/sessions/1/place",
        json!({"x": s["pose"]["x"], "y": s["pose"]["y"]}),
    );
    assert_eq!(after["step"], 0);
}
