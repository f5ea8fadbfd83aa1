//! The web server: the page, its assets and the JSON API, on axum over tokio.
//!
//! Routes (every `/api` answer is JSON unless it is an image; every `/api` error is
//! `{"error": …}`: 400 for a bad request, 404 for something that is not here, 403 for what
//! is refused, and axum's own statuses for a request of the wrong form, a session id that is
//! not a number or a frame query missing a field (400), a body that is not the route's JSON
//! (422), a route asked with another method (405)):
//!
//! | route | what |
//! |---|---|
//! | `GET /` | the page ([`crate::assets`]) |
//! | `GET /api/info` | what is viewed: kind, scenes, episodes with outcomes, preset (with its bodies, `splat_bodies`), play progress |
//! | `GET /api/scenes/{scene}/map` | the map's pixel frame and its objects, rooms, doors |
//! | `GET /api/scenes/{scene}/map.png` | the map image |
//! | `GET /api/scenes/{scene}/frame?x&y&z&yaw&pitch&width&height&layer&format` | a frame; its `X-Sage3d-Render` header is the `sage3d render` command of the same image |
//! | `POST /api/sessions` | open a session: `{scene}` or `{episode}`, `{play: true}` to play it (`{map_shown: true}`: with the map from the start); in human play an episode is explored only once played |
//! | `POST /api/sessions/{id}/step` | `{action}`; a played episode that ends is recorded |
//! | `POST /api/sessions/{id}/place` | `{x, y, yaw}`: an explore session starts again there |
//! | `POST /api/sessions/{id}/map` | a play session notes that the map was shown |
//! | `GET /api/episodes/{id}` | a run's (or a played) episode, step by step |
//! | `GET /api/episodes/{id}/video.gif` | that episode as an animation (`sage3d report --videos`'s) |
//!
//! Names in a request (scenes, episodes, sessions) are looked up among those the viewer
//! opened; none becomes a path. A `POST` carries JSON (`Content-Type: application/json`, at
//! most [`MAX_BODY`] bytes, arriving within [`BODY_TIMEOUT`]) and, when a browser sends it, an
//! `Origin` of the viewer itself: another site's page can neither send a form nor script a
//! request that changes a session. At most one frame per worker thread renders at once (the
//! rest wait their turn) and one animation is made at a time ([`crate::videos`]).

use crate::frame::{self, FrameRequest};
use crate::player::{episode_detail, episode_list};
use crate::scenes::SceneCache;
use crate::session::{self, Purpose, Session, Sessions};
use crate::subject::{self, Subject, ViewOptions};
use crate::videos::VideoCache;
use axum::Router;
use axum::body::Body;
use axum::extract::{Path, Query, Request, State};
use axum::http::{HeaderMap, Method, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use sage_core::{Error, Result};
use sage_env::{ActionSpace, EnvConfig};
use sage_eval::{EvalRecord, EvalSettings};
use sage_physics::AgentProfile;
use serde::Deserialize;
use serde_json::{Value, json};
use std::net::{IpAddr, SocketAddr};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::Semaphore;

/// The largest request body: session requests are a few numbers.
pub const MAX_BODY: usize = 64 * 1024;

/// How long a request's body may take to arrive once its head has.
pub const BODY_TIMEOUT: Duration = Duration::from_secs(30);

/// A started viewer: where it listens and the URL to open.
#[derive(Debug, Clone, PartialEq)]
pub struct Server {
    /// The bound address.
    pub addr: SocketAddr,
    /// The page's URL (with the token when one is needed); on a server listening on every
    /// interface, its loopback URL.
    pub url: String,
}

impl Server {
    /// The line that tells a person where to open the viewer.
    pub fn announcement(&self) -> String {
        let mut line = format!("sage3d view: open {}", self.url);
        if self.addr.ip().is_unspecified() {
            line += " (listening on every interface: from another machine, put this machine's name or address in place of the loopback one)";
        }
        line
    }
}

/// The viewer's state, shared by every request.
struct App {
    subject: Mutex<Subject>,
    scenes: SceneCache,
    sessions: Mutex<Sessions>,
    /// The environment explore sessions move in (the preset's, or the run's).
    config: EnvConfig,
    /// The environment a person plays in (the human run's).
    play_config: Option<EnvConfig>,
    profile: AgentProfile,
    token: Option<String>,
    loopback: bool,
    title: String,
    /// One permit per render under way: renders beyond the worker threads would only wait on
    /// each other while each held a frame's buffers.
    renders: Arc<Semaphore>,
    videos: VideoCache,
}

/// An error as the API answers it.
struct ApiError(StatusCode, String);

impl From<Error> for ApiError {
    fn from(e: Error) -> ApiError {
        ApiError(StatusCode::BAD_REQUEST, e.to_string())
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.0, axum::Json(json!({"error": self.1}))).into_response()
    }
}

