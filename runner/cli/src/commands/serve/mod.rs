//! `runner serve`: the lab in the browser. A small HTTP server (synchronous, a few threads) that
//! serves one page (HTML, JavaScript and the bundled uPlot, nothing from elsewhere) and a JSON API
//! over the models named at start: their variables, runs, animations, sweeps, and downloads. Every
//! run goes to worker processes, so a bad FMU costs its request, never the server.
//!
//! Safety: it listens on 127.0.0.1 unless `--host` says otherwise; it serves only the FMUs named
//! at start (no upload, no path from the client); request bodies, samples per run and points per
//! sweep are limited; and a request from another web page (an `Origin` or `Host` that is not
//! this server's) is refused, so no other page can drive it.

mod lab;

use std::io::Read;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::Scope;
use std::time::{Duration, Instant};

use serde_json::{json, Value as Json};
use tiny_http::{Header, Method, Request, Response, Server};

use crate::interrupt;
use crate::workers;
use lab::{Model, RunBody, Served, SweepBody, SweepJob};

/// Options of `runner serve`.
pub struct Options {
    /// Model names or `.fmu` paths (empty: every model of the workspace).
    pub fmus: Vec<String>,
    /// The address to listen on (default 127.0.0.1).
    pub host: Option<String>,
    /// The port (0: any free port).
    pub port: u16,
    /// Each run or sweep point fails after this many seconds.
    pub point_timeout: Option<f64>,
    /// Most points a sweep may have.
    pub max_points: usize,
    /// Worker processes of a sweep.
    pub threads: Option<usize>,
}

/// Largest request body read (a run request is a few hundred bytes).
const MAX_BODY: usize = 64 * 1024;
/// Threads answering requests (a run waits for its worker, so more than the cores).
const HANDLERS: usize = 4;
/// Sweeps kept for polling and download after they finish.
const KEPT_SWEEPS: usize = 16;
/// A run of the server's stops after this unless `--point-timeout` says otherwise.
pub const DEFAULT_TIMEOUT: f64 = 60.0;

/// The page and its scripts, embedded: the server needs no files and works offline.
const ASSETS: &[(&str, &str, &str)] = &[
    ("/", "text/html; charset=utf-8", include_str!("../../../assets/serve/index.html")),
    ("/app.js", "text/javascript; charset=utf-8", include_str!("../../../assets/serve/app.js")),
    ("/app.css", "text/css; charset=utf-8", include_str!("../../../assets/serve/app.css")),
    ("/uplot/uPlot.iife.min.js", "text/javascript; charset=utf-8", include_str!("../../../assets/serve/uplot/uPlot.iife.min.js")),
    ("/uplot/uPlot.min.css", "text/css; charset=utf-8", include_str!("../../../assets/serve/uplot/uPlot.min.css")),
    ("/uplot/LICENSE", "text/plain; charset=utf-8", include_str!("../../../assets/serve/uplot/LICENSE")),
];

/// An answer that is not a success: its status and what is wrong.
#[derive(Debug)]
struct Refusal {
    status: u16,
    message: String,
}

fn refuse(status: u16, message: impl Into<String>) -> Refusal {
    Refusal { status, message: message.into() }
}

/// A bad request naming the problem (what the engine said of a name, a value or a grid).
fn bad(message: String) -> Refusal {
    refuse(400, message)
}

/// What a request is answered with.
enum Answer {
    Json(u16, Json),
    Bytes { content_type: &'static str, body: Vec<u8>, file_name: Option<String> },
    Asset(&'static str, &'static str),
}

/// The running server: its models, the sweeps, and who may call it.
struct App<'a> {
    served: Vec<Served<'a>>,
    /// The `Host` values of this server that a request may name (empty: any, with `--host`).
    hosts: Vec<String>,
    options: &'a Options,
    config: runner_sandbox::Config,
    sweeps: Mutex<Vec<(u64, Arc<SweepJob>)>>,
    next_job: AtomicU64,
}

