//! `sage-metrics`: the SAGE-Bench and VLN-CE metrics (SPEC §10) as pure functions of a
//! per-episode record.
//!
//! An environment run fills an [`EpisodeRecord`] (positions, headings, contacts, c(t), the
//! geodesic distances only a path finder can give); [`evaluate`] turns it into
//! [`EpisodeMetrics`] under one [`Mode`]; [`aggregate`] averages episodes. Every formula and
//! every difference between the modes is written down in `docs/metrics.md`. Distances are taken
//! in the floor plane.
//!
//! - [`distance`]: path length, goal region, reference-path distance, success tests, SPL;
//! - [`dtw`]: exact DTW, nDTW, SDTW;
//! - [`collision`]: CR, ICP and the published collision window;
//! - [`smoothness`]: PS and the published variant;
//! - [`nogoal`]: Episode Time and Explored Area;
//! - [`gnbench`]: GN-Bench's success, SPL, forced STOP and means (mode `gnbench`).

pub mod collision;
pub mod distance;
pub mod dtw;
pub mod fastdtw;
pub mod gnbench;
pub mod nogoal;
pub mod smoothness;

use distance::{GoalRegion, OfficialGoal, OfficialTest};
use gnbench::GnBenchDistances;
use sage_core::{Error, Result, Task, Vec2};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

/// Which definitions produce the numbers (SPEC §10.1).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Mode {
    /// SPEC §10: goal regions, geodesic NE and L*, c(t) from physics.
    #[default]
    Sage,
    /// VLN-CE as coded: geodesic distance to the goal point, strict 3.0 m success.
    Vlnce,
    /// The published SAGE-3D code's behaviour, for comparison with numbers it produced.
    SageOfficial,
    /// GN-Bench's measures: its grid distance to goal on the occupancy image, success within
    /// 3.0 m at STOP, its forced STOP and its means.
    GnBench,
}

impl Mode {
    /// The mode's name as written in files and flags.
    pub fn as_str(self) -> &'static str {
        match self {
            Mode::Sage => "sage",
            Mode::Vlnce => "vlnce",
            Mode::SageOfficial => "sage-official",
            Mode::GnBench => "gnbench",
        }
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

sage_core::named_by_string!(Mode);

impl FromStr for Mode {
    type Err = Error;

    fn from_str(s: &str) -> Result<Mode> {
        match s.trim().to_ascii_lowercase().as_str() {
            "sage" => Ok(Mode::Sage),
            "vlnce" => Ok(Mode::Vlnce),
            "sage-official" => Ok(Mode::SageOfficial),
            "gnbench" => Ok(Mode::GnBench),
            _ => Err(Error::invalid(format!(
                "unknown metric mode '{s}' (expected sage, vlnce, sage-official or gnbench)"
            ))),
        }
    }
}

/// How nDTW aligns the two paths.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Dtw {
    /// Exact dynamic time warping.
    #[default]
    Exact,
    /// FastDTW with radius 1, as the `fastdtw` package computes it (VLN-CE's default): an
    /// approximation that can only cost more than the exact alignment.
    Fast,
}

impl Dtw {
    /// The name as written in files and flags.
    pub fn as_str(self) -> &'static str {
        match self {
            Dtw::Exact => "exact",
            Dtw::Fast => "fast",
        }
    }
}

impl fmt::Display for Dtw {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

sage_core::named_by_string!(Dtw);

impl FromStr for Dtw {
    type Err = Error;

    fn from_str(s: &str) -> Result<Dtw> {
        match s.trim().to_ascii_lowercase().as_str() {
            "exact" => Ok(Dtw::Exact),
            "fast" => Ok(Dtw::Fast),
            _ => Err(Error::invalid(format!(
                "unknown DTW '{s}' (expected exact or fast)"
            ))),
        }
    }
}

/// Everything that decides how a record is scored: the mode and the DTW used by nDTW.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Scoring {
    /// The metric definitions.
    pub mode: Mode,
    /// The alignment nDTW and SDTW use.
    #[serde(default)]
    pub dtw: Dtw,
}

impl From<Mode> for Scoring {
    fn from(mode: Mode) -> Scoring {
        Scoring {
            mode,
            dtw: Dtw::Exact,
        }
    }
}

