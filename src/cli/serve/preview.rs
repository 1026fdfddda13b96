//! The preview's render thread and the state the page reads: render the scene, publish the
//! outcome as a new generation, wait for a source to change, render again.
//!
//! Invariants:
//! - Only the render thread renders; the HTTP threads read the [`Preview`] under its lock,
//!   which is held only to copy or swap small values (never while rendering, encoding an image
//!   or tracing), so a slow render never blocks the page.
//! - Every finished attempt, successful or not, takes the next generation number (the first
//!   is 1; 0 means none has finished yet) and replaces the diagnostics and timings.
//! - [`State::shown`] is the last attempt that rendered without errors: a failed attempt (a
//!   compile error, a deleted scene) leaves the image, and what a click on it traces, as they
//!   were. A render is attempted whatever the sources hold; no input stops the thread. It
//!   ends only when the file watcher does, and says so in the state.

use std::path::{Path, PathBuf};
use std::sync::{mpsc, Arc, Mutex};
use std::time::Instant;

use serde_json::{json, Value};

use crate::diag::{Diagnostic, Diagnostics, SourceMap};
use crate::jit::Jit;
use crate::runtime::{Frame, Renderer};
use crate::scene::SceneObject;

use super::super::sources::SourceWatch;
use super::Log;

/// What the page reads, shared by the render thread and the HTTP threads.
#[derive(Default)]
pub(super) struct Preview {
    state: Mutex<State>,
}

#[derive(Default, Clone)]
pub(super) struct State {
    pub generation: u64,
    /// `rendering` (before the first attempt), `ok`, `errors`, `missing` or `stopped`.
    pub status: &'static str,
    /// One line for what has no location: the scene is gone, the watcher stopped.
    pub message: Option<String>,
    /// Each diagnostic as JSON ([`diagnostic_json`]).
    pub diagnostics: Vec<Value>,
    /// Milliseconds: `check` (parsing and checking the scene and its primitives), `compile`
    /// (the kernels), `render` (the frame, kernels included), `total` (the attempt).
    pub timings: Option<Value>,
    /// The files whose change started this attempt.
    pub changed: Vec<String>,
    pub shown: Option<Arc<Shown>>,
}

/// A frame rendered without errors, with what tracing one of its pixels needs.
pub(super) struct Shown {
    pub generation: u64,
    pub sources: SourceMap,
    pub renderer: Renderer,
    pub objects: Vec<SceneObject>,
    pub frame: Frame,
}

