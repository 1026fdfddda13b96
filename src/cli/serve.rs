//! `primflow serve [SCENE]`: a live preview in the browser. The page shows the render, the
//! depth buffer or any shading parameter, the diagnostics at their `file:line:col`, the
//! check, kernel compile and render times, and a click on a pixel prints its `primflow
//! trace`; the scene and its `.prim` files can be edited in the page and saved back.
//!
//! Three kinds of thread: the render thread ([`preview`]) renders whenever a source changes
//! (the watch `primflow watch` uses, [`super::sources`]) or the page saves one; one thread
//! per HTTP request reads what it last published; this (the command's) thread only prints
//! their log lines, so that everything still goes through `out` and `err`.
//!
//! Routes (all answers `Cache-Control: no-store`):
//! - `GET /`: the page (`serve/page.html`, compiled in; it fetches nothing else from anywhere
//!   but this server).
//! - `GET /state`: JSON: `generation` (one per finished render attempt), `status` (`ok`,
//!   `errors`, `missing`, `stopped`, `rendering`), `message`, `diagnostics`, `timings`,
//!   `changed`, `shown` (the frame on show: its generation, size and shading parameters)
//!   and `files` (the sources the page may edit).
//! - `GET /image.png`, `/depth.png` (16-bit gray, nearer brighter), `/param.png?name=P`: the
//!   frame on show as `render`, `render --depth` and `render --param` write it.
//! - `GET /trace?x=X&y=Y`: `primflow trace`'s output for that pixel of the frame on show.
//! - `GET /file?path=P` and `POST /file?path=P` (the body is the new text): read or save a
//!   source; a path outside the scene's and the primitive directories is refused with 403
//!   ([`files`]).
//!
//! The server listens on 127.0.0.1 unless `--bind` says otherwise; with `--port 0` the system
//! picks a free port. The first line printed is `serving http://ADDRESS:PORT/`.

use std::io::{Cursor, Read, Write};
use std::net::IpAddr;
use std::path::PathBuf;
use std::sync::{mpsc, Arc};

use serde_json::json;
use tiny_http::{Header, Method, Request, Response};

use super::sources::{Notifier, SourceWatch};

mod files;
mod preview;

use preview::Preview;

/// The page, with its script and style inline.
const PAGE: &str = include_str!("serve/page.html");

/// The largest source the page may save, in bytes.
const MAX_SOURCE: usize = 4 << 20;

#[derive(clap::Args, Debug)]
pub struct ServeArgs {
    /// The scene file. When it does not exist the page says so, and saving it from the
    /// page creates it.
    #[arg(default_value = "scene.scene")]
    pub scene: PathBuf,
    /// Extra directory of .prim files (repeatable).
    #[arg(long = "prims", value_name = "DIR")]
    pub prims: Vec<PathBuf>,
    /// The port (0: any free one; the address is printed).
    #[arg(long, default_value_t = 8000)]
    pub port: u16,
    /// The address to listen on. The default serves this machine only; `0.0.0.0` serves
    /// every network the machine is on, and anyone there can then read and save the
    /// scene's sources.
    #[arg(long, value_name = "ADDRESS", default_value = "127.0.0.1")]
    pub bind: IpAddr,
    /// Worker threads for the tiles (default: one per core), as `render --threads`.
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
}

/// A line for the command's `out` or `err`, from another thread.
pub(super) enum Log {
    Out(String),
    Err(String),
}

/// What the HTTP threads share.
struct Server {
    preview: Arc<Preview>,
    scene: PathBuf,
    prims: Vec<PathBuf>,
    notifier: Notifier,
}

