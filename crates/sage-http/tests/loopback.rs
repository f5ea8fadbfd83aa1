//! The client and the retry policy against a real HTTP/1.1 server on loopback (a thread writing
//! scripted replies and keeping what it received): success, a 503 then success, a 429 with
//! `Retry-After`, a non-retryable 400, a refused connection, a timeout, a body cut short and
//! attempts running out. Pauses go to a recorder, so the waits are asserted, not timed.

use sage_http::{Client, ErrorKind, Failure, GaveUp, HttpError, RetryOn, RetryPolicy, Stage};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::{Arc, Mutex};
use std::time::Duration;

const BODY: &str = r#"{"model":"m","messages":[]}"#;

/// What the server does with one connection.
#[derive(Clone)]
enum Script {
    /// Writes these bytes after reading the request.
    Reply(String),
    /// Reads the request and answers nothing for this long.
    Hang(Duration),
}

/// One request as the server received it: the head (request line and headers) and the body.
#[derive(Debug, Clone)]
struct Received {
    head: String,
    body: String,
}

/// A reply with `status`, extra header lines and a body, closing the connection.
fn reply(status: &str, extra: &str, body: &str) -> Script {
    Script::Reply(format!(
        "HTTP/1.1 {status}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n{extra}\r\n{body}",
        body.len()
    ))
}

fn read_request(stream: &TcpStream) -> Option<Received> {
    let mut reader = BufReader::new(stream.try_clone().ok()?);
    let mut head = String::new();
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line).ok()? == 0 {
            return None;
        }
        head.push_str(&line);
        if line == "\r\n" {
            break;
        }
    }
    let len = head
        .lines()
        .filter_map(|l| l.split_once(':'))
        .find(|(k, _)| k.eq_ignore_ascii_case("content-length"))
        .and_then(|(_, v)| v.trim().parse().ok())
        .unwrap_or(0);
    let mut body = vec![0; len];
    reader.read_exact(&mut body).ok()?;
    Some(Received {
        head,
        body: String::from_utf8(body).ok()?,
    })
}

/// Serves connection n with `script[n]` (the last entry from then on); returns the base URL
/// and what was received.
fn serve(script: Vec<Script>) -> (String, Arc<Mutex<Vec<Received>>>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    let received = Arc::new(Mutex::new(Vec::new()));
    let log = received.clone();
    std::thread::spawn(move || {
        for (n, stream) in listener.incoming().enumerate() {
            let Ok(mut stream) = stream else { continue };
            let Some(request) = read_request(&stream) else {
                continue;
            };
            log.lock().unwrap().push(request);
            match &script[n.min(script.len() - 1)] {
                Script::Reply(bytes) => {
                    let _ = stream.write_all(bytes.as_bytes());
                }
                Script::Hang(d) => std::thread::sleep(*d),
            }
        }
    });
    (url, received)
}

fn client() -> Client {
    Client::new(Duration::from_secs(5))
}

fn policy(retries: u32) -> RetryPolicy {
    RetryPolicy {
        retries,
        initial: Duration::from_millis(100),
        cap: Duration::from_secs(10),
        retry_on: RetryOn::Transient,
    }
}

/// What a run of `policy` gave, every failure it showed and every pause it asked for.
type Run = (Result<String, GaveUp>, Vec<(u32, Failure)>, Vec<Duration>);

/// POSTs [`BODY`] to `url` under `policy`, taking a 200 body as success.
fn post_with(policy: &RetryPolicy, client: &Client, url: &str) -> Run {
    let (mut failures, mut waits) = (Vec::new(), Vec::new());
    let result = policy.run(
        |_| {
            client
                .post_json(url, BODY, None)
                .map_err(|e| e.failure(e.to_string()))?
                .into_ok()
        },
        |n, f| failures.push((n, f.clone())),
        |d| waits.push(d),
    );
    (result, failures, waits)
}

