//! `sage-http`: the one HTTP client of sage3d.
//!
//! The LLM instruction writer (`sage-lang`) and the evaluator's remote agents (`sage-agents`)
//! talk to OpenAI-compatible and model-server endpoints through this crate. [`client`] sends a
//! JSON body with a per-request timeout and hands back the reply (status, headers, body) as
//! plain data: an HTTP error status is a reply, only a request that got no complete reply is an
//! [`HttpError`]. [`retry`] runs attempts under a [`RetryPolicy`] (exponential backoff with a
//! cap, the server's `Retry-After` honoured up to the cap, transient failures or all of them
//! tried again), shows every failed attempt to a hook and sleeps through a function the caller
//! passes, so tests observe the waits instead of timing them.
//!
//! Plain HTTP always; HTTPS with the crate feature `tls` (rustls), which the crates using this
//! one forward.

pub mod client;
pub mod retry;

pub use client::{Client, ErrorKind, HttpError, Reply, Stage};
pub use retry::{Failure, GaveUp, RetryOn, RetryPolicy};