fn not_found(what: String) -> ApiError {
    ApiError(StatusCode::NOT_FOUND, what)
}

type ApiResult<T> = std::result::Result<T, ApiError>;

/// Runs `work` off the async threads (loads, renders and physics take milliseconds to
/// seconds).
async fn blocking<T: Send + 'static>(
    work: impl FnOnce() -> ApiResult<T> + Send + 'static,
) -> ApiResult<T> {
    tokio::task::spawn_blocking(work)
        .await
        .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?
}

fn lock<T>(m: &Mutex<T>) -> ApiResult<std::sync::MutexGuard<'_, T>> {
    m.lock()
        .map_err(|_| ApiError(StatusCode::INTERNAL_SERVER_ERROR, "state poisoned".into()))
}

/// Opens what `opts` names, binds, calls `on_ready` with the address and URL, and serves
/// until `keep_going` returns false (it is asked four times a second, on the calling thread).
///
/// # Errors
///
/// What [`subject::open`] refuses, a non-loopback address without [`ViewOptions::public`],
/// an address that cannot be bound.
pub fn serve(
    opts: &ViewOptions,
    on_ready: impl FnOnce(&Server),
    keep_going: impl Fn() -> bool,
) -> Result<()> {
    if !opts.host.is_loopback() && !opts.public {
        return Err(Error::invalid(format!(
            "{} is not a loopback address: serving to other machines needs the explicit flag `public` (every request then needs the printed URL's token)",
            opts.host
        )));
    }
    let app = Arc::new(open_app(opts)?);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| Error::invalid(format!("cannot start the server's runtime: {e}")))?;
    runtime.block_on(async move {
        let addr = SocketAddr::new(opts.host, opts.port);
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .map_err(|e| Error::invalid(format!("cannot listen on {addr}: {e}")))?;
        let addr = listener
            .local_addr()
            .map_err(|e| Error::invalid(e.to_string()))?;
        let host = match addr.ip() {
            IpAddr::V6(ip) if ip.is_unspecified() => "[::1]".to_string(),
            IpAddr::V4(ip) if ip.is_unspecified() => "127.0.0.1".to_string(),
            IpAddr::V6(ip) => format!("[{ip}]"),
            IpAddr::V4(ip) => ip.to_string(),
        };
        let url = match &app.token {
            Some(t) => format!("http://{host}:{}/?token={t}", addr.port()),
            None => format!("http://{host}:{}/", addr.port()),
        };
        on_ready(&Server { addr, url });
        let (stop, stopped) = tokio::sync::watch::channel(false);
        let server = tokio::spawn(crate::connections::serve(listener, router(app), stopped));
        // Asked here, on the calling thread: Python can only see its signals there.
        while keep_going() && !server.is_finished() {
            tokio::time::sleep(Duration::from_millis(250)).await;
        }
        let _ = stop.send(true);
        server
            .await
            .map_err(|e| Error::invalid(format!("server: {e}")))
    })
}

/// The environment a run is viewed in: the one it recorded (camera, profile, task), moving with
/// its steps, on its bodies; a run that moved by velocities (a pose replay, a Python run's
/// ground actions) has no step for the keys, so explore sessions take its preset's steps.
fn explorable(env: &EnvConfig, settings: &EvalSettings) -> Result<EnvConfig> {
    let actions = match env.actions {
        ActionSpace::Discrete { .. } => env.actions,
        _ => EnvConfig::preset(&settings.preset)?.actions,
    };
    Ok(EnvConfig {
        actions,
        // The settings record the bodies in every run, also one recorded before its `env`
        // was (whose environment is then the preset's, with the default bodies).
        splat_bodies: settings.splat_bodies,
        ..env.clone()
    })
}

