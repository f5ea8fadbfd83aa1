//! `--device cpu|gpu|auto` on every command that renders: unknown names are refused naming the
//! allowed ones, the CPU's images do not change, `auto` says where it rendered, `gpu` renders
//! on any adapter (Mesa's software lavapipe included) and the render benchmark reports batches
//! there.
//!
//! A GPU test without any adapter prints a note and passes, unless `SAGE3D_REQUIRE_GPU` is
//! set (as the test script sets it): then it fails.

mod common;

use common::{eval_output, ok, s, sage3d, small_dataset, small_scene, stderr};
use std::path::Path;
use std::process::Output;

/// True when `out`, a `--device gpu` run, failed because this machine has no GPU adapter at
/// all; the test then stops with a note, or fails under `SAGE3D_REQUIRE_GPU`.
fn no_adapter(out: &Output) -> bool {
    let err = stderr(out);
    if out.status.success() || !err.contains("no GPU adapter") {
        return false;
    }
    assert!(
        std::env::var_os("SAGE3D_REQUIRE_GPU").is_none(),
        "SAGE3D_REQUIRE_GPU is set and there is no GPU adapter: {err}"
    );
    eprintln!(
        "note: no GPU adapter here (Mesa's mesa-vulkan-drivers gives a software one); skipped"
    );
    true
}

/// The `renderer: …` line a command printed on standard error, asserting there is one.
fn renderer_line(out: &Output) -> String {
    let err = stderr(out);
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("renderer: "))
        .collect();
    assert_eq!(lines.len(), 1, "one renderer line: {err}");
    lines[0].to_string()
}

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// A render of `scene` into `out` at 48×36 with the extra flags.
fn render(scene: &Path, out: &Path, extra: &[&str]) -> Output {
    let base = [
        "render",
        s(scene),
        "--out",
        s(out),
        "--width",
        "48",
        "--height",
        "36",
        "--yaw",
        "30",
    ];
    sage3d(&[&base[..], extra].concat())
}

#[test]
fn every_rendering_command_refuses_an_unknown_device_and_explains_the_flag() {
    // (the command, its arguments but for --device)
    let commands: [(&[&str], &[&str]); 5] = [
        (&["render"], &["scene", "--out", "out"]),
        (&["env", "run"], &["scene", "--episodes", "e.jsonl"]),
        (&["eval"], &["data", "--agent", "oracle", "--out", "run"]),
        (&["data", "render"], &["data", "--out", "train"]),
        (&["bench", "render"], &[]),
    ];
    for (command, args) in commands {
        let out = sage3d(&[command, args, &["--device", "bogus"]].concat());
        let err = stderr(&out);
        assert!(!out.status.success(), "{command:?}");
        assert!(
            err.contains("bogus") && err.contains("cpu, gpu, auto"),
            "{command:?}: {err}"
        );
        let help = ok(&[command, &["--help"]].concat());
        let help = help.split_whitespace().collect::<Vec<_>>().join(" ");
        assert!(
            help.contains("--device <cpu|gpu|auto>")
                && help.contains("a hardware GPU when there is one, else the CPU")
                && help.contains("an error when there is none")
                && help.contains("[default: cpu]"),
            "{command:?}: {help}"
        );
    }
}

#[test]
fn the_cpu_renders_the_same_images_with_or_without_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    small_scene(&scene, "3", "3000");
    let plain = render(&scene, &dir.path().join("plain"), &[]);
    let cpu = render(&scene, &dir.path().join("cpu"), &["--device", "cpu"]);
    assert!(
        plain.status.success() && cpu.status.success(),
        "{}",
        stderr(&cpu)
    );
    assert!(renderer_line(&cpu).starts_with("renderer: cpu ("));
    for f in [
        "rgb.png",
        "depth.npy",
        "alpha.npy",
        "instance.png",
        "semantic.png",
    ] {
        assert_eq!(
            bytes(&dir.path().join("plain").join(f)),
            bytes(&dir.path().join("cpu").join(f)),
            "{f}"
        );
    }
    let record: serde_json::Value =
        serde_json::from_slice(&bytes(&dir.path().join("cpu/sage3d_run.json"))).unwrap();
    assert_eq!(record["settings"]["device"], "cpu", "{record}");
    // The files the render read, each with its hash: the Gaussians and the annotations.
    let inputs = record["inputs"].as_object().unwrap();
    assert!(
        inputs.keys().any(|k| k.starts_with("3dgs")) && inputs.contains_key("labels.json"),
        "{record}"
    );
    assert!(
        inputs
            .values()
            .all(|h| h.as_str().is_some_and(|h| h.len() == 16))
    );
    let info: serde_json::Value =
        serde_json::from_slice(&bytes(&dir.path().join("cpu/render.json"))).unwrap();
    assert!(info["stats_ms"]["raster"].is_number() && info["splats"].is_number());
}

