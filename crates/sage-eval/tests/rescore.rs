//! Rescoring a finished run from its stored records gives the numbers of an evaluation of the
//! same agent in the new mode: every episode's metrics and the summary are equal, whichever
//! mode the run was scored in; GN-Bench's distances are only in a `gnbench` run, so only such a
//! run rescores in `gnbench`; the run rescored is left as it was, and a rescoring never writes
//! into it or over another run; a rescoring killed part-way is its rerun's to write again.

mod common;

use sage_eval::report::read_run;
use sage_eval::{EvalRecord, EvalSettings, Summary};
use sage_io::files::read_tree;
use sage_metrics::{Dtw, Mode};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// A small dataset and its scenes, made once.
struct Fixture {
    _dir: tempfile::TempDir,
    scenes: PathBuf,
    data: PathBuf,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let (scenes, _, data) = common::small_dataset(dir.path(), 4);
        Fixture {
            _dir: dir,
            scenes,
            data,
        }
    })
}

/// The random agent (it fails some episodes and succeeds others, collides, wanders) over the
/// train split, scored in `mode` with `dtw`.
fn settings(mode: Mode, dtw: Dtw) -> EvalSettings {
    let f = fixture();
    EvalSettings {
        dataset: f.data.clone(),
        scenes: f.scenes.clone(),
        split: "train".into(),
        agent: "random".parse().unwrap(),
        mode,
        dtw,
        seed: 3,
        preset: "sage".into(),
        device: Default::default(),
        splat_bodies: Default::default(),
    }
}

/// An evaluation in `mode` with `dtw` into `out`.
fn evaluate(mode: Mode, dtw: Dtw, out: &Path) {
    sage_eval::run(&settings(mode, dtw), out, &|_, _| {}).unwrap();
}

fn summary(run: &Path) -> Summary {
    serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap()).unwrap()
}

fn records(run: &Path) -> Vec<EvalRecord> {
    read_run(run).unwrap().records
}

/// Two numbers equal to the last bits of a double: the records are text, and serde_json reads
/// a number back to within an ulp, so inputs read from a file may differ from those an
/// evaluation held in memory by that much (a metric defined for one and not the other, or a
/// NaN against a number, is a difference).
fn same(x: f64, y: f64) -> bool {
    x == y || (x - y).abs() <= 1e-12 * x.abs().max(y.abs()) || (x.is_nan() && y.is_nan())
}

/// The metrics of two records as (name, value) pairs, the same names in the same order.
fn same_metrics(a: &sage_metrics::EpisodeMetrics, b: &sage_metrics::EpisodeMetrics) -> bool {
    let (a, b) = (a.named(), b.named());
    a.len() == b.len()
        && a.iter().zip(&b).all(|((na, va), (nb, vb))| {
            na == nb
                && match (va, vb) {
                    (Some(x), Some(y)) => same(*x, *y),
                    (x, y) => x == y,
                }
        })
}

/// The two runs hold the same episodes with the same metrics and summary.
fn same_numbers(rescored: &Path, evaluated: &Path) {
    let (a, b) = (records(rescored), records(evaluated));
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.episode_id, y.episode_id);
        match (&x.metrics, &y.metrics) {
            (Some(m), Some(n)) => assert!(same_metrics(m, n), "{}: {m:?} vs {n:?}", x.episode_id),
            (m, n) => assert_eq!(m, n, "{}", x.episode_id),
        }
        assert_eq!(x.termination, y.termination, "{}", x.episode_id);
        assert_eq!(
            x.record.as_ref().map(|r| r.gnbench.is_some()),
            y.record.as_ref().map(|r| r.gnbench.is_some()),
            "{}",
            x.episode_id
        );
    }
    let (s, t) = (summary(rescored), summary(evaluated));
    let means = |s: &Summary| {
        std::iter::once(("overall".to_string(), s.overall.clone()))
            .chain(s.slices.iter().flat_map(|(axis, slices)| {
                slices
                    .iter()
                    .map(move |(name, a)| (format!("{axis}.{name}"), a.clone()))
            }))
            .collect::<Vec<_>>()
    };
    let (ms, mt) = (means(&s), means(&t));
    assert_eq!(
        ms.iter().map(|(n, a)| (n, a.episodes)).collect::<Vec<_>>(),
        mt.iter().map(|(n, a)| (n, a.episodes)).collect::<Vec<_>>()
    );
    for ((name, a), (_, b)) in ms.iter().zip(&mt) {
        assert_eq!(
            a.means.keys().collect::<Vec<_>>(),
            b.means.keys().collect::<Vec<_>>(),
            "{name}"
        );
        for (k, v) in &a.means {
            assert!(same(*v, b.means[k]), "{name}.{k}: {v} vs {}", b.means[k]);
        }
    }
    // Everything else of the summary is exactly the evaluation's.
    let strip = |mut s: Summary| {
        s.overall = Default::default();
        s.slices.clear();
        s
    };
    assert_eq!(strip(s), strip(t));
}

