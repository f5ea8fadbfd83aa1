//! `sage3d view PATH`: the browser viewer (`docs/viewer.md`) — a local web server over a scene,
//! a folder of scenes, a dataset split or an evaluation run, with human play (`--play RUN`).

use sage_core::Result;
use sage_metrics::Mode;
use sage_view::ViewOptions;
use std::net::IpAddr;
use std::path::PathBuf;

/// Flags of `sage3d view`.
#[derive(clap::Args)]
pub struct ViewArgs {
    /// A scene folder, a folder of scenes, a dataset folder or an evaluation run folder.
    path: PathBuf,
    /// The scenes of a dataset or run (default: the folder its run record names).
    #[arg(long)]
    scenes: Option<PathBuf>,
    /// The dataset split to show or play (default: the first split with episodes).
    #[arg(long)]
    split: Option<String>,
    /// Human play: record the episodes you play into this run folder (the evaluator's format,
    /// agent `human`; new, empty, or a human run of the same split, which resumes).
    #[arg(long, value_name = "RUN")]
    play: Option<PathBuf>,
    /// Write the human run into a folder holding other files (never replacing one of them).
    #[arg(long)]
    force: bool,
    /// Environment preset the agent moves with: sage, vlnce, gnbench, sage-harness,
    /// navila_small, navila_large or custom_small (a run uses its own).
    #[arg(long, default_value = "sage")]
    preset: String,
    /// Metric mode human play is scored in: sage, vlnce, sage-official or gnbench.
    #[arg(long, default_value_t = Mode::default())]
    mode: Mode,
    /// Address to listen on (an IP address, or `localhost`); anything but a loopback address
    /// needs --public.
    #[arg(long, default_value = "127.0.0.1", value_parser = parse_host)]
    host: IpAddr,
    /// Port to listen on (0: any free port).
    #[arg(long, default_value_t = 8765)]
    port: u16,
    /// Serve to other machines: allows a non-loopback --host, and every request then needs the
    /// random token of the printed URL.
    #[arg(long)]
    public: bool,
    #[command(flatten)]
    device: crate::flags::DeviceFlag,
}

/// Serves until interrupted, after printing the URL.
pub fn run(a: ViewArgs) -> Result<()> {
    eprintln!("renderer: {}", a.device.probe()?);
    let opts = ViewOptions {
        path: a.path,
        scenes: a.scenes,
        split: a.split,
        play: a.play,
        force: a.force,
        preset: a.preset,
        mode: a.mode,
        device: a.device.device,
        host: a.host,
        port: a.port,
        public: a.public,
    };
    sage_view::serve(
        &opts,
        |server| {
            println!("{}", server.announcement());
            eprintln!("(Ctrl-C stops the server; every finished episode is already recorded)");
        },
        || true,
    )
}

/// `--host`: an IP address, or `localhost` (the loopback address a browser would use); other
/// names are refused, since a name resolving elsewhere would widen what the viewer serves.
fn parse_host(text: &str) -> Result<IpAddr, String> {
    if text.eq_ignore_ascii_case("localhost") {
        return Ok(IpAddr::from([127, 0, 0, 1]));
    }
    text.parse()
        .map_err(|e| format!("{e}: give an IP address (127.0.0.1, 0.0.0.0, ::1) or localhost"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn host_takes_addresses_and_localhost_only() {
        assert_eq!(parse_host("localhost"), Ok(IpAddr::from([127, 0, 0, 1])));
        assert_eq!(parse_host("0.0.0.0"), Ok(IpAddr::from([0, 0, 0, 0])));
        assert!(parse_host("::1").is_ok_and(|h| h.is_loopback()));
        let e = parse_host("example.org").unwrap_err();
        assert!(e.contains("localhost"), "{e}");
    }
}
