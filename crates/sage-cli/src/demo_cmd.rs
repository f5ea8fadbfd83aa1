//! `sage3d demo`: the whole pipeline on synthetic scenes, end to end.
//!
//! Every step is one of the ordinary subcommands, run exactly as printed (`$ sage3d …`), so
//! the demo doubles as a worked example of pointing the same commands at real data. Each step
//! resumes: scenes already synthesised are kept, collision hulls come from their cache, the
//! dataset builder and the evaluator skip what their folders already hold.

use sage_bench::eval::{SUMMARY_FILE, Summary};
use sage_core::{Error, Result};
use sage_io::run::RUN_RECORD;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Flags of `sage3d demo`.
#[derive(clap::Args)]
pub struct DemoArgs {
    /// Output folder: scenes/, dataset/, runs/{agent}/ (each with report.html), overview.png.
    #[arg(long, default_value = "demo")]
    out: PathBuf,
    /// Number of synthetic scenes (homes, every third an office).
    #[arg(long, default_value_t = 3)]
    scenes: usize,
    /// Seed of every random choice (scene k uses seed + k).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Trajectories per scene in the dataset.
    #[arg(long, default_value_t = 12)]
    per_scene: usize,
    /// Gaussians per scene.
    #[arg(long, default_value_t = 150_000)]
    gaussians: usize,
    /// Agents to evaluate, comma-separated (any `--agent` of `sage3d eval`).
    #[arg(long, value_delimiter = ',', default_value = "oracle,random,forward")]
    agents: Vec<String>,
    /// Dataset split the agents are evaluated on.
    #[arg(long, default_value = "test_balanced")]
    split: String,
    /// Run the pipeline on these scenes instead of synthetic ones: a folder of scene folders
    /// (InteriorGS or ours). Maps go to SCENE/nav, collision hulls to SCENE/.sage3d.
    #[arg(long)]
    from: Option<PathBuf>,
}

/// One step of the demo: a title and the subcommand that does it.
#[derive(Debug, Clone, PartialEq)]
struct Step {
    title: String,
    argv: Vec<String>,
}

impl Step {
    fn new(title: impl Into<String>, argv: &[&str]) -> Step {
        Step {
            title: title.into(),
            argv: argv.iter().map(|s| s.to_string()).collect(),
        }
    }
}

/// The name of demo scene `k` and its kind.
fn scene_name(k: usize) -> (String, &'static str) {
    let kind = if k % 3 == 2 { "office" } else { "home" };
    (format!("{kind}_{k}"), kind)
}

fn path_arg(p: &Path) -> &str {
    p.to_str().unwrap_or_default()
}

/// The steps of the demo, in order (pure: what runs is decided before anything runs).
fn plan(a: &DemoArgs) -> Result<Vec<Step>> {
    if a.scenes == 0 {
        return Err(Error::invalid("--scenes must be at least 1"));
    }
    if a.agents.is_empty() {
        return Err(Error::invalid("--agents names no agent"));
    }
    let scenes = scenes_folder(a);
    let dataset = a.out.join("dataset");
    let mut steps = Vec::new();
    let dirs: Vec<(String, PathBuf)> = match &a.from {
        Some(from) => sage_io::scenes::scene_dirs_by_name(from)?
            .into_iter()
            .collect(),
        None => (0..a.scenes)
            .map(|k| (scene_name(k).0, scenes.join(scene_name(k).0)))
            .collect(),
    };
    for (k, (name, dir)) in dirs.iter().enumerate() {
        if a.from.is_none() && !dir.join(RUN_RECORD).is_file() {
            let kind = scene_name(k).1;
            steps.push(Step::new(
                format!("synthesise scene {name}"),
                &[
                    "scene",
                    "synth",
                    "--kind",
                    kind,
                    "--seed",
                    &(a.seed + k as u64).to_string(),
                    "--gaussians",
                    &a.gaussians.to_string(),
                    "--out",
                    path_arg(dir),
                ],
            ));
        }
        steps.push(Step::new(
            format!("semantic map and occupancy of {name}"),
            &["nav", "map", path_arg(dir)],
        ));
        steps.push(Step::new(
            format!("collision bodies of {name}"),
            &["physics", "build", path_arg(dir)],
        ));
    }
    steps.push(Step::new(
        "trajectories, instructions, episodes and splits",
        &[
            "data",
            "build",
            path_arg(&scenes),
            "--out",
            path_arg(&dataset),
            "--per-scene",
            &a.per_scene.to_string(),
            "--seed",
            &a.seed.to_string(),
        ],
    ));
    for agent in &a.agents {
        let run = a.out.join("runs").join(agent);
        steps.push(Step::new(
            format!("evaluate the {agent} agent"),
            &[
                "eval",
                path_arg(&dataset),
                "--scenes",
                path_arg(&scenes),
                "--agent",
                agent,
                "--split",
                &a.split,
                "--seed",
                &a.seed.to_string(),
                "--out",
                path_arg(&run),
            ],
        ));
    }
    Ok(steps)
}