#[test]
fn a_rescored_run_has_the_numbers_of_an_evaluation_in_that_mode() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str| dir.path().join(name);
    evaluate(Mode::Sage, Dtw::Exact, &run("sage"));
    evaluate(Mode::Vlnce, Dtw::Fast, &run("vlnce-fast"));
    evaluate(Mode::GnBench, Dtw::Exact, &run("gnbench"));
    evaluate(Mode::SageOfficial, Dtw::Exact, &run("official"));
    let scored = records(&run("sage"))
        .iter()
        .filter(|r| r.metrics.is_some())
        .count();
    assert!(scored >= 3, "{scored} scored episodes");
    // The modes give different numbers here, or the comparison below would prove nothing.
    assert_ne!(
        summary(&run("sage")).overall,
        summary(&run("vlnce-fast")).overall
    );
    let before = read_tree(&run("sage")).unwrap();
    for (from, mode, dtw, evaluated) in [
        ("sage", Some(Mode::Vlnce), Some(Dtw::Fast), "vlnce-fast"),
        ("vlnce-fast", Some(Mode::Sage), Some(Dtw::Exact), "sage"),
        ("gnbench", Some(Mode::SageOfficial), None, "official"),
        ("sage", Some(Mode::SageOfficial), None, "official"),
        // GN-Bench's distances are in the gnbench run's records: they rescore in gnbench.
        ("official", Some(Mode::Sage), None, "sage"),
        ("gnbench", None, None, "gnbench"),
    ] {
        let out = run(&format!("{from}-to-{evaluated}"));
        let done = {
            let _lock = sage_eval::claim(&out, false).unwrap();
            sage_eval::rescore(&run(from), mode, dtw, &out).unwrap()
        };
        let expected = summary(&run(evaluated));
        assert_eq!((done.to.mode, done.to.dtw), (expected.mode, expected.dtw));
        assert_eq!(done.rescored + done.faulted, records(&run(from)).len());
        same_numbers(&out, &run(evaluated));
        // The new folder is a run of that evaluation: an `eval` in the same settings resumes it,
        // with nothing left to run, the same summary and the record of its provenance.
        let target = settings(done.to.mode, done.to.dtw);
        let provenance =
            |run: &Path| sage_eval::folder::run_record(run).unwrap()["rescored_from"].clone();
        let from_before = provenance(&out);
        assert!(from_before["run"].is_string(), "{from_before}");
        let resumed = sage_eval::run(&target, &out, &|_, _| {}).unwrap();
        assert_eq!((resumed.ran, resumed.resumed), (0, resumed.total));
        same_numbers(&out, &run(evaluated));
        assert_eq!(provenance(&out), from_before);
    }
    // The run rescored is only read.
    assert_eq!(read_tree(&run("sage")).unwrap(), before);
}

#[test]
fn a_rescoring_is_refused_before_it_writes_anything() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("sage");
    evaluate(Mode::Sage, Dtw::Exact, &run);
    let before = read_tree(&run).unwrap();
    let refused = |out: &Path, mode: Mode| {
        sage_eval::rescore(&run, Some(mode), None, out)
            .unwrap_err()
            .to_string()
    };
    // A run not scored in gnbench has no GN-Bench distances: refused naming an episode, and
    // the new folder stays empty.
    let out = dir.path().join("to-gnbench");
    std::fs::create_dir_all(&out).unwrap();
    let e = refused(&out, Mode::GnBench);
    assert!(
        e.contains("episodes.jsonl") && e.contains("episode ") && e.contains("GN-Bench"),
        "{e}"
    );
    assert!(read_tree(&out).unwrap().is_empty());
    // Into the run itself, or over another run: refused.
    let e = refused(&run, Mode::Vlnce);
    assert!(e.contains("a rescoring writes a new run folder"), "{e}");
    let other = dir.path().join("other");
    evaluate(Mode::Vlnce, Dtw::Exact, &other);
    let e = refused(&other, Mode::Vlnce);
    assert!(e.contains("the folder holds a run already"), "{e}");
    // A folder that is not a run: a dataset (with the run record `data build` writes).
    let data = dir.path().join("data");
    std::fs::create_dir_all(data.join("episodes")).unwrap();
    sage_io::run::write_run_record(&data, "data build", Some(0), serde_json::json!({})).unwrap();
    let e = sage_eval::rescore(&data, Some(Mode::Vlnce), None, &out)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("not an evaluation run (its sage3d_run.json is from `data build`"),
        "{e}"
    );
    assert_eq!(read_tree(&run).unwrap(), before);
}