pub(super) fn serve(args: &ServeArgs, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    let watch = match SourceWatch::new() {
        Ok(w) => w,
        Err(e) => {
            let _ = writeln!(err, "error: {e}");
            return 1;
        }
    };
    let http = match tiny_http::Server::http((args.bind, args.port)) {
        Ok(s) => s,
        Err(e) => {
            let _ = writeln!(err, "error: cannot listen on {}:{}: {e}", args.bind, args.port);
            return 1;
        }
    };
    let address = match http.server_addr().to_ip() {
        Some(a) => a.to_string(),
        None => format!("{}:{}", args.bind, args.port),
    };
    let _ = writeln!(out, "serving http://{address}/");
    let _ = out.flush();
    let preview = Arc::new(Preview::default());
    let server = Arc::new(Server {
        preview: preview.clone(),
        scene: args.scene.clone(),
        prims: args.prims.clone(),
        notifier: watch.notifier(),
    });
    let (log, lines) = mpsc::channel();
    let (scene, prims, threads) = (args.scene.clone(), args.prims.clone(), args.threads.unwrap_or(0));
    let render_log = log.clone();
    let started = std::thread::Builder::new()
        .name("primflow-render".into())
        .spawn(move || preview::run(scene, prims, threads, preview, watch, render_log));
    if let Err(e) = started {
        let _ = writeln!(err, "error: cannot start the render thread: {e}");
        return 1;
    }
    let http_log = log;
    let listening = std::thread::Builder::new().name("primflow-http".into()).spawn(move || {
        for request in http.incoming_requests() {
            let server = server.clone();
            let log = http_log.clone();
            if let Err(e) = std::thread::Builder::new().spawn(move || respond(&server, request)) {
                let _ = log.send(Log::Err(format!("warning: cannot answer a request: {e}")));
            }
        }
    });
    if let Err(e) = listening {
        let _ = writeln!(err, "error: cannot start the HTTP thread: {e}");
        return 1;
    }
    // Until both threads have ended: the HTTP thread runs until the process is interrupted.
    for line in lines {
        let _ = match line {
            Log::Out(l) => writeln!(out, "{l}").and_then(|()| out.flush()),
            Log::Err(l) => writeln!(err, "{l}").and_then(|()| err.flush()),
        };
    }
    1
}

