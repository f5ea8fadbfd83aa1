//! The blocking client: one `ureq` agent with a timeout per request, JSON POSTs, and replies
//! and errors as plain data.

use crate::retry::Failure;
use std::fmt;
use std::io;
use std::time::Duration;

/// Most characters of a reply body quoted in a failure message.
const QUOTED_BODY_CHARS: usize = 200;

/// An HTTP client whose requests may take a fixed time each, connect to last body byte (share
/// one per endpoint; connections are pooled).
#[derive(Debug, Clone)]
pub struct Client {
    agent: ureq::Agent,
}

/// A complete reply, whatever its status.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    /// The status code.
    pub status: u16,
    /// The header names (lower case) and values, in the order received.
    pub headers: Vec<(String, String)>,
    /// The body as text.
    pub body: String,
}

/// Where a request failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Connecting, sending the request or receiving the reply's head.
    Request,
    /// Reading the body of a reply whose head had come.
    Body,
}

/// What kind of failure a request met; the first three are transient.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// The connection could not be made (refused, unreachable, host not found).
    Connect,
    /// The request ran past its time.
    Timeout,
    /// The server closed or reset the connection before the reply was complete.
    Disconnect,
    /// Anything else (a bad URL, TLS, a malformed reply, a body over the size limit): another
    /// attempt would meet it again.
    Other,
}

impl ErrorKind {
    /// True for the kinds another attempt may cure.
    pub fn is_transient(self) -> bool {
        self != ErrorKind::Other
    }

    fn of(e: &ureq::Error) -> ErrorKind {
        match e {
            ureq::Error::Timeout(_) => ErrorKind::Timeout,
            ureq::Error::ConnectionFailed | ureq::Error::HostNotFound => ErrorKind::Connect,
            ureq::Error::Io(e) => match e.kind() {
                io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock => ErrorKind::Timeout,
                io::ErrorKind::ConnectionRefused
                | io::ErrorKind::HostUnreachable
                | io::ErrorKind::NetworkUnreachable
                | io::ErrorKind::AddrNotAvailable => ErrorKind::Connect,
                io::ErrorKind::ConnectionReset
                | io::ErrorKind::ConnectionAborted
                | io::ErrorKind::BrokenPipe
                | io::ErrorKind::NotConnected
                | io::ErrorKind::UnexpectedEof => ErrorKind::Disconnect,
                _ => ErrorKind::Other,
            },
            _ => ErrorKind::Other,
        }
    }
}

/// A request that got no complete reply.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HttpError {
    /// Where it failed.
    pub stage: Stage,
    /// What kind of failure it was.
    pub kind: ErrorKind,
    /// The transport's description (the text of the `ureq` error).
    pub message: String,
    /// The `Retry-After` of a reply whose body then failed to arrive.
    pub retry_after: Option<Duration>,
}

impl HttpError {
    fn new(stage: Stage, e: &ureq::Error, retry_after: Option<Duration>) -> HttpError {
        HttpError {
            stage,
            kind: ErrorKind::of(e),
            message: e.to_string(),
            retry_after,
        }
    }

    /// This error as a retry [`Failure`] worded `message` (callers word the stages their way).
    pub fn failure(&self, message: String) -> Failure {
        Failure {
            message,
            transient: self.kind.is_transient(),
            retry_after: self.retry_after,
        }
    }
}

impl fmt::Display for HttpError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for HttpError {}

impl Client {
    /// A client whose requests may each take `timeout` in all.
    pub fn new(timeout: Duration) -> Client {
        Client {
            // A redirect is answered as the reply it is, not followed: a POST followed through
            // a 301 or 302 arrives as a GET without its body, and an error there would name
            // the first server.
            agent: ureq::Agent::config_builder()
                .timeout_global(Some(timeout))
                .http_status_as_error(false)
                .max_redirects(0)
                .build()
                .into(),
        }
    }

    /// POSTs `body` to `url` as `application/json`, with `Authorization: Bearer KEY` when
    /// `bearer` is given.
    ///
    /// # Errors
    ///
    /// No complete reply: connect errors, timeouts, disconnects and the rest ([`HttpError`]).
    /// Every status, 4xx and 5xx included, is a [`Reply`].
    pub fn post_json(
        &self,
        url: &str,
        body: &str,
        bearer: Option<&str>,
    ) -> Result<Reply, HttpError> {
        let mut req = self
            .agent
            .post(url)
            .header("Content-Type", "application/json");
        if let Some(key) = bearer {
            req = req.header("Authorization", &format!("Bearer {key}"));
        }
        let mut resp = req
            .send(body)
            .map_err(|e| HttpError::new(Stage::Request, &e, None))?;
        let headers: Vec<(String, String)> = resp
            .headers()
            .iter()
            .map(|(k, v)| {
                let value = String::from_utf8_lossy(v.as_bytes()).into_owned();
                (k.as_str().to_string(), value)
            })
            .collect();
        let status = resp.status().as_u16();
        let body = resp.body_mut().read_to_string().map_err(|e| {
            HttpError::new(
                Stage::Body,
                &e,
                retry_after(header(&headers, "retry-after")),
            )
        })?;
        Ok(Reply {
            status,
            headers,
            body,
        })
    }
}

/// The first value of header `name` (any case) in `headers`.
fn header<'a>(headers: &'a [(String, String)], name: &str) -> Option<&'a str> {
    headers
        .iter()
        .find(|(k, _)| k.eq_ignore_ascii_case(name))
        .map(|(_, v)| v.as_str())
}

/// A `Retry-After` value in whole seconds (the HTTP-date form is not used by the APIs here).
fn retry_after(value: Option<&str>) -> Option<Duration> {
    value?.trim().parse().ok().map(Duration::from_secs)
}

impl Reply {
    /// The first value of header `name` (any case).
    pub fn header(&self, name: &str) -> Option<&str> {
        header(&self.headers, name)
    }

    /// The wait the server asked for in `Retry-After` (seconds).
    pub fn retry_after(&self) -> Option<Duration> {
        retry_after(self.header("retry-after"))
    }

    /// True for the statuses another attempt may cure: 408, 429 and 5xx.
    pub fn is_transient(&self) -> bool {
        matches!(self.status, 408 | 429 | 500..=599)
    }

    /// The body of a `200 OK` reply (the APIs here answer nothing else on success).
    ///
    /// # Errors
    ///
    /// Any other status, as the failure `HTTP {status}: {the body's first 200 characters}`
    /// with the reply's `Retry-After`.
    pub fn into_ok(self) -> Result<String, Failure> {
        if self.status == 200 {
            return Ok(self.body);
        }
        let redirect = header(&self.headers, "location")
            .filter(|_| (300..400).contains(&self.status))
            .map(|to| format!("a redirect to {to}, not followed (give that URL)"));
        let quoted: String = self.body.chars().take(QUOTED_BODY_CHARS).collect();
        let said = match redirect {
            Some(r) if quoted.is_empty() => r,
            Some(r) => format!("{r}; {quoted}"),
            None => quoted,
        };
        Err(Failure {
            message: format!("HTTP {}: {said}", self.status),
            transient: self.is_transient(),
            retry_after: self.retry_after(),
        })
    }
}