/// The state of a viewer of `opts`.
fn open_app(opts: &ViewOptions) -> Result<App> {
    let (subject, dirs) = subject::open(opts)?;
    let (config, play_config, title) = match &subject {
        Subject::Run { settings, env, .. } => (
            explorable(env, settings)?,
            None,
            format!("run: {} on {}", settings.agent, settings.split),
        ),
        Subject::Play { run } => {
            let play = run.env_config()?;
            // Exploring a played episode moves on the bodies it was played on: one load of
            // each scene serves both.
            let explore = EnvConfig {
                splat_bodies: play.splat_bodies,
                ..EnvConfig::preset(&run.settings().preset)?
            };
            (
                explore,
                Some(play),
                format!("human play: {}", run.folder().display()),
            )
        }
        Subject::Dataset { split, .. } => (
            EnvConfig::preset(&opts.preset)?,
            None,
            format!("dataset split {split}"),
        ),
        Subject::Scenes => (EnvConfig::preset(&opts.preset)?, None, "scenes".into()),
    };
    let profile = config.profile()?;
    let token = if opts.public {
        let mut bytes = [0u8; 16];
        getrandom::fill(&mut bytes).map_err(|e| Error::invalid(format!("no random token: {e}")))?;
        Some(bytes.iter().map(|b| format!("{b:02x}")).collect())
    } else {
        None
    };
    Ok(App {
        subject: Mutex::new(subject),
        scenes: SceneCache::new(dirs, opts.device),
        sessions: Mutex::new(Sessions::default()),
        config,
        play_config,
        profile,
        token,
        loopback: opts.host.is_loopback(),
        title: format!("{title} — {}", opts.path.display()),
        renders: Arc::new(Semaphore::new(rayon::current_num_threads().max(1))),
        videos: VideoCache::default(),
    })
}

/// The routes over `app`, behind the guard.
fn router(app: Arc<App>) -> Router {
    Router::new()
        .route("/", get(crate::assets::page))
        .route("/app.js", get(crate::assets::script))
        .route("/app.css", get(crate::assets::style))
        .route("/api/info", get(info))
        .route("/api/scenes/{scene}/map", get(map))
        .route("/api/scenes/{scene}/map.png", get(map_png))
        .route("/api/scenes/{scene}/frame", get(frame))
        .route("/api/sessions", post(open_session))
        .route("/api/sessions/{id}/step", post(step))
        .route("/api/sessions/{id}/place", post(place))
        .route("/api/sessions/{id}/map", post(map_shown))
        .route("/api/episodes/{id}", get(episode))
        .route("/api/episodes/{id}/video.gif", get(video))
        .layer(middleware::from_fn(json_errors))
        .layer(middleware::from_fn_with_state(app.clone(), guard))
        .with_state(app)
}

/// Lets a request through only with the token (when the viewer has one) and, on a loopback
/// address, only when it names a loopback host (a page of another site cannot reach the
/// viewer through a name that resolves to 127.0.0.1); a `POST` only as [`posted`] lets it.
async fn guard(State(app): State<Arc<App>>, req: Request, next: Next) -> Response {
    if app.loopback && !loopback_host(req.headers()) {
        return ApiError(
            StatusCode::FORBIDDEN,
            "the viewer answers requests to localhost only".into(),
        )
        .into_response();
    }
    // The script and style sheet hold no data: the page loads them without the token.
    let asset = matches!(req.uri().path(), "/app.js" | "/app.css");
    if let Some(token) = app.token.as_ref().filter(|_| !asset) {
        let given = req
            .headers()
            .get("x-sage3d-token")
            .and_then(|v| v.to_str().ok())
            .map(str::to_string)
            .or_else(|| {
                req.uri().query().and_then(|q| {
                    q.split('&')
                        .find_map(|kv| kv.strip_prefix("token=").map(str::to_string))
                })
            });
        if !given.is_some_and(|g| same(g.as_bytes(), token.as_bytes())) {
            return ApiError(
                StatusCode::FORBIDDEN,
                "this viewer needs the token of the URL it printed".into(),
            )
            .into_response();
        }
    }
    if req.method() == Method::GET || req.method() == Method::HEAD {
        return next.run(req).await;
    }
    match posted(req).await {
        Ok(req) => next.run(req).await,
        Err(e) => e.into_response(),
    }
}