/// What one step did (STOP is a step).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepRecord {
    /// Agent position after the step `[x, y, z]`, W frame.
    pub position: [f32; 3],
    /// Heading after the step, radians.
    pub yaw: f32,
    /// Simulated seconds since reset, after the step.
    pub time: f32,
    /// Commanded translation length, metres.
    pub commanded: f32,
    /// Achieved translation along the command, metres.
    pub achieved: f32,
    /// The agent touches something after the step.
    pub contact: bool,
    /// Collision intensity c(t) ∈ [0, 1] (SPEC §6).
    pub intensity: f32,
    /// Geodesic distance to the goal point after the step (mode `vlnce`); `None` when
    /// unreachable or not computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geodesic_to_goal_point: Option<f32>,
}

/// Geodesic distances that need the scene's path finder.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Geodesics {
    /// L*: start to goal region (SPEC §10), metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_to_region: Option<f32>,
    /// Final position to goal region (NE), metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub final_to_region: Option<f32>,
    /// d0: start to goal point (mode `vlnce`), metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_to_point: Option<f32>,
}

/// Everything the metrics of one episode need: the record an evaluator stores per episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeRecord {
    /// Episode id.
    pub episode_id: String,
    /// `vln` or `nogoal`.
    pub task: Task,
    /// Start position `[x, y, z]`.
    pub start: [f32; 3],
    /// Start heading, radians.
    pub start_yaw: f32,
    /// The steps, in order.
    pub steps: Vec<StepRecord>,
    /// The agent called STOP (its last step).
    pub stop_called: bool,
    /// The reference path `[x, y, z]`, W frame (dense, as the episode stores it).
    pub reference_path: Vec<[f32; 3]>,
    /// The goal region (VLN episodes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal: Option<GoalRegion>,
    /// Geodesic distances from the path finder.
    #[serde(default)]
    pub geodesics: Geodesics,
    /// The published code's goal test (mode `sage-official`).
    pub official_goal: OfficialGoal,
    /// GN-Bench's distances to goal (mode `gnbench`; filled in when a run is scored in that
    /// mode, since they cost an A* per position).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gnbench: Option<GnBenchDistances>,
}

/// The metrics of one episode; `None` where the metric is not defined for the task or mode.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct EpisodeMetrics {
    /// Navigation error, metres.
    pub ne: Option<f64>,
    /// Success.
    pub sr: Option<f64>,
    /// Oracle success.
    pub osr: Option<f64>,
    /// Success weighted by path length.
    pub spl: Option<f64>,
    /// Trajectory length, metres.
    pub tl: Option<f64>,
    /// Collision count.
    pub cr: Option<f64>,
    /// Continuous success ratio.
    pub csr: Option<f64>,
    /// Integrated collision penalty.
    pub icp: Option<f64>,
    /// Path smoothness.
    pub ps: Option<f64>,
    /// Normalised DTW.
    pub ndtw: Option<f64>,
    /// Success-weighted nDTW.
    pub sdtw: Option<f64>,
    /// NoGoal: simulated seconds survived.
    pub episode_time: Option<f64>,
    /// NoGoal: explored floor area, m².
    pub explored_area: Option<f64>,
    /// NoGoal: explored 0.5 m cells.
    pub explored_cells: Option<f64>,
    /// NoGoal, mode `sage-official`: cells / 400, capped at 1.
    pub coverage: Option<f64>,
    /// Steps taken (STOP included).
    pub steps: Option<f64>,
}

/// The metrics that are shares of an episode or of its steps, each within 0–1; every other is
/// a distance, a count, a time or an area, at least 0.
const SHARES: [&str; 9] = [
    "sr", "osr", "spl", "csr", "icp", "ps", "ndtw", "sdtw", "coverage",
];

impl EpisodeMetrics {
    /// Checks metrics read from a file against what [`evaluate`] can give: the shares
    /// (SR, OSR, SPL, CSR, ICP, PS, nDTW, SDTW, coverage) within 0–1, every other metric
    /// finite and at least 0.
    ///
    /// # Errors
    ///
    /// The first metric out of its range, named.
    pub fn check(&self) -> Result<()> {
        for (name, v) in self.named() {
            let Some(v) = v else { continue };
            let (ok, range) = if SHARES.contains(&name) {
                ((0.0..=1.0).contains(&v), "within 0-1")
            } else {
                (v >= 0.0 && v.is_finite(), "finite and at least 0")
            };
            if !ok {
                return Err(Error::format(
                    name,
                    format!("{v}: no episode scores this (expected {range})"),
                ));
            }
        }
        Ok(())
    }