impl Preview {
    pub(super) fn snapshot(&self) -> State {
        self.state.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    fn publish(&self, update: impl FnOnce(&mut State)) -> u64 {
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        state.generation += 1;
        update(&mut state);
        state.generation
    }

    /// The state as `/state` returns it.
    pub(super) fn json(&self) -> Value {
        let s = self.snapshot();
        let shown = s.shown.as_ref().map(|shown| {
            json!({
                "generation": shown.generation,
                "width": shown.frame.width,
                "height": shown.frame.height,
                "params": shown.frame.params.iter().map(|p| json!({"name": p.name, "components": p.components})).collect::<Vec<_>>(),
            })
        });
        json!({
            "generation": s.generation,
            "status": if s.status.is_empty() { "rendering" } else { s.status },
            "message": s.message,
            "diagnostics": s.diagnostics,
            "timings": s.timings,
            "changed": s.changed,
            "shown": shown,
        })
    }
}

/// The render thread: render, publish, wait for a change, until the watcher stops.
pub(super) fn run(
    scene: PathBuf,
    prims: Vec<PathBuf>,
    threads: usize,
    preview: Arc<Preview>,
    mut watch: SourceWatch,
    log: mpsc::Sender<Log>,
) {
    let pool = crate::runtime::render_pool(threads)
        .map_err(|e| {
            let _ = log.send(Log::Err(format!(
                "warning: cannot start {threads} render threads ({e}); rendering on one"
            )));
        })
        .ok();
    let mut changed: Vec<String> = vec![];
    loop {
        let started = Instant::now();
        // A panic is a bug in primflow, but it ends one attempt, not the preview.
        let attempt = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| attempt(&scene, &prims, pool.as_ref())))
            .unwrap_or_else(|_| Attempt::Failed {
                message: Some("primflow panicked while rendering (a bug: please report it with the scene)".into()),
                diags: Diagnostics::new(),
                sources: SourceMap::new(),
                check_ms: None,
            });
        let total = started.elapsed().as_secs_f64() * 1e3;
        let (line, printed) = publish(&preview, attempt, total, std::mem::take(&mut changed));
        if !printed.is_empty() {
            let _ = log.send(Log::Err(printed));
        }
        let _ = log.send(Log::Out(line));
        for dir in watch.watch_new(&scene, &prims) {
            let _ = log.send(match dir {
                Ok(dir) => Log::Out(format!("watching {}", dir.display())),
                Err(message) => Log::Err(format!("warning: {message}")),
            });
        }
        match watch.next_change() {
            Ok(paths) => {
                changed = paths.iter().map(|p| p.display().to_string()).collect();
                let _ = log.send(Log::Out(format!("changed: {}", changed.join(", "))));
            }
            Err(message) => {
                preview.publish(|s| {
                    s.status = "stopped";
                    s.message = Some(format!("{message}: saved files are no longer rendered"));
                });
                let _ = log.send(Log::Err(format!("error: {message}")));
                return;
            }
        }
    }
}

/// One render of the scene as it is on disk now.
enum Attempt {
    /// The scene file does not exist.
    Missing,
    /// It cannot be read, or has errors: the message or the diagnostics.
    Failed {
        message: Option<String>,
        diags: Diagnostics,
        sources: SourceMap,
        check_ms: Option<f64>,
    },
    Rendered {
        shown: Box<Shown>,
        diags: Diagnostics,
        check_ms: f64,
        compile_ms: f64,
        render_ms: f64,
    },
}

fn attempt(scene: &Path, prims: &[PathBuf], pool: Option<&rayon::ThreadPool>) -> Attempt {
    if !scene.exists() {
        return Attempt::Missing;
    }
    let mut sources = SourceMap::new();
    let file = match crate::scene::read_file(scene) {
        Ok(text) => sources.add_file(scene, text),
        Err(message) => {
            return Attempt::Failed {
                message: Some(message),
                diags: Diagnostics::new(),
                sources,
                check_ms: None,
            }
        }
    };
    let mut diags = Diagnostics::new();
    let base = super::super::sources::scene_dir(scene);
    let checking = Instant::now();
    let loaded = crate::scene::load_objects(&mut sources, file, &base, prims, &mut diags);
    let check_ms = checking.elapsed().as_secs_f64() * 1e3;
    let Some((mut renderer, objects)) = loaded else {
        return Attempt::Failed {
            message: None,
            diags,
            sources,
            check_ms: Some(check_ms),
        };
    };
    // Every parameter keeps its planes, so that the page can show any of them.
    renderer.options.keep_params = renderer.shading_params().iter().map(|p| p.name.clone()).collect();
    // Tier-1 kernels, as `primflow trace` renders: a click traces this very frame.
    let mut jit = match Jit::new(renderer.program().clone()) {
        Ok(jit) => jit,
        Err(e) => {
            return Attempt::Failed {
                message: Some(format!("cannot start the JIT: {e}")),
                diags,
                sources,
                check_ms: Some(check_ms),
            }
        }
    };
    let mut result = match pool {
        Some(pool) => pool.install(|| renderer.render(&mut jit)),
        None => renderer.render(&mut jit),
    };
    diags.extend(std::mem::take(&mut result.diags));
    if diags.has_errors() {
        return Attempt::Failed {
            message: None,
            diags,
            sources,
            check_ms: Some(check_ms),
        };
    }
    Attempt::Rendered {
        compile_ms: result.stats.compile_micros as f64 / 1e3,
        render_ms: result.stats.render_micros as f64 / 1e3,
        shown: Box::new(Shown {
            generation: 0,
            sources,
            renderer,
            objects,
            frame: result.frame,
        }),
        diags,
        check_ms,
    }
}