/// Runs `runner serve` until Ctrl-C.
pub fn run(options: &Options) -> Result<(), String> {
    let names = match options.fmus.is_empty() {
        true => runner_workspace::models(&runner_workspace::root())?,
        false => options.fmus.clone(),
    };
    if options.max_points == 0 {
        return Err("--max-points must be at least 1".to_owned());
    }
    if options.threads == Some(0) {
        return Err("--threads must be at least 1".to_owned());
    }
    let timeout = runner_sandbox::timeout("--point-timeout", Some(options.point_timeout.unwrap_or(DEFAULT_TIMEOUT)))?;
    let mut models: Vec<Model> = Vec::new();
    for name in &names {
        let mut model = Model::open(name)?;
        // Two files of one name: the later one gets a suffix.
        let stem = model.id.clone();
        let mut k = 1;
        while models.iter().any(|m| m.id == model.id) {
            k += 1;
            model.id = format!("{stem}-{k}");
        }
        models.push(model);
    }
    let threads = options.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let config = workers::isolation(timeout, runner_sandbox::default_memory_mib(threads + HANDLERS))?;
    let host = options.host.clone().unwrap_or_else(|| "127.0.0.1".to_owned());
    let server = Server::http((host.as_str(), options.port)).map_err(|e| format!("cannot listen on {host}:{}: {e}", options.port))?;
    let port = server.server_addr().to_ip().map(|a| a.port()).ok_or_else(|| "the server has no IP address".to_owned())?;
    let shown_host = if host.contains(':') { format!("[{host}]") } else { host.clone() };
    let hosts = match &options.host {
        None => ["127.0.0.1", "localhost", "[::1]"].iter().map(|h| format!("{h}:{port}")).collect(),
        Some(_) => Vec::new(),
    };
    if options.host.is_some() {
        eprintln!(
            "warning: listening on {shown_host}:{port} (--host): anyone who can reach this address can run the served FMUs on this machine"
        );
    }
    let app = App {
        served: models.iter().map(|m| Served::new(m, config.clone())).collect(),
        hosts,
        options,
        config,
        sweeps: Mutex::new(Vec::new()),
        next_job: AtomicU64::new(1),
    };
    println!("runner serve: {} model(s) at http://{shown_host}:{port}/ (Ctrl-C to stop)", models.len());
    use std::io::Write;
    let _ = std::io::stdout().flush();
    std::thread::scope(|scope| {
        for _ in 0..HANDLERS {
            scope.spawn(|| app.answer_requests(&server, scope));
        }
    });
    eprintln!("runner serve: stopped");
    Ok(())
}

