//! The HTTP protocols: `POST /vln_step` of the SAGE-3D model servers (JSON
//! `{images, instruction, current_yaw: 0.0}` → `{result: text}`) and OpenAI-compatible chat
//! completions (the paper's MLLM baselines: instruction and image data URIs in, one action
//! word out). Requests go through `sage-http`: plain HTTP; HTTPS when the `tls` feature
//! (rustls) is built in.

use super::{Transport, parse};
use sage_core::{Error, Result};
use sage_http::{Client, Reply, Stage};
use std::time::Duration;

/// The system prompt of the chat agent, after the published MLLM baseline server: one action
/// word per answer.
pub const CHAT_PROMPT: &str = "You are a robot navigating an indoor scene by following a \
navigation instruction. You see the current camera image (the last image; earlier images, \
when given, are the most recent past views). Decide the next action. Answer with exactly one \
of: MOVE_FORWARD (0.25 m), TURN_LEFT (15 degrees), TURN_RIGHT (15 degrees), STOP (when the \
goal is reached). Output only the action.";

/// Checks the scheme of `url` (http or https; none given means http) and trims it.
fn with_scheme(url: &str) -> Result<String> {
    let url = url.trim();
    let lower = url.to_ascii_lowercase();
    if lower.starts_with("http://") || lower.starts_with("https://") {
        Ok(url.to_string())
    } else if url.contains("://") || url.is_empty() {
        Err(Error::invalid(format!(
            "'{url}': expected an http:// or https:// URL"
        )))
    } else {
        Ok(format!("http://{url}"))
    }
}

/// The step URL of an `http:` agent: `/vln_step` appended when `url` names no path.
///
/// # Errors
///
/// A scheme other than http(s).
pub fn step_url(url: &str) -> Result<String> {
    let url = with_scheme(url)?;
    let after_scheme = url.find("://").map_or(0, |i| i + 3);
    match url[after_scheme..].find('/') {
        Some(i) if after_scheme + i + 1 < url.len() => Ok(url),
        _ => Ok(format!("{}/vln_step", url.trim_end_matches('/'))),
    }
}

/// The API base of a `chat:` agent, without a trailing slash.
///
/// # Errors
///
/// A scheme other than http(s).
pub fn base_url(url: &str) -> Result<String> {
    Ok(with_scheme(url)?.trim_end_matches('/').to_string())
}

/// `x` as the f64 of its shortest decimal: 0.1f32 goes out as `0.1`, where widening it would
/// send `0.10000000149011612`.
fn decimal(x: f32) -> f64 {
    x.to_string().parse().unwrap_or_else(|_| f64::from(x))
}

/// Most characters of an HTML page quoted in the fault it makes.
const QUOTED_PAGE_CHARS: usize = 120;

/// True for a reply that is a web page: said so by its `Content-Type`, or, where that is
/// missing or generic, by a body that opens as an HTML document. A proxy's sign-in page or a
/// web app at the wrong path answers 200 with one; read as a model's text, a page that
/// mentions "move forward" would become moves.
fn is_html_page(reply: &Reply) -> bool {
    let declared = reply
        .header("content-type")
        .is_some_and(|t| t.trim().to_ascii_lowercase().starts_with("text/html"));
    let opening: String = reply
        .body
        .trim_start()
        .chars()
        .take(15)
        .collect::<String>()
        .to_ascii_lowercase();
    declared || opening.starts_with("<!doctype html") || opening.starts_with("<html")
}

/// POSTs `body` as JSON to `url`; the reply's text when the status is 200 and the reply is not
/// a web page, else a fault.
fn post(
    client: &Client,
    url: &str,
    body: &serde_json::Value,
    bearer: Option<&str>,
) -> std::result::Result<String, String> {
    let reply = client
        .post_json(url, &body.to_string(), bearer)
        .map_err(|e| match e.stage {
            Stage::Request => e.to_string(),
            Stage::Body => format!("reading the reply: {e}"),
        })?;
    if reply.status == 200 && is_html_page(&reply) {
        let quoted: String = reply.body.trim().chars().take(QUOTED_PAGE_CHARS).collect();
        return Err(format!(
            "the reply is an HTML page, not a model server's answer (is {url} the server's \
             endpoint?): {quoted}"
        ));
    }
    reply.into_ok().map_err(|f| f.message)
}

/// A client of a `/vln_step` server (NaVILA, NaVid and the MLLM servers of SAGE-3D).
pub struct StepClient {
    url: String,
    client: Client,
}

impl StepClient {
    /// A client POSTing to `url`; each request may take `timeout` in all.
    pub fn new(url: &str, timeout: Duration) -> StepClient {
        StepClient {
            url: url.to_string(),
            client: Client::new(timeout),
        }
    }
}