/// Answers an `/api` error that is not yet JSON as `{"error": …}` with its status and headers:
/// axum's own refusals of a request's form (a path parameter or query that does not parse,
/// a body that is not the route's JSON) are plain text, and a route that does not exist or
/// a wrong method has no body at all.
async fn json_errors(req: Request, next: Next) -> Response {
    let api = req.uri().path().starts_with("/api/");
    let what = format!("{} {}", req.method(), req.uri().path());
    let response = next.run(req).await;
    let status = response.status();
    let json = response
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|t| t.to_str().ok())
        .is_some_and(|t| t.starts_with("application/json"));
    if !api || json || !(status.is_client_error() || status.is_server_error()) {
        return response;
    }
    let (parts, body) = response.into_parts();
    // axum's refusals are a line; a longer body is none of them, and its status says enough.
    let text = axum::body::to_bytes(body, MAX_BODY)
        .await
        .map(|b| String::from_utf8_lossy(&b).trim().to_string())
        .unwrap_or_default();
    let text = if text.is_empty() {
        format!("{what}: {}", status.canonical_reason().unwrap_or("error"))
    } else {
        text
    };
    let mut answer = ApiError(status, text).into_response();
    // The others stay (a 405's `Allow`); the body's type and length are the new body's.
    for (name, value) in &parts.headers {
        if name != header::CONTENT_TYPE && name != header::CONTENT_LENGTH {
            answer.headers_mut().append(name.clone(), value.clone());
        }
    }
    answer
}

/// A request that changes something, let through when it is JSON sent by the viewer's own
/// page or a program (a browser names the page's origin; a form or a script of another site
/// cannot send JSON without a preflight the viewer does not answer), with its body read now
/// within [`MAX_BODY`] and [`BODY_TIMEOUT`].
async fn posted(req: Request) -> ApiResult<Request> {
    let (parts, body) = req.into_parts();
    let text = |name| parts.headers.get(name).and_then(|v| v.to_str().ok());
    if let Some(origin) = text(header::ORIGIN) {
        let host = text(header::HOST).unwrap_or_default();
        let own = origin
            .split_once("://")
            .is_some_and(|(_, h)| !host.is_empty() && h.eq_ignore_ascii_case(host));
        if !own {
            return Err(ApiError(
                StatusCode::FORBIDDEN,
                format!("a request from the page of {origin} is not the viewer's own"),
            ));
        }
    }
    let json = text(header::CONTENT_TYPE).is_some_and(|t| {
        t.split(';')
            .next()
            .is_some_and(|m| m.trim().eq_ignore_ascii_case("application/json"))
    });
    if !json {
        return Err(ApiError(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            format!(
                "{} {}: the body must be JSON, sent as Content-Type: application/json",
                parts.method,
                parts.uri.path()
            ),
        ));
    }
    let bytes = tokio::time::timeout(BODY_TIMEOUT, axum::body::to_bytes(body, MAX_BODY))
        .await
        .map_err(|_| {
            ApiError(
                StatusCode::REQUEST_TIMEOUT,
                format!(
                    "the request's body did not arrive within {} s",
                    BODY_TIMEOUT.as_secs()
                ),
            )
        })?
        .map_err(|e| {
            ApiError(
                StatusCode::PAYLOAD_TOO_LARGE,
                format!("the request's body could not be read whole within {MAX_BODY} bytes: {e}"),
            )
        })?;
    Ok(Request::from_parts(parts, Body::from(bytes)))
}

