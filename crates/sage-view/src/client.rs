//! A minimal HTTP/1.1 client for the viewer's own routes on loopback: one request per
//! connection, a body with its length. The benchmark (`sage3d bench view`) and the tests talk
//! to a running viewer through it, as the page does.

use sage_core::{Error, Result};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};

/// A reply: its status and body.
#[derive(Debug, Clone, PartialEq)]
pub struct Reply {
    /// HTTP status.
    pub status: u16,
    /// Response headers, names in lower case.
    pub headers: Vec<(String, String)>,
    /// Body bytes.
    pub body: Vec<u8>,
}

impl Reply {
    /// The body as JSON.
    ///
    /// # Errors
    ///
    /// A body that is not JSON.
    pub fn json(&self) -> Result<serde_json::Value> {
        serde_json::from_slice(&self.body)
            .map_err(|e| Error::invalid(format!("reply {}: not JSON: {e}", self.status)))
    }
}

/// Sends `method target` to `addr` with the JSON `body` (if any) and `headers` (a `Host` of
/// 127.0.0.1 unless one is given) and reads the whole reply.
///
/// # Errors
///
/// A connection or read error, or a reply that is not HTTP.
pub fn request(
    addr: SocketAddr,
    method: &str,
    target: &str,
    body: Option<&serde_json::Value>,
    headers: &[(&str, &str)],
) -> Result<Reply> {
    let io = |e: std::io::Error| Error::invalid(format!("{method} {target}: {e}"));
    let mut s = TcpStream::connect(addr).map_err(io)?;
    let body = body.map(ToString::to_string).unwrap_or_default();
    let mut head = format!(
        "{method} {target} HTTP/1.1\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    if !headers.iter().any(|(k, _)| k.eq_ignore_ascii_case("host")) {
        head += &format!("Host: 127.0.0.1:{}\r\n", addr.port());
    }
    if !body.is_empty() {
        head += "Content-Type: application/json\r\n";
    }
    for (k, v) in headers {
        head += &format!("{k}: {v}\r\n");
    }
    s.write_all(format!("{head}\r\n{body}").as_bytes())
        .map_err(io)?;
    let mut reply = Vec::new();
    s.read_to_end(&mut reply).map_err(io)?;
    let bad = || Error::invalid(format!("{method} {target}: not an HTTP reply"));
    let split = reply
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .ok_or_else(bad)?;
    let head = String::from_utf8_lossy(&reply[..split]).into_owned();
    let mut lines = head.lines();
    let status = lines
        .next()
        .and_then(|l| l.split(' ').nth(1))
        .and_then(|c| c.parse().ok())
        .ok_or_else(bad)?;
    let headers = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    Ok(Reply {
        status,
        headers,
        body: reply[split + 4..].to_vec(),
    })
}