#[test]
fn a_post_sends_json_and_the_key_and_returns_the_reply() {
    let (url, received) = serve(vec![reply("200 OK", "X-Extra: yes\r\n", "{\"ok\":1}")]);
    let got = client()
        .post_json(&format!("{url}/v1/chat/completions"), BODY, Some("sk-1"))
        .unwrap();
    assert_eq!(got.status, 200);
    assert_eq!(got.body, "{\"ok\":1}");
    assert_eq!(got.header("x-extra"), Some("yes"));
    assert_eq!(got.header("Content-Length"), Some("8"));
    assert_eq!(got.retry_after(), None);
    let seen = received.lock().unwrap().clone();
    assert_eq!(seen.len(), 1);
    let head = seen[0].head.to_ascii_lowercase();
    assert!(
        head.starts_with("post /v1/chat/completions http/1.1\r\n"),
        "{head}"
    );
    for line in [
        "content-type: application/json\r\n",
        "authorization: bearer sk-1\r\n",
        &format!("content-length: {}\r\n", BODY.len()),
    ] {
        assert!(head.contains(line), "{line} in {head}");
    }
    assert_eq!(seen[0].body, BODY);
    // No key, no header.
    client().post_json(&url, BODY, None).unwrap();
    let head = received.lock().unwrap()[1].head.to_ascii_lowercase();
    assert!(!head.contains("authorization"), "{head}");
}

#[test]
fn error_statuses_are_replies() {
    let (url, _) = serve(vec![reply("404 Not Found", "", "no such path")]);
    let got = client().post_json(&url, BODY, None).unwrap();
    assert_eq!((got.status, got.body.as_str()), (404, "no such path"));
    assert!(!got.is_transient());
    let failure = got.into_ok().unwrap_err();
    assert_eq!(failure.message, "HTTP 404: no such path");
    assert!(!failure.transient);
    // The body is quoted up to 200 characters.
    let long = "x".repeat(300);
    let (url, _) = serve(vec![reply("500 Internal Server Error", "", &long)]);
    let failure = client()
        .post_json(&url, BODY, None)
        .unwrap()
        .into_ok()
        .unwrap_err();
    assert_eq!(failure.message, format!("HTTP 500: {}", &long[..200]));
    assert!(failure.transient);
    // A redirect is a reply too, naming where it points: never followed (a POST would arrive
    // there as a GET without its body), so the server is asked once.
    let (url, received) = serve(vec![
        reply(
            "302 Found",
            "Location: http://127.0.0.1:9/elsewhere\r\n",
            "",
        ),
        reply("200 OK", "", "{}"),
    ]);
    let failure = client()
        .post_json(&url, BODY, None)
        .unwrap()
        .into_ok()
        .unwrap_err();
    assert_eq!(
        failure.message,
        "HTTP 302: a redirect to http://127.0.0.1:9/elsewhere, not followed (give that URL)"
    );
    assert_eq!(received.lock().unwrap().len(), 1);
}

#[test]
fn a_503_is_retried_after_the_initial_pause() {
    let (url, received) = serve(vec![
        reply("503 Service Unavailable", "", "{\"error\":\"busy\"}"),
        reply("200 OK", "", "{\"ok\":1}"),
    ]);
    let (result, failures, waits) = post_with(&policy(3), &client(), &url);
    assert_eq!(result.unwrap(), "{\"ok\":1}");
    assert_eq!(failures.len(), 1);
    assert_eq!(failures[0].0, 0);
    assert_eq!(failures[0].1.message, "HTTP 503: {\"error\":\"busy\"}");
    assert_eq!(waits, [Duration::from_millis(100)]);
    assert_eq!(received.lock().unwrap().len(), 2);
}

#[test]
fn a_429_waits_as_long_as_retry_after_says_up_to_the_cap() {
    let script = vec![
        reply("429 Too Many Requests", "Retry-After: 2\r\n", "slow down"),
        reply("200 OK", "", "{}"),
    ];
    let (url, _) = serve(script.clone());
    let (result, failures, waits) = post_with(&policy(3), &client(), &url);
    assert_eq!(result.unwrap(), "{}");
    assert_eq!(failures[0].1.retry_after, Some(Duration::from_secs(2)));
    assert_eq!(waits, [Duration::from_secs(2)]);

    let (url, _) = serve(script);
    let capped = RetryPolicy {
        cap: Duration::from_millis(1500),
        ..policy(3)
    };
    let (result, _, waits) = post_with(&capped, &client(), &url);
    assert!(result.is_ok());
    assert_eq!(waits, [Duration::from_millis(1500)]);
}