/// True when the request's `Host` names a loopback host.
fn loopback_host(headers: &HeaderMap) -> bool {
    let Some(host) = headers.get(header::HOST).and_then(|h| h.to_str().ok()) else {
        return false;
    };
    let name = match host.rsplit_once(':') {
        Some((name, port)) if port.bytes().all(|b| b.is_ascii_digit()) => name,
        _ => host,
    };
    let name = name.trim_start_matches('[').trim_end_matches(']');
    name.eq_ignore_ascii_case("localhost")
        || name.parse::<IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

/// Equality in time independent of where the bytes differ.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

async fn info(State(app): State<Arc<App>>) -> ApiResult<axum::Json<Value>> {
    let subject = lock(&app.subject)?;
    let (forward, turn_deg, look_deg) = match app.config.actions {
        sage_env::ActionSpace::Discrete {
            forward,
            turn_deg,
            look_deg,
            ..
        } => (forward, turn_deg, look_deg),
        _ => (0.0, 0.0, 0.0),
    };
    let play = match &*subject {
        Subject::Play { run } => json!({
            "folder": run.folder(),
            "played": run.played(),
            "total": run.episodes().len(),
            "mode": run.settings().mode,
            "size": app.play_config.as_ref().map(|c| [c.sensors.width, c.sensors.height]),
        }),
        _ => Value::Null,
    };
    Ok(axum::Json(json!({
        "title": app.title,
        "kind": subject.kind(),
        "scenes": app.scenes.names(),
        "episodes": episode_list(&subject),
        "preset": {
            "forward": forward,
            "turn_deg": turn_deg,
            "look_deg": look_deg,
            "hfov_deg": app.config.sensors.hfov_deg,
            "max_steps": app.config.task.max_steps,
            "success_distance": app.config.task.success_distance,
            "splat_bodies": app.config.splat_bodies,
        },
        "play": play,
    })))
}

async fn map(
    State(app): State<Arc<App>>,
    Path(scene): Path<String>,
) -> ApiResult<axum::Json<Value>> {
    let loaded = load(app, scene).await?;
    Ok(axum::Json(loaded.map.clone()))
}

async fn map_png(State(app): State<Arc<App>>, Path(scene): Path<String>) -> ApiResult<Response> {
    let loaded = load(app, scene).await?;
    Ok(image("image/png", loaded.map_png.clone()))
}

/// Scene `scene` on the bodies of the environment explored in, loaded off the async threads.
async fn load(app: Arc<App>, scene: String) -> ApiResult<Arc<crate::scenes::LoadedScene>> {
    if !app.scenes.contains(&scene) {
        return Err(not_found(format!("no scene '{scene}' here")));
    }
    blocking(move || Ok(app.scenes.get(&scene, app.config.splat_bodies)?)).await
}

/// Waits for a render's turn: held until the render ends, even when its client has gone.
async fn render_turn(app: &App) -> ApiResult<tokio::sync::OwnedSemaphorePermit> {
    app.renders
        .clone()
        .acquire_owned()
        .await
        .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))
}

fn image(content_type: &'static str, bytes: Vec<u8>) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::CACHE_CONTROL, "no-store"),
        ],
        Body::from(bytes),
    )
        .into_response()
}

async fn frame(
    State(app): State<Arc<App>>,
    Path(scene): Path<String>,
    Query(req): Query<FrameRequest>,
) -> ApiResult<Response> {
    let loaded = load(app.clone(), scene.clone()).await?;
    let dir = app.scenes.dir(&scene).map(|d| d.display().to_string());
    let turn = render_turn(&app).await?;
    let (bytes, command) = blocking(move || {
        let _turn = turn;
        let bytes = frame::render(&loaded, &app.config, &app.profile, &req)?;
        let command =
            frame::render_command(&dir.unwrap_or(scene), &app.config, &app.profile, &req)?;
        Ok((bytes, command))
    })
    .await?;
    let mut response = image(req.format.content_type(), bytes);
    // The same image from the command line, for a figure or a bug report.
    if let Ok(value) = header::HeaderValue::from_str(&command) {
        response.headers_mut().insert("x-sage3d-render", value);
    }
    Ok(response)
}

/// What opens a session.
#[derive(Deserialize)]
struct OpenSession {
    /// The scene to explore (default: the episode's, else the first).
    scene: Option<String>,
    /// The episode to explore from or play.
    episode: Option<String>,
    /// Play the episode (human play) rather than explore from its start.
    #[serde(default)]
    play: bool,
    /// The person chose to see the map from the start.
    #[serde(default)]
    map_shown: bool,
}