    /// The metrics by name, in a fixed order (names as in the paper's tables, lower case).
    pub fn named(&self) -> [(&'static str, Option<f64>); 16] {
        [
            ("ne", self.ne),
            ("sr", self.sr),
            ("osr", self.osr),
            ("spl", self.spl),
            ("tl", self.tl),
            ("cr", self.cr),
            ("csr", self.csr),
            ("icp", self.icp),
            ("ps", self.ps),
            ("ndtw", self.ndtw),
            ("sdtw", self.sdtw),
            ("episode_time", self.episode_time),
            ("explored_area", self.explored_area),
            ("explored_cells", self.explored_cells),
            ("coverage", self.coverage),
            ("steps", self.steps),
        ]
    }
}

fn xy(p: &[f32; 3]) -> [f64; 2] {
    [f64::from(p[0]), f64::from(p[1])]
}

fn flag(b: bool) -> f64 {
    if b { 1.0 } else { 0.0 }
}

/// The metrics of one episode under `scoring` (a [`Mode`] alone scores with exact DTW).
///
/// # Errors
///
/// An `invalid` error naming the episode when a VLN record has no goal region, or when it says
/// STOP was called but holds no step (STOP is a step).
pub fn evaluate(rec: &EpisodeRecord, scoring: impl Into<Scoring>) -> Result<EpisodeMetrics> {
    let Scoring { mode, dtw } = scoring.into();
    if rec.stop_called && rec.steps.is_empty() {
        return Err(Error::invalid(format!(
            "episode {}: stop_called is set but there is no step (STOP is a step)",
            rec.episode_id
        )));
    }
    let cut;
    let rec = if let Some(steps) = official_auto_stop(rec, mode) {
        cut = EpisodeRecord {
            steps: rec.steps[..steps].to_vec(),
            ..rec.clone()
        };
        &cut
    } else if let Some(steps) = gnbench_forced_stop(rec, mode)? {
        cut = gnbench_cut(rec, steps);
        &cut
    } else {
        rec
    };
    let start = xy(&rec.start);
    let trace: Vec<[f64; 2]> = std::iter::once(start)
        .chain(rec.steps.iter().map(|s| xy(&s.position)))
        .collect();
    let moves: Vec<(f64, f64)> = rec
        .steps
        .iter()
        .map(|s| (f64::from(s.commanded), f64::from(s.achieved)))
        .collect();
    let headings: Vec<f64> = rec.steps.iter().map(|s| f64::from(s.yaw)).collect();
    let tl = distance::path_length(&trace);
    // The published code samples once at reset, then before and after every step.
    let official_samples: Vec<[f64; 2]> = std::iter::once(start)
        .chain(trace.windows(2).flat_map(|w| [w[0], w[1]]))
        .collect();
    let mut m = EpisodeMetrics {
        tl: Some(tl),
        steps: Some(rec.steps.len() as f64),
        ..EpisodeMetrics::default()
    };
    match mode {
        Mode::Sage => {
            let contact: Vec<bool> = rec.steps.iter().map(|s| s.contact).collect();
            m.cr = Some(collision::collision_events(&contact) as f64);
            m.icp = Some(collision::mean(
                rec.steps.iter().map(|s| f64::from(s.intensity)),
            ));
            m.ps = Some(smoothness::path_smoothness(&headings));
        }
        Mode::Vlnce => {
            let positions = positions3(rec);
            let blocked =
                rec.steps.iter().zip(positions.windows(2)).filter(|(s, w)| {
                    collision::habitat_collided(f64::from(s.commanded), &w[0], &w[1])
                });
            m.cr = Some(blocked.count() as f64);
            m.icp = Some(collision::mean(
                rec.steps.iter().map(|s| f64::from(s.intensity)),
            ));
            m.ps = Some(smoothness::path_smoothness(&headings));
        }
        Mode::SageOfficial => {
            m.icp = Some(collision::official_icp(&moves));
            m.ps = Some(smoothness::official_path_smoothness(&official_samples));
        }
        // GN-Bench measures no collisions and no smoothness.
        Mode::GnBench => {}
    }
    match rec.task {
        Task::Vln => vln_metrics(rec, mode, dtw, &trace, &official_samples, &mut m)?,
        Task::Nogoal => {
            m.episode_time = Some(rec.steps.last().map_or(0.0, |s| f64::from(s.time)));
            let cells = match mode {
                Mode::SageOfficial => nogoal::visited_cells(&official_samples, true),
                _ => nogoal::visited_cells(&trace, false),
            };
            m.explored_cells = Some(cells as f64);
            m.explored_area = Some(nogoal::explored_area(cells));
            if mode == Mode::SageOfficial {
                m.coverage = Some((cells as f64 / nogoal::OFFICIAL_COVERAGE_CELLS).min(1.0));
            }
        }
    }
    Ok(m)
}

/// The published goal point g of a VLN record: the reference path's last point (its
/// `gt_locations[-1]`), else the goal point.
fn official_goal_point(rec: &EpisodeRecord) -> Option<[f64; 2]> {
    rec.reference_path
        .last()
        .map(xy)
        .or(rec.goal.as_ref().map(|g| g.point))
}

/// In mode `sage-official`, the number of steps the published loop would have run: it ends a
/// VLN episode after the first step that leaves the agent closer than 0.5 m to g (its
/// auto-stop). `None` when the record needs no cut: no step comes that close before its last,
/// or another mode or task.
pub fn official_auto_stop(rec: &EpisodeRecord, mode: Mode) -> Option<usize> {
    if mode != Mode::SageOfficial || rec.task != Task::Vln {
        return None;
    }
    let g = official_goal_point(rec)?;
    rec.steps
        .iter()
        .position(|s| dtw::euclidean(&xy(&s.position), &g) < distance::OFFICIAL_GOAL_RADIUS)
        .map(|k| k + 1)
        .filter(|&n| n < rec.steps.len())
}

/// The GN-Bench distances of a VLN record, one per position (the start first), checked
/// against its steps.
fn gnbench_distances(rec: &EpisodeRecord) -> Result<Vec<Option<f64>>> {
    let d = rec.gnbench.as_ref().ok_or_else(|| {
        Error::invalid(format!(
            "episode {}: the record holds no GN-Bench distances (mode gnbench needs them: \
             they are computed on the scene's occupancy image when an episode is scored in \
             that mode)",
            rec.episode_id
        ))
    })?;
    if d.steps.len() != rec.steps.len() {
        return Err(Error::invalid(format!(
            "episode {}: gnbench.steps holds {} distances for {} steps",
            rec.episode_id,
            d.steps.len(),
            rec.steps.len()
        )));
    }
    Ok(std::iter::once(d.start)
        .chain(d.steps.iter().copied())
        .collect())
}

/// GN-Bench's distances of a VLN record as its measure reports them: recomputed only after a
/// move beyond `np.allclose(…, atol=1e-4)`, else the last value repeats.
fn gnbench_readings(rec: &EpisodeRecord) -> Result<Vec<Option<f64>>> {
    Ok(distance::habitat_cached_distances(
        &positions3(rec),
        &gnbench_distances(rec)?,
    ))
}

/// In mode `gnbench`, the number of steps the agent chose before GN-Bench's runner would have
/// forced STOP ([`gnbench::forced_stop`]: its distance to goal unchanged for more than 25
/// iterations in a row). `None` when the record needs no cut: no forced STOP before its end, or
/// the agent's own STOP came at that very step; or another mode or task.
///
/// # Errors
///
/// A VLN record without GN-Bench distances, or with one per step missing.
pub fn gnbench_forced_stop(rec: &EpisodeRecord, mode: Mode) -> Result<Option<usize>> {
    if mode != Mode::GnBench || rec.task != Task::Vln {
        return Ok(None);
    }
    let readings = gnbench_readings(rec)?;
    // Reading k is taken before step k + 1; the last one (after the last step) forces nothing.
    let t = rec.steps.len();
    Ok(gnbench::forced_stop(&readings[..t]).filter(|&k| !(rec.stop_called && k + 1 == t)))
}

/// `rec` as GN-Bench's runner would have ended it: its first `steps` steps, then a STOP where
/// the agent stood (the distance read there repeats).
fn gnbench_cut(rec: &EpisodeRecord, steps: usize) -> EpisodeRecord {
    let mut kept = rec.steps[..steps].to_vec();
    let stop = match kept.last() {
        Some(s) => StepRecord {
            commanded: 0.0,
            achieved: 0.0,
            contact: false,
            intensity: 0.0,
            ..s.clone()
        },
        None => StepRecord {
            position: rec.start,
            yaw: rec.start_yaw,
            time: 0.0,
            commanded: 0.0,
            achieved: 0.0,
            contact: false,
            intensity: 0.0,
            geodesic_to_goal_point: rec.geodesics.start_to_point,
        },
    };
    kept.push(stop);
    let gnbench = rec.gnbench.as_ref().map(|d| {
        let mut steps_d = d.steps[..steps].to_vec();
        steps_d.push(steps_d.last().copied().unwrap_or(d.start));
        GnBenchDistances {
            start: d.start,
            steps: steps_d,
        }
    });
    EpisodeRecord {
        steps: kept,
        stop_called: true,
        gnbench,
        ..rec.clone()
    }
}

/// The start and every step's position in 3-D, f64.
fn positions3(rec: &EpisodeRecord) -> Vec<[f64; 3]> {
    std::iter::once(&rec.start)
        .chain(rec.steps.iter().map(|s| &s.position))
        .map(|p| p.map(f64::from))
        .collect()
}

fn vln_metrics(
    rec: &EpisodeRecord,
    mode: Mode,
    dtw_kind: Dtw,
    trace: &[[f64; 2]],
    samples: &[[f64; 2]],
    m: &mut EpisodeMetrics,
) -> Result<()> {
    let goal = rec.goal.as_ref().ok_or_else(|| {
        Error::invalid(format!(
            "episode {}: a vln record needs a goal",
            rec.episode_id
        ))
    })?;
    let last = *trace.last().unwrap_or(&trace[0]);
    let tl = m.tl.unwrap_or(0.0);
    let reference: Vec<[f64; 2]> = rec.reference_path.iter().map(xy).collect();
    let agent = dtw::dedup_trace(trace);
    let inf = |v: Option<f64>| v.unwrap_or(f64::INFINITY);
    let opt = |v: Option<f32>| v.map_or(f64::INFINITY, f64::from);
    let align = |r: &[[f64; 2]]| match dtw_kind {
        Dtw::Exact => dtw::dtw(r, &agent, dtw::euclidean),
        Dtw::Fast => fastdtw::fastdtw(&agent, r, fastdtw::FASTDTW_RADIUS),
    };
    let (success, ndtw) = match mode {
        Mode::Sage => {
            let r = distance::SAGE_SUCCESS_DISTANCE;
            let yaws: Vec<f64> = std::iter::once(rec.start_yaw)
                .chain(rec.steps.iter().map(|s| s.yaw))
                .map(f64::from)
                .collect();
            let last_yaw = *yaws.last().unwrap_or(&yaws[0]);
            let success = rec.stop_called && goal.reached(&last, last_yaw, r);
            m.ne = Some(opt(rec.geodesics.final_to_region));
            m.osr = Some(flag(
                trace[1..]
                    .iter()
                    .zip(&yaws[1..])
                    .any(|(p, &yaw)| goal.reached(p, yaw, r)),
            ));
            m.spl = Some(
                distance::spl(success, opt(rec.geodesics.start_to_region), tl)
                    .unwrap_or(flag(success)),
            );
            m.csr = Some(collision::mean(rec.steps.iter().zip(&trace[1..]).map(
                |(s, p)| {
                    flag(
                        s.intensity == 0.0
                            && distance::point_polyline(p, &reference) <= distance::CSR_TOLERANCE,
                    )
                },
            )));
            let pts: Vec<Vec2> = reference
                .iter()
                .map(|p| Vec2::new(p[0] as f32, p[1] as f32))
                .collect();
            let resampled: Vec<[f64; 2]> = sage_core::geometry::resample_polyline(&pts, 0.25)
                .iter()
                .map(|p| [f64::from(p.x), f64::from(p.y)])
                .collect();
            let d = align(&resampled);
            (
                success,
                dtw::ndtw_from(d, resampled.len(), dtw::DTW_THRESHOLD),
            )
        }
        Mode::Vlnce => {
            let r = distance::VLNCE_SUCCESS_DISTANCE;
            let raw: Vec<Option<f64>> = std::iter::once(rec.geodesics.start_to_point)
                .chain(rec.steps.iter().map(|s| s.geodesic_to_goal_point))
                .map(|d| d.map(f64::from))
                .collect();
            let dist = distance::habitat_cached_distances(&positions3(rec), &raw);
            let d_final = inf(dist.last().copied().flatten());
            let success = rec.stop_called && d_final < r;
            m.ne = Some(d_final);
            m.osr = Some(flag(dist.iter().any(|d| inf(*d) < r)));
            m.spl = distance::spl(success, inf(dist[0]), tl);
            let d = align(&reference);
            (
                success,
                dtw::ndtw_from(d, reference.len(), dtw::DTW_THRESHOLD),
            )
        }
        Mode::SageOfficial => {
            let g = official_goal_point(rec).unwrap_or(goal.point);
            let og = &rec.official_goal;
            let success = og.passes(OfficialTest::Success, &last, &g);
            m.ne = Some(dtw::euclidean(&last, &g));
            m.osr = Some(flag(
                samples
                    .iter()
                    .any(|p| og.passes(OfficialTest::Oracle, p, &g)),
            ));
            m.spl = Some(distance::official_spl(
                success,
                dtw::euclidean(&trace[0], &g),
                tl,
            ));
            m.csr = Some(collision::mean(
                samples
                    .iter()
                    .map(|p| flag(og.passes(OfficialTest::Continuous, p, &g))),
            ));
            m.sr = Some(flag(success));
            return Ok(());
        }
        Mode::GnBench => {
            let d: Vec<f64> = gnbench_readings(rec)?
                .into_iter()
                .map(gnbench::value)
                .collect();
            let d_final = *d.last().unwrap_or(&d[0]);
            let success = gnbench::success(rec.stop_called, d_final);
            m.ne = Some(d_final);
            m.sr = Some(flag(success));
            m.osr = Some(flag(d.iter().any(|&v| v < gnbench::SUCCESS_DISTANCE)));
            m.spl = Some(gnbench::spl(success, d[0], tl));
            return Ok(());
        }
    };
    m.sr = Some(flag(success));
    m.ndtw = Some(ndtw);
    m.sdtw = Some(flag(success) * ndtw);
    Ok(())
}

/// Means of each metric over episodes (over those that define it), with the episode count.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Aggregate {
    /// Episodes aggregated.
    pub episodes: usize,
    /// The mode that produced the numbers.
    pub mode: Mode,
    /// Metric name → mean.
    pub means: BTreeMap<String, f64>,
}

