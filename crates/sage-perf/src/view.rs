//! `sage3d bench view`: the browser viewer's frame rate, end to end — a generated home saved
//! as a scene folder, the viewer serving it on loopback, and the requests the page makes: a
//! keypress (a step through physics) and the first-person frame at the new pose (rendered on
//! the CPU and JPEG-encoded), timed over HTTP.

use crate::machine;
use sage_core::{Error, Result};
use sage_view::ViewOptions;
use sage_view::client::request;
use serde::Serialize;
use serde_json::{Value, json};
use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, mpsc};
use std::time::Instant;

/// What `bench view` measures.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewSettings {
    /// Gaussians in the generated home.
    pub gaussians: usize,
    /// Objects in it.
    pub objects: usize,
    /// Seed of the home.
    pub seed: u64,
    /// Keypresses (each a step and a frame).
    pub steps: usize,
    /// Frame size, pixels.
    pub size: (u32, u32),
}

impl Default for ViewSettings {
    fn default() -> Self {
        Self {
            gaussians: 1_000_000,
            objects: 60,
            seed: 1,
            steps: 60,
            size: (640, 480),
        }
    }
}

/// What `bench view` measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ViewReport {
    /// The machine ([`machine::describe`]).
    pub machine: String,
    /// Gaussians in the scene.
    pub gaussians: usize,
    /// Frame size.
    pub size: (u32, u32),
    /// Seconds from the first request to the scene's map (load, bodies, path finder).
    pub load_s: f64,
    /// Keypresses timed.
    pub steps: usize,
    /// Frames per second, frame requests alone (render + JPEG + HTTP).
    pub frames_per_s: f64,
    /// Keypress-to-frame updates per second (step + frame, as the page does them).
    pub updates_per_s: f64,
    /// Mean milliseconds of a step request.
    pub step_ms: f64,
    /// Mean JPEG size, kilobytes.
    pub jpeg_kb: f64,
}

impl fmt::Display for ViewReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "machine          {}", self.machine)?;
        writeln!(
            f,
            "scene            generated home, {} Gaussians; loaded (bodies, path finder, map) in {:.1} s",
            self.gaussians, self.load_s
        )?;
        writeln!(
            f,
            "frames           {:.1} frames/s at {}x{} (CPU render + JPEG + HTTP; {:.0} kB each)",
            self.frames_per_s, self.size.0, self.size.1, self.jpeg_kb
        )?;
        writeln!(
            f,
            "keypresses       {:.1} updates/s (step {:.2} ms + frame; {} keypresses)",
            self.updates_per_s, self.step_ms, self.steps
        )
    }
}

/// Runs `bench view`.
///
/// # Errors
///
/// The scene cannot be made or saved, the viewer cannot start, or a request fails.
pub fn run(settings: &ViewSettings) -> Result<ViewReport> {
    let scene = crate::generated_home(settings.seed, settings.objects, settings.gaussians)?;
    let gaussians = scene.gaussians.len();
    let dir = std::env::temp_dir().join(format!("sage3d-bench-view-{}", std::process::id()));
    let home = dir.join("home");
    scene.save(&home, sage_scene::SplatLayout::Compressed)?;
    let result = measure(&home, settings, gaussians);
    let _ = std::fs::remove_dir_all(&dir);
    result
}

/// Serves `home` and times the page's requests.
fn measure(
    home: &std::path::Path,
    settings: &ViewSettings,
    gaussians: usize,
) -> Result<ViewReport> {
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel();
    let flag = stop.clone();
    let opts = ViewOptions {
        port: 0,
        ..ViewOptions::new(home)
    };
    let server = std::thread::spawn(move || {
        sage_view::serve(
            &opts,
            move |s| {
                let _ = tx.send(s.addr);
            },
            move || !flag.load(Ordering::SeqCst),
        )
    });
    let addr = match rx.recv() {
        Ok(addr) => addr,
        Err(_) => {
            return Err(server
                .join()
                .map_err(|_| Error::invalid("the viewer panicked"))?
                .err()
                .unwrap_or_else(|| Error::invalid("the viewer did not start")));
        }
    };
    let ok = |method: &str, target: &str, body: Option<&Value>| {
        let reply = request(addr, method, target, body, &[])?;
        if reply.status != 200 {
            return Err(Error::invalid(format!(
                "{method} {target}: {} {}",
                reply.status,
                String::from_utf8_lossy(&reply.body)
            )));
        }
        Ok(reply)
    };
    let result = (|| {
        let t0 = Instant::now();
        ok("GET", "/api/scenes/home/map", None)?;
        let load_s = t0.elapsed().as_secs_f64();
        let state = ok("POST", "/api/sessions", Some(&json!({})))?.json()?;
        let id = state["session"].as_str().unwrap_or_default().to_string();
        let (w, h) = settings.size;
        let frame = |s: &Value| {
            let p = &s["pose"];
            format!(
                "/api/scenes/home/frame?x={}&y={}&z={}&yaw={}&width={w}&height={h}",
                p["x"], p["y"], p["z"], p["yaw"]
            )
        };
        // One warm-up frame: the renderer's first call sizes its buffers.
        ok("GET", &frame(&state), None)?;
        let (mut step_s, mut frame_s, mut bytes) = (0.0, 0.0, 0usize);
        for k in 0..settings.steps {
            // Walk forward, turning every third key (and around when blocked).
            let action = if k % 3 == 2 { "left" } else { "forward" };
            let t = Instant::now();
            let state = ok(
                "POST",
                &format!("/api/sessions/{id}/step"),
                Some(&json!({"action": action})),
            )?
            .json()?;
            step_s += t.elapsed().as_secs_f64();
            let t = Instant::now();
            bytes += ok("GET", &frame(&state), None)?.body.len();
            frame_s += t.elapsed().as_secs_f64();
        }
        let n = settings.steps.max(1) as f64;
        Ok(ViewReport {
            machine: machine::describe(),
            gaussians,
            size: settings.size,
            load_s,
            steps: settings.steps,
            frames_per_s: n / frame_s,
            updates_per_s: n / (frame_s + step_s),
            step_ms: step_s * 1e3 / n,
            jpeg_kb: bytes as f64 / n / 1e3,
        })
    })();
    stop.store(true, Ordering::SeqCst);
    server
        .join()
        .map_err(|_| Error::invalid("the viewer panicked"))??;
    result
}