async fn open_session(
    State(app): State<Arc<App>>,
    axum::Json(req): axum::Json<OpenSession>,
) -> ApiResult<axum::Json<Value>> {
    blocking(move || {
        let (scene, episode) = session_episode(&app, &req)?;
        let (config, purpose) = if req.play {
            let config = app
                .play_config
                .as_ref()
                .ok_or_else(|| Error::invalid("this viewer has no human play (`play`)"))?;
            let purpose = Purpose::Play {
                map_shown: req.map_shown,
            };
            (config, purpose)
        } else {
            (&app.config, Purpose::Explore)
        };
        // Loaded with the bodies the session's environment asks for: it refuses others.
        let loaded = app.scenes.get(&scene, config.splat_bodies)?;
        let episode = match episode {
            Some(e) => e,
            None => session::explore_episode(session::default_start(&loaded)?, 0.0),
        };
        let session = Session::start(&scene, loaded, config, episode, purpose)?;
        let mut sessions = lock(&app.sessions)?;
        let id = sessions.insert(session);
        Ok(axum::Json(sessions.get_mut(id)?.state(id)))
    })
    .await
}

/// The scene and the environment episode a session request names: a play request needs an
/// episode of the human run not yet played; an explore request may name an episode (its start
/// and goal; in human play only one already played) or a scene.
fn session_episode(
    app: &App,
    req: &OpenSession,
) -> ApiResult<(String, Option<sage_env::EnvEpisode>)> {
    let subject = lock(&app.subject)?;
    let Some(id) = &req.episode else {
        if req.play {
            return Err(Error::invalid("play: name the episode to play").into());
        }
        let scene = match &req.scene {
            Some(s) if app.scenes.contains(s) => s.clone(),
            Some(s) => return Err(not_found(format!("no scene '{s}' here"))),
            None => app.scenes.names().into_iter().next().unwrap_or_default(),
        };
        return Ok((scene, None));
    };
    let unknown = || not_found(format!("no episode '{id}' here"));
    match &*subject {
        Subject::Play { run } => {
            let e = run.episode(id).ok_or_else(unknown)?;
            let played = run.recorded(id).is_some();
            if req.play && played {
                return Err(Error::invalid(format!(
                    "episode {id} is already played and recorded in this run"
                ))
                .into());
            }
            // Exploring shows the goal, the reference path and the distance to the goal: of
            // an episode still to play, that would be playing it with the answer, unnoted.
            if !req.play && !played {
                return Err(ApiError(
                    StatusCode::FORBIDDEN,
                    format!(
                        "episode {id} is not played yet: play it (`play: true`) before exploring it"
                    ),
                ));
            }
            Ok((e.scene.clone(), Some(e.env_episode())))
        }
        _ if req.play => Err(Error::invalid("this viewer has no human play (`play`)").into()),
        Subject::Dataset { episodes, .. } => {
            let e = episodes
                .iter()
                .find(|e| &e.episode_id == id)
                .ok_or_else(unknown)?;
            Ok((e.scene.clone(), Some(e.env_episode())))
        }
        Subject::Run { records, .. } => {
            let r = records
                .iter()
                .find(|r| &r.episode_id == id)
                .ok_or_else(unknown)?;
            let rec = r.record.as_ref().ok_or_else(|| {
                Error::invalid(format!(
                    "episode {id} faulted: there is no start to explore from"
                ))
            })?;
            let start = glam::Vec3::from_array(rec.start);
            Ok((
                r.scene.clone(),
                Some(session::explore_episode(start, rec.start_yaw)),
            ))
        }
        Subject::Scenes => Err(unknown()),
    }
}

/// A step request.
#[derive(Deserialize)]
struct StepRequest {
    action: String,
}