/// What a rescoring killed part-way leaves in `out`, copied from the finished rescoring in
/// `whole`: its run record marked unfinished and `files` of its outputs.
fn killed_rescoring(whole: &Path, out: &Path, files: &[&str]) {
    std::fs::create_dir_all(out).unwrap();
    for name in files {
        std::fs::copy(whole.join(name), out.join(name)).unwrap();
    }
    let mut record = sage_eval::folder::run_record(whole).unwrap();
    record["status"] = sage_io::run::UNFINISHED.into();
    sage_io::files::write_json(&out.join(sage_io::run::RUN_RECORD), &record).unwrap();
}

#[test]
fn a_rescoring_killed_part_way_is_written_again_by_its_rerun_and_by_nothing_else() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("sage");
    evaluate(Mode::Sage, Dtw::Exact, &run);
    let job = sage_eval::report::ReportJob::new(&f.scenes);
    let rescore = |out: &Path, mode: Mode, force: bool| {
        let _lock = sage_eval::claim_rescoring(out, force)?;
        sage_eval::rescore_with_report(&run, Some(mode), None, out, &job)
    };
    let whole = dir.path().join("whole");
    rescore(&whole, Mode::Vlnce, false).unwrap();
    let record = sage_eval::folder::run_record(&whole).unwrap();
    assert_eq!(record["status"], "finished");
    let files = |run: &Path| {
        let mut tree = read_tree(run).unwrap();
        tree.retain(|name, _| !name.starts_with("report"));
        tree
    };
    // Killed after its records and summary (before its report), and killed after its first
    // file: a reader says what to rerun, and the rerun — with `force` too — writes it all.
    let mut killed = Vec::new();
    for (k, (outputs, force)) in [
        (&["episodes.jsonl", "summary.json"][..], false),
        (&["episodes.jsonl"][..], false),
        (&[][..], true),
    ]
    .into_iter()
    .enumerate()
    {
        let out = dir.path().join(format!("killed{k}"));
        killed_rescoring(&whole, &out, outputs);
        let e = read_run(&out).unwrap_err().to_string();
        assert!(
            e.contains("the rescoring in this folder was not finished")
                && e.contains(&format!(
                    "rerun the same rescoring (`sage3d report {} --mode vlnce --dtw exact --out {}`)",
                    std::fs::canonicalize(&run).unwrap().display(),
                    out.display()
                )),
            "{e}"
        );
        rescore(&out, Mode::Vlnce, force).unwrap();
        assert_eq!(files(&out), files(&whole), "{outputs:?}");
        assert!(out.join("report.html").is_file());
        killed.push(out);
    }
    // A finished rescoring is a run: refused, as is an unfinished rescoring in another mode
    // and an evaluation killed half-way.
    let held = |e: sage_core::Error| {
        let e = e.to_string();
        assert!(e.contains("the folder holds a run already"), "{e}");
    };
    held(rescore(&killed[0], Mode::Vlnce, false).unwrap_err());
    let other_mode = dir.path().join("other_mode");
    killed_rescoring(&whole, &other_mode, &["episodes.jsonl"]);
    let before = read_tree(&other_mode).unwrap();
    held(rescore(&other_mode, Mode::SageOfficial, true).unwrap_err());
    assert_eq!(read_tree(&other_mode).unwrap(), before);
    let eval = dir.path().join("eval");
    killed_rescoring(&run, &eval, &["episodes.jsonl"]);
    held(rescore(&eval, Mode::Vlnce, true).unwrap_err());
    // A folder of other files is refused naming the command run, a rescoring's `report`.
    let foreign = dir.path().join("foreign");
    std::fs::create_dir(&foreign).unwrap();
    std::fs::write(foreign.join("notes.txt"), "mine").unwrap();
    let e = rescore(&foreign, Mode::Vlnce, false)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("holds files `sage3d report` did not write ('notes.txt')"),
        "{e}"
    );
    assert_eq!(
        std::fs::read_to_string(foreign.join("notes.txt")).unwrap(),
        "mine"
    );
}