impl Transport for StepClient {
    fn ask(
        &mut self,
        images: &[String],
        instruction: &str,
    ) -> std::result::Result<serde_json::Value, String> {
        let body = serde_json::json!({
            "images": images,
            "instruction": instruction,
            "current_yaw": 0.0,
        });
        step_answer(post(&self.client, &self.url, &body, None)?)
    }
}

/// A `/vln_step` reply body as the parser reads it: its JSON, or, for a body that is not JSON,
/// the text as it is (a Python dict literal included, which the parser reads as one). A body
/// that begins as an object or array and parses as neither is one cut short or broken
/// (`{"result": "MOVE_FOR`), not free text: read as text, its words would become moves.
fn step_answer(text: String) -> std::result::Result<serde_json::Value, String> {
    match serde_json::from_str(&text) {
        Ok(value) => Ok(value),
        Err(e)
            if text.trim_start().starts_with(['{', '['])
                && parse::dict_value(text.trim()).is_none() =>
        {
            Err(format!("the reply is JSON cut short or broken: {e}"))
        }
        Err(_) => Ok(serde_json::Value::String(text)),
    }
}

/// An OpenAI-compatible chat-completions client; the API key comes from `OPENAI_API_KEY`
/// when set, and is never stored.
pub struct ChatClient {
    url: String,
    model: String,
    temperature: f32,
    max_tokens: u32,
    client: Client,
}

impl ChatClient {
    /// A client of `model` at `base_url` (requests go to `BASE_URL/chat/completions`).
    pub fn new(
        model: &str,
        base_url: &str,
        timeout: Duration,
        temperature: f32,
        max_tokens: u32,
    ) -> ChatClient {
        ChatClient {
            url: format!("{base_url}/chat/completions"),
            model: model.to_string(),
            temperature,
            max_tokens,
            client: Client::new(timeout),
        }
    }

    /// The request body: the system prompt, then the instruction and the images (current
    /// last) as data URIs.
    pub fn request(&self, images: &[String], instruction: &str) -> serde_json::Value {
        let mut content = vec![serde_json::json!({
            "type": "text",
            "text": format!("Instruction: {instruction}"),
        })];
        content.extend(images.iter().map(|b64| {
            serde_json::json!({
                "type": "image_url",
                "image_url": {"url": format!("data:image/jpeg;base64,{b64}")},
            })
        }));
        serde_json::json!({
            "model": self.model,
            "messages": [
                {"role": "system", "content": CHAT_PROMPT},
                {"role": "user", "content": content},
            ],
            "temperature": decimal(self.temperature),
            "max_tokens": self.max_tokens,
        })
    }
}

impl Transport for ChatClient {
    fn ask(
        &mut self,
        images: &[String],
        instruction: &str,
    ) -> std::result::Result<serde_json::Value, String> {
        let key = std::env::var("OPENAI_API_KEY")
            .ok()
            .filter(|k| !k.is_empty());
        let text = post(
            &self.client,
            &self.url,
            &self.request(images, instruction),
            key.as_deref(),
        )?;
        let reply: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| format!("the reply is not JSON: {e}"))?;
        Ok(chat_answer(reply))
    }
}