/// One answer: status, content type, body.
struct Answer(u16, &'static str, Vec<u8>);

impl Answer {
    fn text(status: u16, text: impl Into<String>) -> Answer {
        Answer(status, "text/plain; charset=utf-8", text.into().into_bytes())
    }
}

fn respond(server: &Server, mut request: Request) {
    let url = request.url().to_string();
    let (path, query) = url.split_once('?').unwrap_or((&url, ""));
    let answer = match (request.method(), path) {
        (Method::Get, "/") => Answer(200, "text/html; charset=utf-8", PAGE.as_bytes().to_vec()),
        (Method::Get, "/state") => {
            let mut state = server.preview.json();
            state["files"] = json!(files::listing(&server.scene, &server.dirs()));
            Answer(200, "application/json", state.to_string().into_bytes())
        }
        (Method::Get, "/image.png" | "/depth.png" | "/param.png") => image(server, path, query),
        (Method::Get, "/trace") => trace(server, query),
        (Method::Get, "/file") => read_source(server, query),
        (Method::Post, "/file") => save_source(server, query, &mut request),
        (Method::Get | Method::Post, _) => Answer::text(404, format!("no such page: {path}")),
        _ => Answer::text(405, "only GET and POST"),
    };
    let Answer(status, content_type, body) = answer;
    let mut response = Response::from_data(body).with_status_code(status);
    for (name, value) in [("Content-Type", content_type), ("Cache-Control", "no-store")] {
        if let Ok(h) = Header::from_bytes(name, value) {
            response = response.with_header(h);
        }
    }
    let _ = request.respond(response);
}

impl Server {
    fn dirs(&self) -> Vec<PathBuf> {
        super::sources::directories(&self.scene, &self.prims)
    }

    fn shown(&self) -> Result<Arc<preview::Shown>, Answer> {
        self.preview
            .snapshot()
            .shown
            .ok_or_else(|| Answer::text(404, "nothing has rendered yet"))
    }
}

fn image(server: &Server, path: &str, query: &str) -> Answer {
    let shown = match server.shown() {
        Ok(s) => s,
        Err(a) => return a,
    };
    let frame = &shown.frame;
    let img = match path {
        "/image.png" => image::DynamicImage::ImageRgb8(frame.to_rgb8()),
        "/depth.png" => image::DynamicImage::ImageLuma16(frame.depth_image()),
        _ => {
            let name = param(query, "name").unwrap_or_default();
            match frame.param_image(&name) {
                Ok(img) => image::DynamicImage::ImageRgb8(img),
                Err(message) => return Answer::text(404, message),
            }
        }
    };
    let mut png = vec![];
    match img.write_to(&mut Cursor::new(&mut png), image::ImageFormat::Png) {
        Ok(()) => Answer(200, "image/png", png),
        Err(e) => Answer::text(500, format!("cannot encode the image: {e}")),
    }
}

fn trace(server: &Server, query: &str) -> Answer {
    let coord = |name| param(query, name).and_then(|v| v.parse::<u32>().ok());
    let (Some(x), Some(y)) = (coord("x"), coord("y")) else {
        return Answer::text(400, "expected /trace?x=X&y=Y, two non-negative integers");
    };
    let shown = match server.shown() {
        Ok(s) => s,
        Err(a) => return a,
    };
    let mut text = vec![];
    let _ = writeln!(text, "primflow trace {} --pixel {x},{y}", server.scene.display());
    match crate::trace::trace(
        &shown.sources,
        &shown.renderer,
        &shown.objects,
        &shown.frame,
        (x, y),
        &mut text,
    ) {
        Ok(_) => Answer(200, "text/plain; charset=utf-8", text),
        Err(message) => Answer::text(400, format!("error: {message}")),
    }
}

fn read_source(server: &Server, query: &str) -> Answer {
    let path = match files::allowed(&param(query, "path").unwrap_or_default(), &server.dirs()) {
        Ok(p) => p,
        Err(why) => return Answer::text(403, format!("refused: {why}")),
    };
    match std::fs::read_to_string(&path) {
        Ok(text) => Answer(200, "text/plain; charset=utf-8", text.into_bytes()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            Answer::text(404, format!("{} does not exist yet", path.display()))
        }
        Err(e) => Answer::text(500, format!("cannot read {}: {e}", path.display())),
    }
}

fn save_source(server: &Server, query: &str, request: &mut Request) -> Answer {
    let path = match files::allowed(&param(query, "path").unwrap_or_default(), &server.dirs()) {
        Ok(p) => p,
        Err(why) => return Answer::text(403, format!("refused: {why}")),
    };
    let mut body = vec![];
    let read = request.as_reader().take(MAX_SOURCE as u64 + 1).read_to_end(&mut body);
    if let Err(e) = read {
        return Answer::text(400, format!("cannot read the request: {e}"));
    }
    if body.len() > MAX_SOURCE {
        return Answer::text(413, format!("a source may have at most {MAX_SOURCE} bytes"));
    }
    let Ok(text) = String::from_utf8(body) else {
        return Answer::text(400, "a source must be UTF-8 text");
    };
    match files::save(&path, &text) {
        Ok(()) => {
            server.notifier.changed(&path);
            Answer::text(200, format!("saved {}", path.display()))
        }
        Err(message) => Answer::text(500, message),
    }
}

/// The value of `name` in a URL query (`a=1&b=x%2Fy`), percent-decoded; `None` when absent
/// or not valid UTF-8 once decoded.
fn param(query: &str, name: &str) -> Option<String> {
    let raw = query
        .split('&')
        .filter_map(|pair| pair.split_once('='))
        .find(|(k, _)| *k == name)?
        .1;
    let bytes = raw.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        match bytes[i] {
            b'%' if i + 2 < bytes.len() => match (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                (Some(h), Some(l)) => {
                    decoded.push((h * 16 + l) as u8);
                    i += 3;
                    continue;
                }
                _ => decoded.push(b'%'),
            },
            b'+' => decoded.push(b' '),
            b => decoded.push(b),
        }
        i += 1;
    }
    String::from_utf8(decoded).ok()
}