impl<'a> App<'a> {
    /// Answers requests until Ctrl-C.
    fn answer_requests<'s>(&'s self, server: &'s Server, scope: &'s Scope<'s, '_>) {
        while !interrupt::requested() {
            let request = match server.recv_timeout(Duration::from_millis(200)) {
                Ok(Some(request)) => request,
                Ok(None) => continue,
                Err(e) => {
                    eprintln!("runner serve: {e}");
                    continue;
                }
            };
            self.answer(request, scope);
        }
    }

    fn answer<'s>(&'s self, mut request: Request, scope: &'s Scope<'s, '_>) {
        let clock = Instant::now();
        let answer = self.route(&mut request, scope);
        let mut response = match answer {
            Ok(Answer::Json(status, body)) => json_response(status, &body),
            Ok(Answer::Bytes { content_type, body, file_name }) => {
                let mut r = Response::from_data(body).with_header(header("Content-Type", content_type));
                if let Some(name) = file_name {
                    r = r.with_header(header("Content-Disposition", &format!("attachment; filename=\"{name}\"")));
                }
                r
            }
            Ok(Answer::Asset(content_type, text)) => {
                Response::from_data(text.as_bytes().to_vec()).with_header(header("Content-Type", content_type))
            }
            Err(refusal) => {
                let mut r = json_response(refusal.status, &json!({ "error": refusal.message, "status": refusal.status }));
                if refusal.status == 405 {
                    r = r.with_header(header("Allow", if request.url().starts_with("/api/sweeps/") { "GET, DELETE" } else { "GET, POST" }));
                }
                r
            }
        };
        response = response
            .with_header(header("Cache-Control", "no-store"))
            .with_header(header("X-Content-Type-Options", "nosniff"))
            .with_header(header("X-Frame-Options", "DENY"))
            .with_header(header(
                "Content-Security-Policy",
                "default-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; frame-ancestors 'none'",
            ))
            .with_header(header("Server-Timing", &format!("total;dur={:.3}", clock.elapsed().as_secs_f64() * 1e3)));
        // A client that went away is no error of the server's.
        let _ = request.respond(response);
    }

    /// Checks that the request comes from this server's own page (or from a program that is no
    /// browser page), then answers it.
    fn route<'s>(&'s self, request: &mut Request, scope: &'s Scope<'s, '_>) -> Result<Answer, Refusal> {
        self.check_origin(request)?;
        let url = request.url().to_owned();
        let (path, query) = url.split_once('?').unwrap_or((&url, ""));
        let method = request.method().clone();
        let parts: Vec<&str> = path.trim_start_matches('/').split('/').collect();
        let get = method == Method::Get || method == Method::Head;
        match (parts.as_slice(), get) {
            (["api", "models"], true) => Ok(Answer::Json(200, Json::Array(self.served.iter().map(|s| s.model.summary()).collect()))),
            (["api", "models", id], true) => self.model(id)?.model.details().map(|d| Answer::Json(200, d)).map_err(bad),
            (["api", "models", id, "fmu"], true) => {
                let model = self.model(id)?.model;
                let body = std::fs::read(&model.path).map_err(|e| refuse(500, format!("cannot read {}: {e}", model.path.display())))?;
                Ok(Answer::Bytes { content_type: "application/octet-stream", body, file_name: Some(format!("{}.fmu", model.id)) })
            }
            (["api", "models", id, "simulate"], false) if method == Method::Post => {
                let served = self.model(id)?;
                let body: RunBody = read_json(request)?;
                self.simulate(served, &body)
            }
            (["api", "models", id, "scene"], false) if method == Method::Post => {
                let served = self.model(id)?;
                let body: RunBody = read_json(request)?;
                match served.scene(&body, &interrupt::requested).map_err(bad)? {
                    Some(scene) => Ok(Answer::Json(200, scene)),
                    None => Err(refuse(
                        404,
                        format!("{} has no animation: it outputs no point coordinates and has no [animate] scene", served.model.id),
                    )),
                }
            }
            (["api", "models", id, "sweep"], false) if method == Method::Post => {
                let served = self.model(id)?;
                let body: SweepBody = read_json(request)?;
                self.start_sweep(served, &body, scope)
            }
            (["api", "sweeps", job], true) => {
                let from = query.split('&').find_map(|kv| kv.strip_prefix("from=")).map(|v| v.parse::<usize>()).transpose();
                let from = from.map_err(|_| refuse(400, "from must be a row number"))?.unwrap_or(0);
                Ok(Answer::Json(200, self.job(job)?.report(from)))
            }
            (["api", "sweeps", job, "csv"], true) => {
                let job_ref = self.job(job)?;
                let body = job_ref.csv().map_err(|e| refuse(500, e))?;
                Ok(Answer::Bytes { content_type: "text/csv; charset=utf-8", body, file_name: Some(format!("{}_sweep.csv", job_ref.model)) })
            }
            (["api", "sweeps", job], false) if method == Method::Delete => {
                let job = self.job(job)?;
                job.cancel.store(true, Ordering::Relaxed);
                Ok(Answer::Json(200, json!({ "cancelled": true })))
            }
            (["api", "models", _, "simulate" | "scene" | "sweep"], true) => Err(refuse(405, format!("{path} takes POST with a JSON body"))),
            (["api", "models", ..], false) | (["api", "sweeps", ..], false) => {
                Err(refuse(405, format!("{method} is not allowed on {path}")))
            }
            (_, true) => match ASSETS.iter().find(|(p, _, _)| *p == path || (*p == "/" && path == "/index.html")) {
                Some((_, content_type, text)) => Ok(Answer::Asset(content_type, text)),
                None => Err(refuse(404, format!("nothing at {path}"))),
            },
            (_, false) => Err(refuse(405, format!("{method} is not allowed on {path}"))),
        }
    }

    /// Refuses a request a browser sent from another origin: its `Origin` (or `Sec-Fetch-Site`)
    /// says another site, or its `Host` is not this server's (a DNS name rebound to 127.0.0.1).
    fn check_origin(&self, request: &Request) -> Result<(), Refusal> {
        let value = |name: &'static str| request.headers().iter().find(|h| h.field.equiv(name)).map(|h| h.value.as_str().to_owned());
        let host = value("Host").unwrap_or_default();
        if !self.hosts.is_empty() && !self.hosts.iter().any(|h| h.eq_ignore_ascii_case(&host)) {
            return Err(refuse(
                403,
                format!("the Host '{host}' is not this server's: requests must address it as {}", self.hosts.join(" or ")),
            ));
        }
        if let Some(origin) = value("Origin") {
            if !origin.eq_ignore_ascii_case(&format!("http://{host}")) {
                return Err(refuse(
                    403,
                    format!("a request from the page of another origin ({origin}) is refused: only this server's own page may call it"),
                ));
            }
        }
        if value("Sec-Fetch-Site").is_some_and(|s| s.eq_ignore_ascii_case("cross-site")) {
            return Err(refuse(403, "a cross-site request is refused: only this server's own page may call it"));
        }
        Ok(())
    }

    fn model(&self, id: &str) -> Result<&Served<'a>, Refusal> {
        self.served.iter().find(|s| s.model.id == id).ok_or_else(|| {
            let ids: Vec<&str> = self.served.iter().map(|s| s.model.id.as_str()).collect();
            refuse(404, format!("no model '{id}' is served here (served: {})", ids.join(", ")))
        })
    }

    fn job(&self, id: &str) -> Result<Arc<SweepJob>, Refusal> {
        let number: u64 = id.parse().map_err(|_| refuse(404, format!("no sweep '{id}'")))?;
        let sweeps = self.sweeps.lock().map_err(|_| refuse(500, "the sweeps' record broke"))?;
        sweeps
            .iter()
            .find(|(n, _)| *n == number)
            .map(|(_, j)| j.clone())
            .ok_or_else(|| refuse(404, format!("no sweep {number} (finished sweeps are kept for the last {KEPT_SWEEPS})")))
    }

    fn simulate(&self, served: &Served, body: &RunBody) -> Result<Answer, Refusal> {
        let recorded = served.simulate(body, &interrupt::requested).map_err(bad)?;
        if let Some(csv) = recorded.csv {
            return Ok(Answer::Bytes {
                content_type: "text/csv; charset=utf-8",
                body: csv,
                file_name: Some(format!("{}.csv", served.model.id)),
            });
        }
        let trace = &recorded.trace;
        let grid = &recorded.grid;
        // Written straight from the trace's columns (no JSON tree of a million numbers): a run
        // of the quarter car has 10,001 samples of a dozen variables.
        let chosen: Vec<usize> =
            match &body.variables {
                None => (0..trace.names.len()).collect(),
                Some(names) => names
                    .iter()
                    .map(|n| {
                        trace.names.iter().position(|r| r == n).ok_or_else(|| {
                            bad(format!("variables: '{n}' is not recorded (the recorded columns: {})", trace.names.join(", ")))
                        })
                    })
                    .collect::<Result<_, _>>()?,
            };
        let names: Vec<&String> = chosen.iter().map(|&k| &trace.names[k]).collect();
        let columns: Vec<&Vec<f64>> = chosen.iter().map(|&k| &trace.columns[k]).collect();
        let answer = RunAnswer {
            model: &served.model.id,
            recorded: &trace.names,
            outputs: recorded.outputs,
            names,
            time: &trace.time,
            columns,
            events: recorded.events.iter().map(|e| json!({ "time": e.time, "index": e.index, "text": e.text })).collect(),
            ended_early: trace.ended_early.as_deref(),
            grid: json!({ "start": grid.start, "stop": grid.stop, "interval": grid.interval, "tolerance": grid.tolerance }),
            run_ms: recorded.run_ms,
        };
        let body = serde_json::to_vec(&answer).map_err(|e| refuse(500, format!("cannot write JSON: {e}")))?;
        Ok(Answer::Bytes { content_type: "application/json", body, file_name: None })
    }

    /// Starts a sweep in the background (one at a time: the machine's cores are its workers).
    fn start_sweep<'s>(&'s self, served: &'s Served<'a>, body: &SweepBody, scope: &'s Scope<'s, '_>) -> Result<Answer, Refusal> {
        let (prepared, job) = lab::prepare_sweep(served.model, body, self.options.max_points).map_err(bad)?;
        let job = Arc::new(job);
        let number = self.next_job.fetch_add(1, Ordering::Relaxed);
        {
            let mut sweeps = self.sweeps.lock().map_err(|_| refuse(500, "the sweeps' record broke"))?;
            let running = |j: &SweepJob| !j.state.lock().map(|s| s.finished).unwrap_or(true);
            if let Some((n, j)) = sweeps.iter().find(|(_, j)| running(j)) {
                return Err(refuse(
                    429,
                    format!("sweep {n} of {} is still running: wait for it or cancel it (DELETE /api/sweeps/{n})", j.model),
                ));
            }
            sweeps.push((number, job.clone()));
            let excess = sweeps.len().saturating_sub(KEPT_SWEEPS);
            sweeps.drain(..excess);
        }
        let threads = self.options.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
        let running = job.clone();
        scope.spawn(move || prepared.run(&running, &self.config, threads, &interrupt::requested));
        Ok(Answer::Json(202, json!({ "job": number, "total": job.total, "params": job.params, "metrics": job.metrics })))
    }
}

