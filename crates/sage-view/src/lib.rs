//! `sage-view`: the browser viewer of sage3d (`sage3d view PATH`, `sage3d.view(path)`).
//!
//! A local web server over one [`Subject`] — a scene, a folder of scenes, a dataset split or
//! an evaluation run — that serves a page of its own (plain HTML, CSS and JavaScript embedded
//! in the binary, [`assets`]) and a small JSON API ([`server`]):
//!
//! - the semantic top-down map of a scene as a PNG with the objects, rooms and doors as data
//!   for the page to draw and label ([`scenes`]);
//! - first-person frames rendered by sage3d's renderer at any agent pose, with the agent
//!   camera every observation uses (`EnvConfig::camera`), as RGB, depth, semantic or instance
//!   images ([`frame`]);
//! - sessions that step an agent through the environment's physics as `sage3d eval` does,
//!   for exploring a scene with the keyboard and for human play ([`session`]);
//! - the episodes of a run with their outcome and, per episode, every recorded step for the
//!   player's timeline ([`player`]).
//!
//! [`connections`] holds the limits on connections (how many, how slow) and [`videos`] the
//! episode animations made so far.
//!
//! [`client`] is a minimal HTTP client of these routes for the benchmark and the tests.
//!
//! Human play records the person as agent `human` in a run folder of the evaluator's format
//! ([`sage_eval::HumanRun`]), so the same code scores people and models.
//!
//! The server binds to 127.0.0.1 unless told otherwise; another address needs
//! [`ViewOptions::public`], and then every request must carry a random token given in the
//! printed URL. It answers only its own routes: no request names a file, so nothing outside
//! the folders it was given (and no file of theirs but through these routes) can be read.
//! It writes the human-play run folder and, as every command that loads a scene does, the
//! scene's cache of collision hulls (`SCENE/.sage3d/collision/`), nothing else.

pub mod assets;
pub mod client;
pub mod connections;
pub mod frame;
pub mod player;
pub mod scenes;
pub mod server;
pub mod session;
pub mod subject;
pub mod videos;

pub use server::{Server, serve};
pub use subject::{Subject, ViewOptions};
