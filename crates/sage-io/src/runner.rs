//! The resumable per-scene runner: a pipeline step over many scenes writes each scene's output
//! last and atomically, so a complete output marks the scene as done; a rerun resumes it, and a
//! scene that fails is skipped with its reason while the run goes on.

use sage_core::Result;
use serde::{Deserialize, Serialize};
use std::fmt;

/// What became of one scene of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Made by this run.
    Done,
    /// Already complete with the same settings: left as it was.
    Resumed,
    /// Failed (the outcome says why); the run went on.
    Skipped,
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Status::Done => "done",
            Status::Resumed => "resumed",
            Status::Skipped => "skipped",
        })
    }
}

/// The outcome of one scene: its status, how many items its output holds (trajectories,
/// episodes, …) and, when skipped, why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Outcome {
    /// What became of it.
    pub status: Status,
    /// Items in its output (0 when skipped).
    pub count: usize,
    /// Why it was skipped.
    pub reason: Option<String>,
}

/// Runs one scene resumably: `complete` returns the item count of an output that is already
/// complete with the same settings (the scene is then `Resumed`); otherwise `make` writes the
/// output and returns its item count (`Done`), and an error skips the scene with the error as
/// its reason.
pub fn resume_or_run(
    complete: impl FnOnce() -> Option<usize>,
    make: impl FnOnce() -> Result<usize>,
) -> Outcome {
    if let Some(count) = complete() {
        return Outcome {
            status: Status::Resumed,
            count,
            reason: None,
        };
    }
    match make() {
        Ok(count) => Outcome {
            status: Status::Done,
            count,
            reason: None,
        },
        Err(e) => Outcome {
            status: Status::Skipped,
            count: 0,
            reason: Some(e.to_string()),
        },
    }
}

/// How many scenes of a run ended in each status.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Tally {
    /// Made by this run.
    pub done: usize,
    /// Already complete.
    pub resumed: usize,
    /// Failed.
    pub skipped: usize,
}

impl Tally {
    /// Counts `statuses`.
    pub fn of(statuses: impl IntoIterator<Item = Status>) -> Tally {
        statuses.into_iter().fold(Tally::default(), |mut t, s| {
            match s {
                Status::Done => t.done += 1,
                Status::Resumed => t.resumed += 1,
                Status::Skipped => t.skipped += 1,
            }
            t
        })
    }
}

impl fmt::Display for Tally {
    /// `N done, N already complete, N skipped`, as the run summaries print it.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} done, {} already complete, {} skipped",
            self.done, self.resumed, self.skipped
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sage_core::Error;

    #[test]
    fn complete_output_resumes_a_failure_skips_with_its_reason_and_statuses_serialise_lowercase() {
        let resumed = resume_or_run(|| Some(4), || panic!("must not run"));
        assert_eq!((resumed.status, resumed.count), (Status::Resumed, 4));
        let done = resume_or_run(|| None, || Ok(7));
        assert_eq!(
            (done.status, done.count, done.reason),
            (Status::Done, 7, None)
        );
        let skipped = resume_or_run(|| None, || Err(Error::invalid("no floor")));
        assert_eq!(skipped.status, Status::Skipped);
        assert!(skipped.reason.unwrap().contains("no floor"));
        assert_eq!(
            serde_json::to_string(&Status::Resumed).unwrap(),
            "\"resumed\""
        );
        let t = Tally::of([Status::Done, Status::Skipped, Status::Done]);
        assert_eq!(t.to_string(), "2 done, 0 already complete, 1 skipped");
    }
}