async fn step(
    State(app): State<Arc<App>>,
    Path(id): Path<u64>,
    axum::Json(req): axum::Json<StepRequest>,
) -> ApiResult<axum::Json<Value>> {
    blocking(move || {
        let action = session::parse_action(&req.action)?;
        let mut sessions = lock(&app.sessions)?;
        let s = sessions.get_mut(id).map_err(|e| not_found(e.to_string()))?;
        s.step(action)?;
        let mut state = s.state(id);
        if let (Purpose::Play { map_shown }, true) = (s.purpose, s.env().done()) {
            let trace = s.env().trace().expect("a started episode").clone();
            let ctx = s.loaded().ctx.clone();
            drop(sessions);
            let notes = if map_shown {
                vec![sage_eval::human::NOTE_MAP_SHOWN.to_string()]
            } else {
                Vec::new()
            };
            let mut subject = lock(&app.subject)?;
            let Subject::Play { run } = &mut *subject else {
                return Err(Error::invalid("a play session outside human play").into());
            };
            let rec = run.record(&ctx, &trace.episode.id, &trace, notes)?;
            state["record"] = episode_detail(&rec, Some(&trace.episode.instruction));
            state["played"] = json!(run.played());
        }
        Ok(axum::Json(state))
    })
    .await
}

/// A place request.
#[derive(Deserialize)]
struct PlaceRequest {
    x: f32,
    y: f32,
    #[serde(default)]
    yaw: f32,
}

async fn place(
    State(app): State<Arc<App>>,
    Path(id): Path<u64>,
    axum::Json(req): axum::Json<PlaceRequest>,
) -> ApiResult<axum::Json<Value>> {
    blocking(move || {
        let mut sessions = lock(&app.sessions)?;
        let s = sessions.get_mut(id).map_err(|e| not_found(e.to_string()))?;
        s.place(req.x, req.y, req.yaw)?;
        Ok(axum::Json(s.state(id)))
    })
    .await
}

async fn map_shown(
    State(app): State<Arc<App>>,
    Path(id): Path<u64>,
) -> ApiResult<axum::Json<Value>> {
    let mut sessions = lock(&app.sessions)?;
    let s = sessions.get_mut(id).map_err(|e| not_found(e.to_string()))?;
    if let Purpose::Play { map_shown } = &mut s.purpose {
        *map_shown = true;
    }
    Ok(axum::Json(s.state(id)))
}

async fn episode(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
) -> ApiResult<axum::Json<Value>> {
    let subject = lock(&app.subject)?;
    let (r, instruction) = recorded(&subject, &id)?;
    Ok(axum::Json(episode_detail(&r, instruction.as_deref())))
}

/// The record of episode `id` of a run or human run, with its instruction.
fn recorded(subject: &Subject, id: &str) -> ApiResult<(EvalRecord, Option<String>)> {
    let unknown = || not_found(format!("no recorded episode '{id}' here"));
    match subject {
        Subject::Run {
            records,
            instructions,
            ..
        } => {
            let r = records
                .iter()
                .find(|r| r.episode_id == id)
                .ok_or_else(unknown)?;
            Ok((r.clone(), instructions.get(id).cloned()))
        }
        Subject::Play { run } => {
            let r = run.recorded(id).ok_or_else(unknown)?;
            Ok((r.clone(), run.episode(id).map(|e| e.instruction.clone())))
        }
        _ => Err(unknown()),
    }
}

async fn video(State(app): State<Arc<App>>, Path(id): Path<String>) -> ApiResult<Response> {
    let (rec, instruction) = recorded(&*lock(&app.subject)?, &id)?;
    let loaded = load(app.clone(), rec.scene.clone()).await?;
    let key = id.clone();
    // Not a render turn: animations are made one at a time by the cache, beside frames.
    let gif = blocking(move || {
        let ctx = &loaded.ctx;
        Ok(app.videos.get(&key, || {
            sage_eval::report::video::episode_gif(
                ctx,
                &app.config,
                &ctx.semantic,
                &ctx.pathfinder.grid,
                &rec,
                instruction.as_deref().unwrap_or_default(),
                sage_eval::report::video::VideoSize::default(),
            )
        })?)
    })
    .await?;
    let mut response = image("image/gif", gif.to_vec());
    if let Ok(value) = header::HeaderValue::from_str(&format!(
        "attachment; filename=\"{}.gif\"",
        sage_io::names::stem(&id)
    )) {
        response
            .headers_mut()
            .insert(header::CONTENT_DISPOSITION, value);
    }
    Ok(response)
}