/// What the parser reads of a chat completion: `choices[0].message.content`, as text (a
/// content given as parts, their text parts joined). A reply that came through without it is
/// handed on for the parser to call what it is, not made a transport fault: an `error` body
/// (some servers answer errors with status 200) as a server error, anything else (no choices,
/// a `null` content) as unparseable, quoted.
fn chat_answer(reply: serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match reply.pointer("/choices/0/message/content") {
        Some(Value::String(text)) => Value::String(text.clone()),
        Some(Value::Array(parts)) => Value::String(
            parts
                .iter()
                .filter_map(|p| p.get("text").and_then(Value::as_str))
                .collect::<Vec<_>>()
                .join(" "),
        ),
        _ => match reply.get("error") {
            Some(error) => serde_json::json!({"status": "error", "error": error}),
            None => reply,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls() {
        assert_eq!(
            step_url("127.0.0.1:8000").unwrap(),
            "http://127.0.0.1:8000/vln_step"
        );
        assert_eq!(step_url("http://h:1/").unwrap(), "http://h:1/vln_step");
        assert_eq!(
            step_url("http://h:1/api/step").unwrap(),
            "http://h:1/api/step"
        );
        assert_eq!(base_url("https://api.x/v1/").unwrap(), "https://api.x/v1");
        assert!(step_url("ftp://h").is_err());
    }

    /// A reply of status 200 with `content_type` and `body`.
    fn reply(content_type: Option<&str>, body: &str) -> Reply {
        Reply {
            status: 200,
            headers: content_type
                .map(|t| ("content-type".to_string(), t.to_string()))
                .into_iter()
                .collect(),
            body: body.to_string(),
        }
    }

    #[test]
    fn a_web_page_is_told_from_a_model_answer() {
        let page = "<p>Sign in, then move forward to your dashboard</p>";
        assert!(is_html_page(&reply(Some("text/html; charset=utf-8"), page)));
        assert!(is_html_page(&reply(Some(" Text/HTML"), "move forward")));
        for body in [
            "\n  <!DOCTYPE html><html>",
            "<HTML><body>move forward</body>",
        ] {
            assert!(is_html_page(&reply(Some("text/plain"), body)), "{body}");
            assert!(is_html_page(&reply(None, body)), "{body}");
        }
        for (t, body) in [
            (Some("text/plain"), "move forward 75 cm"),
            (Some("application/json"), r#"{"result": "<html> STOP"}"#),
            (None, "<turn left> 30 degrees"),
        ] {
            assert!(!is_html_page(&reply(t, body)), "{body}");
        }
    }

    #[test]
    fn a_web_page_answered_with_200_is_a_fault_naming_the_url() {
        use std::io::{Read, Write};
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let url = format!("http://{}/vln_step", listener.local_addr().unwrap());
        let server = std::thread::spawn(move || {
            let (mut stream, _) = listener.accept().unwrap();
            let mut head = Vec::new();
            let mut byte = [0u8];
            while !head.ends_with(b"\r\n\r\n") {
                stream.read_exact(&mut byte).unwrap();
                head.push(byte[0]);
            }
            let head = String::from_utf8(head).unwrap();
            let length: usize = head
                .lines()
                .find_map(|l| {
                    l.to_ascii_lowercase()
                        .strip_prefix("content-length:")
                        .map(|v| v.trim().parse().unwrap())
                })
                .unwrap();
            let mut body = vec![0u8; length];
            stream.read_exact(&mut body).unwrap();
            let page = "<html><body>Welcome! Click to move forward.</body></html>";
            write!(
                stream,
                "HTTP/1.1 200 OK\r\nContent-Type: text/html\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{page}",
                page.len()
            )
            .unwrap();
            (head, body)
        });
        let mut client = StepClient::new(&url, Duration::from_secs(10));
        let e = client.ask(&["AAAA".into()], "go").unwrap_err();
        assert!(e.contains("HTML page") && e.contains(&url), "{e}");
        let (head, body) = server.join().unwrap();
        assert!(head.starts_with("POST /vln_step "), "{head}");
        let sent: serde_json::Value = serde_json::from_slice(&body).unwrap();
        assert_eq!(sent["instruction"], "go");
    }

    #[test]
    fn a_step_reply_is_json_or_text_but_never_json_cut_short() {
        assert_eq!(
            step_answer(r#"{"result": "STOP"}"#.into()).unwrap(),
            serde_json::json!({"result": "STOP"})
        );
        for text in [
            "move forward 75 cm",
            "{'status': 'success', 'result': 'STOP'}",
        ] {
            assert_eq!(step_answer(text.into()).unwrap(), text);
        }
        for cut in [r#"{"result": "MOVE_FOR"#, "  [1, 2", "{'result': 'STOP'"] {
            let e = step_answer(cut.into()).unwrap_err();
            assert!(e.contains("cut short"), "{cut}: {e}");
        }
    }

    #[test]
    fn chat_replies_without_a_content_are_server_errors_or_unparseable() {
        use crate::remote::parse::{Steps, parse_reply};
        use sage_env::agents::FaultKind;
        let steps = Steps {
            forward: 0.25,
            turn_deg: 15.0,
            bare_turn_deg: None,
        };
        let content = |c: serde_json::Value| {
            chat_answer(
                serde_json::json!({"choices": [{"message": {"role": "assistant", "content": c}}]}),
            )
        };
        assert_eq!(content(serde_json::json!("STOP")), "STOP");
        let parts = serde_json::json!([{"type": "text", "text": "I will"}, {"type": "text", "text": "TURN_LEFT"}]);
        assert_eq!(content(parts), "I will TURN_LEFT");
        let error = chat_answer(
            serde_json::json!({"error": {"message": "model overloaded", "type": "server_error"}}),
        );
        let (kind, why) = parse_reply(&error, &steps).unwrap_err();
        assert_eq!(kind, FaultKind::ServerError, "{why}");
        assert!(why.contains("model overloaded"), "{why}");
        for empty in [
            serde_json::json!({"choices": []}),
            serde_json::json!({"choices": [{"message": {"content": null}}]}),
        ] {
            let (kind, why) = parse_reply(&chat_answer(empty.clone()), &steps).unwrap_err();
            assert_eq!(kind, FaultKind::Unparseable, "{empty}: {why}");
        }
    }

    #[test]
    fn the_chat_request_sends_the_temperature_as_written() {
        let chat = ChatClient::new("m", "http://h/v1", Duration::from_secs(1), 0.1, 64);
        let body = chat.request(&["AAAA".into()], "go");
        assert_eq!(body["temperature"].to_string(), "0.1");
        assert_eq!(body["max_tokens"], 64);
        assert_eq!(decimal(0.7), 0.7);
        assert_eq!(decimal(1.0), 1.0);
    }
}
