//! One WebSocket connection to a GN0 / openpi policy server (`ws://` only, no TLS): binary
//! frames carrying one msgpack-numpy message each ([`super::msgpack_numpy`]), strict
//! request/reply. On connect the server may send its metadata first (openpi's server always
//! does, GN0's client waits up to 2 s for it); pings are answered while waiting.
//!
//! Every way an exchange can fail comes back as a [`ReplyFault`] with its kind: no connection,
//! a timeout, a close frame or a dropped connection, and a message that is not msgpack are
//! [`FaultKind::Transport`]; a text frame (openpi's server sends the traceback as text, then
//! closes with 1011) is [`FaultKind::ServerError`]. A connection that faulted is not reused.

use super::msgpack_numpy::{self, Item};
use super::parse::ReplyFault;
use sage_env::agents::FaultKind;
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};
use tungstenite::protocol::WebSocketConfig;
use tungstenite::{Message, WebSocket};

/// Largest message accepted from the server, bytes (as the WNM-3D server's own limit).
const MAX_REPLY: usize = 64 << 20;

/// An open connection and what the server said on connect.
pub struct WsConnection {
    socket: WebSocket<TcpStream>,
    url: String,
    /// The server's metadata message, when it sent one.
    pub metadata: Option<Item>,
}

impl WsConnection {
    /// Connects to `ws://host:port/` within `timeout`, then waits up to `metadata_wait` for
    /// the server's metadata message.
    ///
    /// # Errors
    ///
    /// A transport fault (resolve, connect, handshake, timeout), or a server error when the
    /// first message is a text frame.
    pub fn open(
        host: &str,
        port: u16,
        timeout: Duration,
        metadata_wait: Duration,
    ) -> Result<WsConnection, ReplyFault> {
        let transport = |m: String| (FaultKind::Transport, m);
        let host = host.trim_start_matches('[').trim_end_matches(']');
        let url = if host.contains(':') {
            format!("ws://[{host}]:{port}/")
        } else {
            format!("ws://{host}:{port}/")
        };
        let addr = (host, port)
            .to_socket_addrs()
            .map_err(|e| transport(format!("resolving {host}: {e}")))?
            .next()
            .ok_or_else(|| transport(format!("{host} resolves to no address")))?;
        let stream = TcpStream::connect_timeout(&addr, timeout)
            .map_err(|e| transport(format!("connect {url}: {e}")))?;
        let _ = stream.set_nodelay(true);
        stream
            .set_read_timeout(Some(timeout))
            .and_then(|()| stream.set_write_timeout(Some(timeout)))
            .map_err(|e| transport(format!("socket: {e}")))?;
        // Both limits are on what the server sends, checked against a frame's declared length
        // before its payload is read: a header declaring 2⁶² bytes is refused, not allocated.
        let config = WebSocketConfig::default()
            .max_message_size(Some(MAX_REPLY))
            .max_frame_size(Some(MAX_REPLY));
        let (socket, _) = tungstenite::client::client_with_config(&url, stream, Some(config))
            .map_err(|e| transport(format!("WebSocket handshake with {url}: {e}")))?;
        let mut conn = WsConnection {
            socket,
            url,
            metadata: None,
        };
        if !metadata_wait.is_zero() {
            conn.metadata = conn.receive(metadata_wait)?;
        }
        Ok(conn)
    }

    /// Sends `request` and returns the server's reply, all within `timeout`.
    ///
    /// # Errors
    ///
    /// A transport fault or a server error (see the module doc).
    pub fn exchange(&mut self, request: &[u8], timeout: Duration) -> Result<Item, ReplyFault> {
        let deadline = Instant::now() + timeout;
        self.socket
            .get_mut()
            .set_write_timeout(Some(timeout))
            .map_err(|e| (FaultKind::Transport, format!("socket: {e}")))?;
        self.socket
            .send(Message::binary(request.to_vec()))
            .map_err(|e| {
                let what = if timed_out(&e) {
                    format!("timed out after {:.1} s", timeout.as_secs_f64())
                } else {
                    e.to_string()
                };
                (
                    FaultKind::Transport,
                    format!("sending to {}: {what}", self.url),
                )
            })?;
        let left = deadline
            .checked_duration_since(Instant::now())
            .filter(|d| !d.is_zero())
            .unwrap_or(Duration::from_millis(1));
        self.receive(left)?.ok_or_else(|| {
            (
                FaultKind::Transport,
                format!(
                    "timed out after {:.1} s waiting for the reply of {}",
                    timeout.as_secs_f64(),
                    self.url
                ),
            )
        })
    }

    /// The next data message within `wait`, `None` when the wait ran out (pings are answered
    /// on the way).
    fn receive(&mut self, wait: Duration) -> Result<Option<Item>, ReplyFault> {
        let deadline = Instant::now() + wait;
        loop {
            let left = deadline
                .checked_duration_since(Instant::now())
                .filter(|d| !d.is_zero());
            let Some(left) = left else {
                return Ok(None);
            };
            // The write timeout too: a read answers pings, and a server that floods pings
            // and reads none of the pongs would otherwise hold each write for a whole timeout.
            self.socket
                .get_mut()
                .set_read_timeout(Some(left))
                .and_then(|()| self.socket.get_mut().set_write_timeout(Some(left)))
                .map_err(|e| (FaultKind::Transport, format!("socket: {e}")))?;
            match self.socket.read() {
                Ok(Message::Binary(bytes)) => {
                    return msgpack_numpy::decode(&bytes)
                        .map(Some)
                        .map_err(|e| (FaultKind::Transport, e));
                }
                Ok(Message::Text(text)) => {
                    let text = text.as_str().trim();
                    let last = text.lines().last().unwrap_or("");
                    return Err((
                        FaultKind::ServerError,
                        format!(
                            "the server sent a text frame (an error): {}",
                            if last.is_empty() { text } else { last }
                        ),
                    ));
                }
                Ok(Message::Close(frame)) => {
                    return Err((
                        FaultKind::Transport,
                        match frame {
                            Some(f) => format!(
                                "the server closed the connection ({} {})",
                                u16::from(f.code),
                                f.reason.as_str()
                            )
                            .trim_end()
                            .to_string(),
                            None => "the server closed the connection".into(),
                        },
                    ));
                }
                Ok(_) => {}
                Err(e) if timed_out(&e) => return Ok(None),
                Err(e) => {
                    return Err((
                        FaultKind::Transport,
                        format!("reading from {}: {e}", self.url),
                    ));
                }
            }
        }
    }
}

/// Whether `e` is a socket's timeout (which a read or write reports as "would block").
fn timed_out(e: &tungstenite::Error) -> bool {
    matches!(e, tungstenite::Error::Io(io) if matches!(
        io.kind(),
        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
    ))
}
