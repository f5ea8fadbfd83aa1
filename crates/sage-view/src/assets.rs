//! The page: plain HTML, CSS and JavaScript written for sage3d and embedded in the binary (no
//! build step, no third-party browser library, nothing fetched from elsewhere).

use axum::http::header;
use axum::response::IntoResponse;

/// The page's HTML.
pub const PAGE: &str = include_str!("../assets/index.html");
/// The page's script.
pub const SCRIPT: &str = include_str!("../assets/app.js");
/// The page's style sheet.
pub const STYLE: &str = include_str!("../assets/app.css");

/// `GET /`.
pub async fn page() -> impl IntoResponse {
    ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], PAGE)
}

/// `GET /app.js`.
pub async fn script() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        SCRIPT,
    )
}

/// `GET /app.css`.
pub async fn style() -> impl IntoResponse {
    ([(header::CONTENT_TYPE, "text/css; charset=utf-8")], STYLE)
}