/// The metrics mode `gnbench` averages as GN-Bench's results script does: over every scored
/// VLN episode, a missing or non-finite value (an unreachable goal's ∞ NE, its NaN SPL)
/// counting as 0.
const GNBENCH_ZERO_FILLED: [&str; 4] = ["ne", "sr", "osr", "spl"];

/// The mean of each metric over `episodes`: in modes `sage`, `vlnce` and `sage-official` over
/// the episodes that define it; in mode `gnbench` NE, SR, OSR and SPL over every VLN episode,
/// with missing or non-finite values as 0 (GN-Bench's means).
pub fn aggregate<'a>(
    mode: Mode,
    episodes: impl IntoIterator<Item = &'a EpisodeMetrics>,
) -> Aggregate {
    let mut sums: BTreeMap<&'static str, (f64, usize)> = BTreeMap::new();
    let mut n = 0;
    for e in episodes {
        n += 1;
        for (name, v) in e.named() {
            let zero_filled =
                mode == Mode::GnBench && e.sr.is_some() && GNBENCH_ZERO_FILLED.contains(&name);
            let v = match v {
                Some(v) if zero_filled && !v.is_finite() => Some(0.0),
                None if zero_filled => Some(0.0),
                v => v,
            };
            if let Some(v) = v {
                let s = sums.entry(name).or_default();
                s.0 += v;
                s.1 += 1;
            }
        }
    }
    Aggregate {
        episodes: n,
        mode,
        means: sums
            .into_iter()
            .map(|(k, (s, c))| (k.to_string(), s / c as f64))
            .collect(),
    }
}

#[cfg(test)]
mod tests;
