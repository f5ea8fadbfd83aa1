//! The SAGE-3D socket protocol: a new TCP connection per step; the request is an 8-byte
//! big-endian length followed by that many bytes of UTF-8 JSON
//! `{"images": [base64 JPEG, …], "query": instruction}`, and the reply comes back in the
//! same framing around any JSON value. The whole exchange must finish within the timeout.

use super::Transport;
use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

/// Largest reply accepted, bytes: a length beyond it is taken for bad framing.
const MAX_REPLY: u64 = 64 << 20;

/// Writes one frame: the payload's length as u64 big-endian, then the payload.
///
/// # Errors
///
/// The stream's write error.
pub fn write_frame(w: &mut impl Write, payload: &[u8]) -> std::io::Result<()> {
    w.write_all(&(payload.len() as u64).to_be_bytes())?;
    w.write_all(payload)?;
    w.flush()
}

/// A socket-protocol client of one server.
#[derive(Debug, Clone)]
pub struct SocketClient {
    host: String,
    port: u16,
    timeout: Duration,
}

impl SocketClient {
    /// A client of `host:port`; each request may take `timeout` in all.
    pub fn new(host: &str, port: u16, timeout: Duration) -> SocketClient {
        SocketClient {
            host: host
                .trim_start_matches('[')
                .trim_end_matches(']')
                .to_string(),
            port,
            timeout,
        }
    }

    /// One request/reply exchange on a fresh connection; the reply's JSON.
    ///
    /// # Errors
    ///
    /// A fault message: connect refused, timeout, disconnect, bad framing or non-JSON reply.
    pub fn exchange(&self, request: &[u8]) -> Result<serde_json::Value, String> {
        let deadline = Instant::now() + self.timeout;
        let left = || {
            deadline
                .checked_duration_since(Instant::now())
                .filter(|d| !d.is_zero())
                .ok_or_else(|| format!("timed out after {:.1} s", self.timeout.as_secs_f64()))
        };
        let addr = (self.host.as_str(), self.port)
            .to_socket_addrs()
            .map_err(|e| format!("resolving {}: {e}", self.host))?
            .next()
            .ok_or_else(|| format!("{} resolves to no address", self.host))?;
        let mut stream =
            TcpStream::connect_timeout(&addr, left()?).map_err(|e| format!("connect: {e}"))?;
        let _ = stream.set_nodelay(true);
        stream
            .set_write_timeout(Some(left()?))
            .map_err(|e| format!("socket: {e}"))?;
        write_frame(&mut stream, request).map_err(|e| format!("sending: {e}"))?;
        let mut read_exact = |buf: &mut [u8], what: &str| -> Result<(), String> {
            let mut got = 0;
            while got < buf.len() {
                stream
                    .set_read_timeout(Some(left()?))
                    .map_err(|e| format!("socket: {e}"))?;
                match stream.read(&mut buf[got..]) {
                    Ok(0) => {
                        return Err(format!(
                            "disconnected after {got} of {} bytes of the {what}",
                            buf.len()
                        ));
                    }
                    Ok(n) => got += n,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                        ) =>
                    {
                        return Err(format!(
                            "timed out after {:.1} s reading the {what}",
                            self.timeout.as_secs_f64()
                        ));
                    }
                    Err(e) => return Err(format!("reading the {what}: {e}")),
                }
            }
            Ok(())
        };
        let mut len = [0u8; 8];
        read_exact(&mut len, "reply length")?;
        let len = u64::from_be_bytes(len);
        if len > MAX_REPLY {
            return Err(format!(
                "bad framing: reply length {len} exceeds {MAX_REPLY} bytes"
            ));
        }
        let mut body = vec![0u8; len as usize];
        read_exact(&mut body, "reply")?;
        serde_json::from_slice(&body).map_err(|e| {
            format!(
                "the reply is not JSON ({e}): {}",
                String::from_utf8_lossy(&body[..body.len().min(120)])
            )
        })
    }
}

impl Transport for SocketClient {
    fn ask(&mut self, images: &[String], instruction: &str) -> Result<serde_json::Value, String> {
        let request = serde_json::json!({"images": images, "query": instruction});
        self.exchange(request.to_string().as_bytes())
    }

    fn send(&mut self, message: &serde_json::Value) -> Result<serde_json::Value, String> {
        self.exchange(message.to_string().as_bytes())
    }
}