/// Where the scenes are: `--from`, or the synthetic ones under OUT/scenes.
fn scenes_folder(a: &DemoArgs) -> PathBuf {
    a.from.clone().unwrap_or_else(|| a.out.join("scenes"))
}

/// One row per agent: the headline metrics of its run's summary.
fn agents_table(out: &Path, agents: &[String]) -> Result<String> {
    const COLUMNS: [(&str, &str); 6] = [
        ("sr", "SR"),
        ("osr", "OSR"),
        ("spl", "SPL"),
        ("ne", "NE"),
        ("ndtw", "nDTW"),
        ("cr", "CR"),
    ];
    let mut text = format!("{:<10} {:>8}", "agent", "episodes");
    for (_, title) in COLUMNS {
        text += &format!(" {title:>7}");
    }
    text.push('\n');
    for agent in agents {
        let path = out.join("runs").join(agent).join(SUMMARY_FILE);
        let s: Summary = sage_io::files::read_json(&path)?;
        text += &format!("{agent:<10} {:>8}", s.overall.episodes);
        for (key, _) in COLUMNS {
            match s.overall.means.get(key) {
                Some(v) => text += &format!(" {v:>7.3}"),
                None => text += &format!(" {:>7}", "-"),
            }
        }
        text.push('\n');
    }
    Ok(text)
}

/// Fails early, with what to do, when the split to evaluate holds no episode (with few
/// scenes every scene can go to the training split).
fn check_split(dataset: &Path, split: &str) -> Result<()> {
    let (_, episodes) = sage_bench::eval::split_episodes(dataset, split)?;
    if episodes.is_empty() {
        return Err(Error::invalid(format!(
            "the {split} split is empty (with few scenes, all of them can land in train); pass --split train or more --scenes"
        ))
        .in_file(dataset));
    }
    Ok(())
}

/// Runs the demo and prints where everything is.
pub fn run(a: DemoArgs) -> Result<()> {
    let start = Instant::now();
    let steps = plan(&a)?;
    for (k, step) in steps.iter().enumerate() {
        eprintln!(
            "\n[{}/{}] {}\n$ sage3d {}",
            k + 1,
            steps.len(),
            step.title,
            step.argv.join(" ")
        );
        if step.argv[0] == "eval" {
            check_split(&a.out.join("dataset"), &a.split)?;
        }
        crate::run_subcommand(&step.argv)
            .map_err(|e| e.within(format!("demo step '{}'", step.title)))?;
    }
    let overview = a.out.join("overview.png");
    sage_pipeline::overview::write(
        &scenes_folder(&a),
        &a.out.join("runs").join(&a.agents[0]),
        &overview,
    )?;
    println!(
        "\nsage3d demo finished in {:.0} s on {} threads ({} split, metrics in the sage mode):\n",
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
        a.split
    );
    print!("{}", agents_table(&a.out, &a.agents)?);
    let out = a.out.display();
    println!(
        "\n  scenes    {}/   (semantic maps in */nav/)\n  dataset   {out}/dataset/  (episodes/*.jsonl, R2R and GVLN files)\n  runs      {out}/runs/{{agent}}/  (episodes.jsonl, summary.json, report.html)\n  overview  {}",
        scenes_folder(&a).display(),
        overview.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Wrapper {
        #[command(flatten)]
        demo: DemoArgs,
    }

    #[test]
    fn every_planned_step_is_a_valid_command_line() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("demo");
        let a = Wrapper::parse_from(["demo", "--out", path_arg(&out), "--scenes", "3"]).demo;
        let steps = plan(&a).unwrap();
        // Three scenes × (synth, map, physics), the dataset, three agents.
        assert_eq!(steps.len(), 3 * 3 + 1 + 3);
        assert!(steps.iter().any(|s| s.argv.contains(&"office".to_string())));
        for s in &steps {
            let argv = std::iter::once("sage3d".to_string()).chain(s.argv.iter().cloned());
            crate::Cli::try_parse_from(argv).unwrap_or_else(|e| panic!("{:?}: {e}", s.argv));
        }
        // A scene already synthesised is kept.
        let first = out.join("scenes").join(scene_name(0).0);
        std::fs::create_dir_all(&first).unwrap();
        std::fs::write(first.join(RUN_RECORD), "{}").unwrap();
        assert_eq!(plan(&a).unwrap().len(), steps.len() - 1);
        let none = Wrapper::parse_from(["demo", "--scenes", "0"]).demo;
        assert!(plan(&none).unwrap_err().to_string().contains("--scenes"));
    }
}