#[test]
fn auto_says_where_it_rendered() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    small_scene(&scene, "3", "3000");
    let out = render(&scene, &dir.path().join("auto"), &["--device", "auto"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let line = renderer_line(&out);
    // Without a hardware GPU (a software adapter does not count) the CPU renders and says why;
    // with one, the GPU renders.
    if line.starts_with("renderer: cpu") {
        assert!(line.contains("(auto: no hardware GPU adapter"), "{line}");
        let cpu = render(&scene, &dir.path().join("cpu"), &[]);
        assert!(cpu.status.success());
        assert_eq!(
            bytes(&dir.path().join("auto/rgb.png")),
            bytes(&dir.path().join("cpu/rgb.png"))
        );
    } else {
        assert!(
            line.starts_with("renderer: gpu: ") && !line.contains("software"),
            "{line}"
        );
    }
}

#[test]
fn gpu_renders_the_images_and_names_the_adapter() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    small_scene(&scene, "3", "3000");
    let gpu_dir = dir.path().join("gpu");
    let out = render(&scene, &gpu_dir, &["--device", "gpu", "--turntable", "3"]);
    if no_adapter(&out) {
        return;
    }
    assert!(out.status.success(), "{}", stderr(&out));
    let line = renderer_line(&out);
    assert!(line.starts_with("renderer: gpu: "), "{line}");
    for f in [
        "rgb.png",
        "depth.npy",
        "turntable.gif",
        "turntable/rgb_002.png",
    ] {
        assert!(gpu_dir.join(f).is_file(), "{f} missing");
    }
    let info: serde_json::Value =
        serde_json::from_slice(&bytes(&gpu_dir.join("render.json"))).unwrap();
    assert!(info["frame_ms"].is_number(), "{info}");
    assert_eq!(info["renderer"], line["renderer: ".len()..], "{info}");
    // The same picture as the CPU's: the GPU forms the image with the same constants, so the
    // colours differ by rounding only.
    let cpu = render(&scene, &dir.path().join("cpu"), &[]);
    assert!(cpu.status.success());
    let (a, b) = (
        rgb(&gpu_dir.join("rgb.png")),
        rgb(&dir.path().join("cpu/rgb.png")),
    );
    assert_eq!(a.len(), b.len());
    let mean = a
        .iter()
        .zip(&b)
        .map(|(x, y)| x.abs_diff(*y) as f64)
        .sum::<f64>()
        / a.len() as f64;
    assert!(mean < 2.0, "mean difference {mean:.2} of 255");
}

/// The RGB bytes of an 8-bit PNG.
fn rgb(path: &Path) -> Vec<u8> {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    buf
}

/// The fixed depth slabs a JSON bench report names.
fn report_slabs(out: &std::process::Output) -> Option<u64> {
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    report.get("slabs").and_then(serde_json::Value::as_u64)
}