#[test]
fn a_400_is_not_retried_unless_the_policy_retries_everything() {
    let (url, received) = serve(vec![reply("400 Bad Request", "", "bad model")]);
    let (result, failures, waits) = post_with(&policy(3), &client(), &url);
    let gave_up = result.unwrap_err();
    assert_eq!(gave_up.attempts, 1);
    assert_eq!(gave_up.last.message, "HTTP 400: bad model");
    assert!(!gave_up.last.transient);
    assert_eq!((failures.len(), waits.len()), (1, 0));
    assert_eq!(received.lock().unwrap().len(), 1);

    let any = RetryPolicy {
        retry_on: RetryOn::Any,
        ..policy(2)
    };
    let (result, failures, waits) = post_with(&any, &client(), &url);
    assert_eq!(result.unwrap_err().attempts, 3);
    assert_eq!(failures.len(), 3);
    assert_eq!(
        waits,
        [Duration::from_millis(100), Duration::from_millis(200)]
    );
    assert_eq!(received.lock().unwrap().len(), 4);
}

#[test]
fn a_refused_connection_is_a_transient_connect_error() {
    let url = {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        format!("http://{}", listener.local_addr().unwrap())
    };
    let e: HttpError = client().post_json(&url, BODY, None).unwrap_err();
    assert_eq!((e.stage, e.kind), (Stage::Request, ErrorKind::Connect));
    assert!(e.kind.is_transient());
    let (result, failures, waits) = post_with(&policy(1), &client(), &url);
    assert_eq!(result.unwrap_err().attempts, 2);
    assert_eq!(failures[1].1.message, e.message);
    assert_eq!(waits, [Duration::from_millis(100)]);
}

#[test]
fn a_server_slower_than_the_timeout_is_a_timeout() {
    let (url, received) = serve(vec![Script::Hang(Duration::from_secs(3))]);
    let quick = Client::new(Duration::from_millis(300));
    let e = quick.post_json(&url, BODY, None).unwrap_err();
    assert_eq!((e.stage, e.kind), (Stage::Request, ErrorKind::Timeout));
    assert!(e.message.contains("timeout"), "{e}");
    assert_eq!(received.lock().unwrap()[0].body, BODY);
}

#[test]
fn a_body_cut_short_is_a_disconnect_that_keeps_retry_after() {
    let (url, _) = serve(vec![Script::Reply(
        "HTTP/1.1 503 Service Unavailable\r\nContent-Length: 100\r\nRetry-After: 3\r\nConnection: close\r\n\r\nshort"
            .into(),
    )]);
    let e = client().post_json(&url, BODY, None).unwrap_err();
    assert_eq!((e.stage, e.kind), (Stage::Body, ErrorKind::Disconnect));
    assert_eq!(e.retry_after, Some(Duration::from_secs(3)));
    let failure = e.failure(format!("reading the reply: {e}"));
    assert!(failure.transient);
    assert_eq!(failure.retry_after, Some(Duration::from_secs(3)));
}

#[test]
fn attempts_run_out_with_every_failure_shown() {
    let (url, received) = serve(vec![reply("503 Service Unavailable", "", "busy")]);
    let (result, failures, waits) = post_with(&policy(2), &client(), &url);
    assert_eq!(
        result.unwrap_err(),
        GaveUp {
            attempts: 3,
            last: Failure {
                message: "HTTP 503: busy".into(),
                transient: true,
                retry_after: None,
            },
        }
    );
    let attempts: Vec<u32> = failures.iter().map(|(n, _)| *n).collect();
    assert_eq!(attempts, [0, 1, 2]);
    assert_eq!(
        waits,
        [Duration::from_millis(100), Duration::from_millis(200)]
    );
    assert_eq!(received.lock().unwrap().len(), 3);
}
