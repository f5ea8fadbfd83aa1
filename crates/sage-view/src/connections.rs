//! The viewer's connections: HTTP/1 over tokio with the limits a server needs against
//! programs that open connections and never finish a request (a slow or idle client holds a
//! file descriptor for as long as it is let).
//!
//! - at most [`MAX_CONNECTIONS`] open at once: the next waits in the listen queue, so the
//!   server never runs out of file descriptors;
//! - a request's head must arrive within [`HEAD_TIMEOUT`] of the connection waiting for it,
//!   which also closes a kept-alive connection idle that long;
//! - a request's body is read by the guard ([`crate::server`]) within its own time limit;
//! - on stop, open connections finish the request under way (at most [`SHUTDOWN_GRACE`]).

use axum::Router;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;
use tokio::sync::{Semaphore, watch};

/// The most connections open at once (a browser opens six per host).
pub const MAX_CONNECTIONS: usize = 256;

/// How long a connection may take to send a request's head, or stay idle between requests.
pub const HEAD_TIMEOUT: Duration = Duration::from_secs(30);

/// How long open connections are given to finish once the viewer stops.
pub const SHUTDOWN_GRACE: Duration = Duration::from_secs(5);

/// Serves `router` on `listener` until `stop` turns true (or its sender is gone).
pub async fn serve(listener: TcpListener, router: Router, mut stop: watch::Receiver<bool>) {
    let open = Arc::new(Semaphore::new(MAX_CONNECTIONS));
    loop {
        let permit = tokio::select! {
            permit = open.clone().acquire_owned() => match permit {
                Ok(p) => p,
                Err(_) => break,
            },
            _ = stopped(&mut stop) => break,
        };
        let stream = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((stream, _)) => stream,
                // Out of descriptors or a connection reset before it was accepted: what
                // frees them is time, not a busy loop.
                Err(_) => {
                    tokio::time::sleep(Duration::from_millis(100)).await;
                    continue;
                }
            },
            _ = stopped(&mut stop) => break,
        };
        // Small JSON replies to key presses: sent at once, not held for more.
        let _ = stream.set_nodelay(true);
        let service = TowerToHyperService::new(router.clone());
        let mut stop = stop.clone();
        tokio::spawn(async move {
            let _permit = permit;
            let mut builder = http1::Builder::new();
            builder
                .timer(TokioTimer::new())
                .header_read_timeout(HEAD_TIMEOUT);
            let connection = builder.serve_connection(TokioIo::new(stream), service);
            let mut connection = std::pin::pin!(connection);
            tokio::select! {
                _ = connection.as_mut() => return,
                _ = stopped(&mut stop) => connection.as_mut().graceful_shutdown(),
            }
            let _ = tokio::time::timeout(SHUTDOWN_GRACE, connection).await;
        });
    }
    // Every connection gives its permit back when it ends.
    let _ = tokio::time::timeout(
        SHUTDOWN_GRACE + Duration::from_secs(1),
        open.acquire_many(MAX_CONNECTIONS as u32),
    )
    .await;
}

/// Resolves once `stop` is true or can no longer change.
async fn stopped(stop: &mut watch::Receiver<bool>) {
    let _ = stop.wait_for(|&s| s).await;
}