#[test]
fn bench_render_tunes_only_the_gpu_and_only_to_settings_it_has() {
    // Refused before the scene is generated.
    for flags in [["--slabs", "2"], ["--blending", "columns"]] {
        let cpu = sage3d(&[&["bench", "render"], &flags[..]].concat());
        assert!(!cpu.status.success());
        assert!(stderr(&cpu).contains("--device gpu"), "{}", stderr(&cpu));
    }
    let unknown = sage3d(&["bench", "render", "--blending", "pixels"]);
    assert!(!unknown.status.success());
    assert!(
        stderr(&unknown).contains("blocks, columns"),
        "{}",
        stderr(&unknown)
    );
    let out = sage3d(&["bench", "render", "--device", "gpu", "--slabs", "5"]);
    if no_adapter(&out) {
        return;
    }
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("1 to 4 depth slabs, got 5"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn bench_render_on_the_gpu_reports_frame_times_and_batches() {
    let out = sage3d(&[
        "bench",
        "render",
        "--device",
        "gpu",
        "--gaussians",
        "3000",
        "--frames",
        "2",
        "--sizes",
        "32x24",
        "--batches",
        "1,4",
        "--batch-size",
        "32x32",
        "--slabs",
        "2",
        "--blending",
        "columns",
        "--json",
    ]);
    if no_adapter(&out) {
        return;
    }
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(report_slabs(&out), Some(2));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["blending"], "columns", "{report}");
    // The measuring process says once which renderer it measures.
    let line = renderer_line(&out);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["renderer"], line["renderer: ".len()..], "{report}");
    assert!(report["machine"].is_string() && report.get("index_bytes").is_none());
    let sizes = report["sizes"].as_array().unwrap();
    assert_eq!(sizes.len(), 1);
    assert!(sizes[0]["median_ms"].as_f64().unwrap() > 0.0 && sizes[0].get("cull_ms").is_none());
    // The CPU renderer on the same headings in the same run, for the ratio.
    assert!(
        sizes[0]["cpu_median_ms"].as_f64().unwrap() > 0.0,
        "{report}"
    );
    let batches = report["batches"].as_array().unwrap();
    let cameras: Vec<u64> = batches
        .iter()
        .map(|b| b["cameras"].as_u64().unwrap())
        .collect();
    assert_eq!(cameras, [1, 4]);
    for b in batches {
        assert_eq!(
            (b["width"].as_u64(), b["height"].as_u64()),
            (Some(32), Some(32))
        );
        assert!(b["batch_ms"].as_f64().unwrap() > 0.0 && b["frames_per_s"].as_f64().unwrap() > 0.0);
        // The same batches streamed, the next in flight while one is read back.
        assert!(
            b["streamed_frames_per_s"].as_f64().unwrap() > 0.0,
            "{report}"
        );
        // Single frames of the batch's size (no single size here) timed in its rounds.
        let (single, mean) = (b["single_ms"].as_f64(), b["single_mean_ms"].as_f64());
        assert!(
            single.is_some_and(|t| t > 0.0) && mean.is_some_and(|t| t > 0.0),
            "{report}"
        );
        // Where the device writes timestamps: its stages, its copy of the images and the
        // host's unpacking of them.
        if let Some(p) = b.get("gpu_passes") {
            let raster = p["raster_ms"].as_f64().unwrap();
            let unpack = p["unpack_ms"].as_f64().unwrap();
            assert!(raster > 0.0 && unpack > 0.0, "{report}");
            assert!(p["read_back_ms"].as_f64().unwrap() >= 0.0, "{report}");
        }
    }
}

#[test]
fn env_eval_and_data_render_say_where_they_render_and_record_the_device() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let (scene, episodes) = (scenes.join("home1"), data.join("episodes/train.jsonl"));
    let env_run = ["env", "run", s(&scene), "--episodes", s(&episodes)];
    let out = sage3d(&[&env_run[..], &["--render", "--device", "auto"]].concat());
    assert!(out.status.success(), "{}", stderr(&out));
    let line = renderer_line(&out);
    assert!(!line.contains("not used"), "{line}");
    let blind = sage3d(&env_run);
    assert!(blind.status.success(), "{}", stderr(&blind));
    assert!(renderer_line(&blind).ends_with("(not used: without --render no images are rendered)"));

    let run = dir.path().join("run");
    let eval = |run: &Path, device: &[&str]| {
        eval_output(
            "2",
            &data,
            &scenes,
            run,
            &[&["--agent", "forward"], device].concat(),
        )
    };
    let out = eval(&run, &["--device", "auto"]);
    assert!(out.status.success(), "{}", stderr(&out));
    renderer_line(&out);
    let record: serde_json::Value =
        serde_json::from_slice(&bytes(&run.join("sage3d_run.json"))).unwrap();
    assert_eq!(record["settings"]["device"], "auto", "{record}");
    // A run resumes only on the device it started on.
    let other = eval(&run, &["--device", "cpu"]);
    assert!(!other.status.success());
    assert!(
        stderr(&other).contains("other settings"),
        "{}",
        stderr(&other)
    );
    // On the CPU the run record is as it always was: no device named.
    let cpu_run = dir.path().join("cpu_run");
    let cpu = eval(&cpu_run, &[]);
    assert!(cpu.status.success(), "{}", stderr(&cpu));
    let record: serde_json::Value =
        serde_json::from_slice(&bytes(&cpu_run.join("sage3d_run.json"))).unwrap();
    assert!(record["settings"].get("device").is_none(), "{record}");

    let train = dir.path().join("train");
    let out = sage3d(&[
        "data",
        "render",
        s(&data),
        "--scenes",
        s(&scenes),
        "--out",
        s(&train),
        "--width",
        "32",
        "--height",
        "24",
        "--keep-failed",
        "--device",
        "auto",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    renderer_line(&out);
    let manifest: serde_json::Value =
        serde_json::from_slice(&bytes(&train.join("manifest.json"))).unwrap();
    assert_eq!(manifest["settings"]["device"], "auto", "{manifest}");
}