/// A run as the API answers it (numbers in SI; NaN as null).
#[derive(serde::Serialize)]
struct RunAnswer<'r> {
    model: &'r str,
    /// Every recorded column's name; the first `outputs` are the CSV's.
    recorded: &'r [String],
    outputs: usize,
    /// The columns answered (the request's `variables`, else all).
    names: Vec<&'r String>,
    time: &'r [f64],
    columns: Vec<&'r Vec<f64>>,
    events: Vec<Json>,
    ended_early: Option<&'r str>,
    grid: Json,
    run_ms: f64,
}

fn header(name: &str, value: &str) -> Header {
    Header::from_bytes(name.as_bytes(), value.as_bytes()).expect("header names and values are ASCII")
}

fn json_response(status: u16, body: &Json) -> Response<std::io::Cursor<Vec<u8>>> {
    let bytes = serde_json::to_vec(body).unwrap_or_else(|e| format!("{{\"error\":\"cannot write JSON: {e}\"}}").into_bytes());
    Response::from_data(bytes).with_status_code(status).with_header(header("Content-Type", "application/json"))
}

/// The request's JSON body: at most [`MAX_BODY`] bytes, sent as `application/json` (which a
/// page of another origin cannot send without asking first).
fn read_json<T: serde::de::DeserializeOwned>(request: &mut Request) -> Result<T, Refusal> {
    let content_type = request.headers().iter().find(|h| h.field.equiv("Content-Type")).map(|h| h.value.as_str().to_owned());
    if !content_type.as_deref().is_some_and(|t| t.split(';').next().is_some_and(|m| m.trim().eq_ignore_ascii_case("application/json"))) {
        return Err(refuse(415, "send the request body as JSON (Content-Type: application/json)"));
    }
    if request.body_length().is_some_and(|n| n > MAX_BODY) {
        return Err(refuse(413, format!("the request body has more than the {MAX_BODY} bytes a request may have")));
    }
    let mut bytes = Vec::new();
    request
        .as_reader()
        .take(MAX_BODY as u64 + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| refuse(400, format!("cannot read the request body: {e}")))?;
    if bytes.len() > MAX_BODY {
        return Err(refuse(413, format!("the request body has more than the {MAX_BODY} bytes a request may have")));
    }
    let text = if bytes.iter().all(|b| b.is_ascii_whitespace()) { b"{}".as_slice() } else { &bytes };
    serde_json::from_slice(text).map_err(|e| refuse(400, format!("the request body is not the JSON expected: {e}")))
}
