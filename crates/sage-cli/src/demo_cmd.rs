//! `sage3d demo`: the whole pipeline on synthetic scenes, end to end (`sage_pipeline::demo`).
//!
//! Every step is printed as the ordinary subcommand that does the same (`$ sage3d …`) and
//! reports what it made as that subcommand would, so the demo doubles as a worked example of
//! pointing the same commands at real data.

use sage_core::Result;
use sage_eval::Summary;
use sage_pipeline::demo::{self, DemoSettings, Step, StepReport, Tick};
use std::path::Path;
use std::time::Instant;

/// Flags of `sage3d demo`.
#[derive(clap::Args)]
pub struct DemoArgs {
    #[command(flatten)]
    settings: DemoSettings,
    /// Write into a folder holding other files (never replacing one of them).
    #[arg(long)]
    force: bool,
}

fn path_arg(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

/// The `sage3d` command line (without `sage3d`) that runs the same step as `step`.
pub fn command_line(step: &Step) -> Vec<String> {
    let mut args: Vec<String> = Vec::new();
    let mut flag = |name: &str, value: String| args.extend([format!("--{name}"), value]);
    let words: Vec<String> = match step {
        Step::Synth { config, out, .. } => {
            flag("kind", config.kind.as_str().into());
            flag("rooms", config.rooms.to_string());
            flag("objects", config.objects.to_string());
            flag("seed", config.seed.to_string());
            flag("gaussians", config.gaussians.to_string());
            flag("out", path_arg(out));
            vec!["scene".into(), "synth".into()]
        }
        Step::NavMap { scene, .. } => vec!["nav".into(), "map".into(), path_arg(scene)],
        Step::Physics { scene, .. } => vec!["physics".into(), "build".into(), path_arg(scene)],
        Step::Dataset {
            scenes,
            out,
            settings,
        } => {
            flag("out", path_arg(out));
            flag("per-scene", settings.per_scene.to_string());
            flag("seed", settings.seed.to_string());
            if let Some(mix) = &settings.length_mix {
                let shares: Vec<String> = mix.iter().map(f32::to_string).collect();
                flag("length-mix", shares.join(","));
            }
            vec!["data".into(), "build".into(), path_arg(scenes)]
        }
        Step::TrainData { options, out } => {
            if let Some(scenes) = &options.scenes {
                flag("scenes", path_arg(scenes));
            }
            flag("limit", options.limit.unwrap_or(0).to_string());
            flag("preview", options.preview.to_string());
            flag("out", path_arg(out));
            vec!["data".into(), "render".into(), path_arg(&options.dataset)]
        }
        Step::Eval { settings, out } => {
            flag("scenes", path_arg(&settings.scenes));
            flag("agent", settings.agent.to_string());
            flag("split", settings.split.clone());
            flag("seed", settings.seed.to_string());
            flag("out", path_arg(out));
            vec!["eval".into(), path_arg(&settings.dataset)]
        }
    };
    words.into_iter().chain(args).collect()
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
        (Step::TrainData { out, .. }, StepReport::TrainData(Some(r))) => {
            crate::data_cmd::print_render(r, out, secs);
        }
        (_, StepReport::TrainData(None)) => println!("the train split is empty: nothing to render"),
        (_, StepReport::Dataset(_) | StepReport::Eval(_) | StepReport::TrainData(_)) => {}
    }
}

/// Runs the demo and prints where everything is.
pub fn run(a: DemoArgs) -> Result<()> {
    let (force, s) = (a.force, a.settings);
    let _lock = sage_pipeline::demo::claim(&s, force)?;
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
                command_line(step).join(" ")
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
    use crate::data_cmd::DataCommand;
    use crate::{Cli, Command};
    use clap::Parser;

    #[derive(Parser)]
    struct Wrapper {
        #[command(flatten)]
        demo: DemoArgs,
    }

    /// Every step prints as a command line that parses, and the commands that take the same
    /// settings structs parse into the step's own settings.
    #[test]
    fn every_planned_step_is_the_command_line_of_the_same_settings() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("demo");
        let a = Wrapper::parse_from(["demo", "--out", out.to_str().unwrap(), "--scenes", "3"]).demo;
        let steps = demo::plan(&a.settings).unwrap();
        assert_eq!(steps.len(), 3 * 3 + 2 + 3);
        for s in &steps {
            let argv = std::iter::once("sage3d".to_string()).chain(command_line(s));
            let cli =
                Cli::try_parse_from(argv).unwrap_or_else(|e| panic!("{:?}: {e}", command_line(s)));
            match (s, cli.command) {
                (Step::Dataset { settings, .. }, Command::Data(DataCommand::Build(b))) => {
                    assert_eq!(**settings, b.settings);
                }
                (Step::TrainData { options, .. }, Command::Data(DataCommand::Render(r))) => {
                    assert_eq!(**options, r.options);
                }
                _ => {}
            }
        }
    }

    #[test]
    fn the_flags_default_to_the_demo_settings_defaults() {
        let a = Wrapper::parse_from(["demo"]).demo;
        assert_eq!(a.settings, DemoSettings::default());
    }
}
