//! `sage3d demo`: the whole pipeline on synthetic scenes, end to end (`sage_pipeline::demo`).
//!
//! Every step is printed as the ordinary subcommand that does the same (`$ sage3d …`) and
//! reports what it made as that subcommand would, so the demo doubles as a worked example of
//! pointing the same commands at real data.

use sage_core::Result;
use sage_eval::Summary;
use sage_pipeline::demo::{self, DemoSettings, Step, StepReport, Tick};
use std::path::PathBuf;
use std::time::Instant;

/// Flags of `sage3d demo`.
#[derive(clap::Args)]
pub struct DemoArgs {
    /// Output folder: scenes/, dataset/, train_data/, runs/{agent}/ (each with report.html),
    /// overview.png; new, empty, or a demo's (rerunning resumes).
    #[arg(long, default_value = "demo")]
    out: PathBuf,
    /// Write into a folder holding other files (never replacing one of them).
    #[arg(long)]
    force: bool,
    /// Number of synthetic scenes (homes, every third an office).
    #[arg(long, default_value_t = 3)]
    scenes: usize,
    /// Seed of every random choice (scene k uses seed + k).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Trajectories per scene in the dataset.
    #[arg(long, default_value_t = 12)]
    per_scene: usize,
    /// Gaussians per five rooms of a synthetic scene (a scene gets its share by its rooms).
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

impl From<DemoArgs> for DemoSettings {
    fn from(a: DemoArgs) -> DemoSettings {
        DemoSettings {
            out: a.out,
            scenes: a.scenes,
            seed: a.seed,
            per_scene: a.per_scene,
            gaussians: a.gaussians,
            agents: a.agents,
            split: a.split,
            from: a.from,
        }
    }
}

/// One row per agent: the headline metrics of its run's summary.
fn agents_table(runs: &[(String, Summary)]) -> String {
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
    for (agent, s) in runs {
        text += &format!("{agent:<10} {:>8}", s.overall.episodes);
        for (key, _) in COLUMNS {
            match s.overall.means.get(key) {
                Some(v) => text += &format!(" {v:>7.3}"),
                None => text += &format!(" {:>7}", "-"),
            }
        }
        text.push('\n');
    }
    text
}

/// Prints what a step made, as its subcommand prints it.
fn print_step(step: &Step, report: &StepReport, secs: f64) {
    match (step, report) {
        (_, StepReport::Synth(scene)) => println!("{}", scene.summary()),
        (_, StepReport::NavMap(r)) => crate::nav_cmd::print_map(r),
        (_, StepReport::Physics(built)) => {
            let (scene, bodies, report) = &**built;
            crate::physics_cmd::print_build(scene, bodies, report);
        }
        (Step::Dataset { out, .. }, StepReport::Dataset(r)) => {
            crate::data_cmd::print_dataset(r, out, secs);
        }
        (Step::Eval { out, .. }, StepReport::Eval(r)) => {
            crate::eval_cmd::print_eval(&r.0, &r.1, out, secs);
        }
        (Step::TrainData { out, .. }, StepReport::TrainData(Some(m))) => {
            crate::data_cmd::print_render(m, out, m.counts.frames, secs);
        }
        (_, StepReport::TrainData(None)) => println!("the train split is empty: nothing to render"),
        (_, StepReport::Dataset(_) | StepReport::Eval(_) | StepReport::TrainData(_)) => {}
    }
}

/// Runs the demo and prints where everything is.
pub fn run(a: DemoArgs) -> Result<()> {
    let force = a.force;
    let s = DemoSettings::from(a);
    sage_pipeline::demo_folder::claim(&s, force)?;
    let start = Instant::now();
    let step_start = std::cell::Cell::new(Instant::now());
    let bar = crate::progress::bar("{bar:30} {pos}/{len} {msg} {elapsed}");
    let runs = demo::run(
        &s,
        &|k, n, step| {
            eprintln!(
                "\n[{}/{}] {}\n$ sage3d {}",
                k + 1,
                n,
                step.title(),
                step.command_line().join(" ")
            );
            step_start.set(Instant::now());
        },
        &|t: Tick<'_>| {
            bar.set_length(t.total as u64);
            bar.set_position(t.done as u64);
            bar.set_message(t.what.to_string());
        },
        &|step, report| {
            bar.finish_and_clear();
            bar.reset();
            print_step(step, report, step_start.get().elapsed().as_secs_f64());
        },
    )?;
    let overview = s.out.join("overview.png");
    println!(
        "\nsage3d demo finished in {:.0} s on {} threads ({} split, metrics in the sage mode):\n",
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
        s.split
    );
    print!("{}", agents_table(&runs));
    let out = s.out.display();
    println!(
        "\n  scenes    {}/   (semantic maps in */nav/)\n  dataset   {out}/dataset/  (episodes/*.jsonl, R2R and GVLN files)\n  training  {out}/train_data/  (NaVILA annotations, frames, preview.gif)\n  runs      {out}/runs/{{agent}}/  (episodes.jsonl, summary.json, report.html)\n  overview  {}",
        s.scenes_folder().display(),
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
        let a = Wrapper::parse_from(["demo", "--out", out.to_str().unwrap(), "--scenes", "3"]).demo;
        let steps = demo::plan(&DemoSettings::from(a)).unwrap();
        assert_eq!(steps.len(), 3 * 3 + 2 + 3);
        for s in &steps {
            let argv = std::iter::once("sage3d".to_string()).chain(s.command_line());
            crate::Cli::try_parse_from(argv)
                .unwrap_or_else(|e| panic!("{:?}: {e}", s.command_line()));
        }
    }
}