/// Publish `attempt` as the next generation: the summary line for stdout, and the
/// diagnostics (or the message) as printed on stderr.
fn publish(preview: &Preview, attempt: Attempt, total_ms: f64, changed: Vec<String>) -> (String, String) {
    let round = |ms: f64| (ms * 100.0).round() / 100.0;
    let diags_of = |diags: &Diagnostics, sources: &SourceMap| -> (Vec<Value>, String) {
        let values = diags.items.iter().map(|d| diagnostic_json(d, sources)).collect();
        (values, diags.render(sources))
    };
    match attempt {
        Attempt::Missing => {
            let message = "the scene does not exist; waiting for it to be saved".to_string();
            let generation = preview.publish(|s| {
                s.status = "missing";
                s.message = Some(message.clone());
                s.diagnostics = vec![];
                s.timings = None;
                s.changed = changed;
            });
            (format!("render {generation}: {message}"), String::new())
        }
        Attempt::Failed {
            message,
            diags,
            sources,
            check_ms,
        } => {
            let (values, mut printed) = diags_of(&diags, &sources);
            if let Some(m) = &message {
                printed.push_str(&format!("error: {m}"));
            }
            let errors = diags.error_count().max(usize::from(message.is_some()));
            let generation = preview.publish(|s| {
                s.status = "errors";
                s.message = message;
                s.diagnostics = values;
                s.timings = Some(json!({"check": check_ms.map(round), "total": round(total_ms)}));
                s.changed = changed;
            });
            (
                format!("render {generation}: {errors} error(s), nothing rendered ({total_ms:.1} ms)"),
                printed,
            )
        }
        Attempt::Rendered {
            mut shown,
            diags,
            check_ms,
            compile_ms,
            render_ms,
        } => {
            let (values, printed) = diags_of(&diags, &shown.sources);
            let size = (shown.frame.width, shown.frame.height);
            let timings = json!({
                "check": round(check_ms),
                "compile": round(compile_ms),
                "render": round(render_ms),
                "total": round(total_ms),
            });
            let generation = preview.publish(|s| {
                shown.generation = s.generation;
                s.status = "ok";
                s.message = None;
                s.diagnostics = values;
                s.timings = Some(timings);
                s.changed = changed;
                s.shown = Some(Arc::new(*shown));
            });
            (
                format!(
                    "render {generation}: {}x{} done in {total_ms:.1} ms (check {check_ms:.1} ms, kernels {compile_ms:.1} ms, frame {render_ms:.1} ms)",
                    size.0, size.1
                ),
                printed,
            )
        }
    }
}

/// A diagnostic for the page: severity, code, message, where (`file`, `line`, `col` and
/// `location` as `file:line:col`, all null without a span) and the rendering `check` prints.
fn diagnostic_json(d: &Diagnostic, sources: &SourceMap) -> Value {
    let at = d
        .primary_span()
        .filter(|s| (s.file as usize) < sources.files.len())
        .map(|s| {
            let (line, col) = sources.line_col(s.file, s.start);
            (sources.file(s.file).name.clone(), line, col)
        });
    json!({
        "severity": if d.is_error() { "error" } else { "warning" },
        "code": d.code,
        "message": d.message,
        "file": at.as_ref().map(|a| &a.0),
        "line": at.as_ref().map(|a| a.1),
        "col": at.as_ref().map(|a| a.2),
        "location": at.as_ref().map(|(f, l, c)| format!("{f}:{l}:{c}")),
        "rendered": d.render(sources),
    })
}
