//! The source files a scene's render reads, and a watch on them: what `primflow watch` and
//! `primflow serve` share.
//!
//! The directories ([`directories`]): the scene file's own, every `--prims` directory, every
//! `PRIMFLOW_PRIMS` directory and the scene's `prims DIR` directories (looked up again on each
//! call, as the scene may name new ones); only those that exist now. `serve` also reads and
//! writes the page's edits only in these directories (`serve::files`).
//!
//! [`SourceWatch`] watches them (not their subdirectories) and reports a change when a
//! `.scene` or `.prim` file in one of them is touched, so images a render writes (and their
//! temporary files) never count. Such events arriving within [`SETTLE`] of each other are
//! one change (an editor's save is often a write, a rename and an attribute change).

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use notify::{RecursiveMode, Watcher};

use crate::diag::{Diagnostics, SourceMap};

/// How long a watch waits after an event for more of the same change.
pub(super) const SETTLE: Duration = Duration::from_millis(30);

/// A file watcher on the directories of one scene's sources.
pub(super) struct SourceWatch {
    watcher: notify::RecommendedWatcher,
    events: mpsc::Receiver<notify::Result<notify::Event>>,
    /// A sender into `events`, for [`SourceWatch::notifier`].
    sender: mpsc::Sender<notify::Result<notify::Event>>,
    /// The directories watched so far, canonicalised.
    watched: Vec<PathBuf>,
}

/// Tells a [`SourceWatch`] that a file changed, as if the watcher had seen it (`serve` after
/// saving an edit, so that the render does not wait on the file system's event).
#[derive(Clone)]
pub(super) struct Notifier(mpsc::Sender<notify::Result<notify::Event>>);

impl Notifier {
    pub(super) fn changed(&self, path: &Path) {
        // Absolute, as the watcher names files, so that its own event for the save is the
        // same path.
        let path = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        let event = notify::Event::new(notify::EventKind::Modify(notify::event::ModifyKind::Any));
        let _ = self.0.send(Ok(event.add_path(path)));
    }
}

impl SourceWatch {
    pub(super) fn new() -> Result<SourceWatch, String> {
        let (sender, events) = mpsc::channel();
        let watcher = notify::recommended_watcher(sender.clone()).map_err(|e| format!("cannot watch files: {e}"))?;
        Ok(SourceWatch {
            watcher,
            events,
            sender,
            watched: vec![],
        })
    }

    pub(super) fn notifier(&self) -> Notifier {
        Notifier(self.sender.clone())
    }

    /// Start watching the directories of `scene`'s sources not watched yet: per directory,
    /// `Ok(dir)` when it is now watched, `Err(message)` when it cannot be.
    pub(super) fn watch_new(&mut self, scene: &Path, prims: &[PathBuf]) -> Vec<Result<PathBuf, String>> {
        let mut report = vec![];
        for dir in directories(scene, prims) {
            let canonical = std::fs::canonicalize(&dir).unwrap_or(dir.clone());
            if self.watched.contains(&canonical) {
                continue;
            }
            match self.watcher.watch(&dir, RecursiveMode::NonRecursive) {
                Ok(()) => {
                    self.watched.push(canonical);
                    report.push(Ok(dir));
                }
                Err(e) => report.push(Err(format!("cannot watch {}: {e}", dir.display()))),
            }
        }
        report
    }

    /// Wait for a change to a source, then for it to settle: the `.scene` and `.prim` files
    /// touched, sorted. `Err` when the watcher has stopped.
    pub(super) fn next_change(&self) -> Result<Vec<PathBuf>, String> {
        let mut changed: Vec<PathBuf> = vec![];
        while changed.is_empty() {
            match self.events.recv() {
                Ok(event) => changed.extend(sources_in(event)),
                Err(_) => return Err("the file watcher stopped".to_string()),
            }
        }
        // Settled once SETTLE passes without a source touched: other events (a file read,
        // which `serve` does on each request) neither count nor keep the change open.
        let mut settled = Instant::now() + SETTLE;
        while let Some(left) = settled.checked_duration_since(Instant::now()) {
            let Ok(event) = self.events.recv_timeout(left) else {
                break;
            };
            let sources = sources_in(event);
            if !sources.is_empty() {
                changed.extend(sources);
                settled = Instant::now() + SETTLE;
            }
        }
        changed.sort();
        changed.dedup();
        Ok(changed)
    }
}

/// The `.scene` and `.prim` files an event touched.
fn sources_in(event: notify::Result<notify::Event>) -> Vec<PathBuf> {
    let Ok(event) = event else { return vec![] };
    if event.kind.is_access() {
        return vec![];
    }
    event
        .paths
        .into_iter()
        .filter(|p| is_source(p))
        // `dir/./a.scene` as `dir/a.scene`.
        .map(|p| p.components().collect())
        .collect()
}

/// Whether `path` names a source a render reads: a `.scene` or `.prim` file.
pub(super) fn is_source(path: &Path) -> bool {
    path.extension().is_some_and(|x| x == "scene" || x == "prim")
}

/// The directory of `scene`: its parent, or `.` for a bare file name.
pub(super) fn scene_dir(scene: &Path) -> PathBuf {
    match scene.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// The directories a render of `scene` with `--prims` directories `prims` reads sources
/// from, that exist now: the scene's, `prims`, `PRIMFLOW_PRIMS`'s and the scene's `prims
/// DIR` lines' (resolved against the scene's directory; none when it does not parse).
pub(super) fn directories(scene: &Path, prims: &[PathBuf]) -> Vec<PathBuf> {
    let base = scene_dir(scene);
    let mut dirs = vec![base.clone()];
    dirs.extend(prims.iter().cloned());
    if let Some(v) = std::env::var_os(crate::runtime::PRIMS_ENV) {
        dirs.extend(std::env::split_paths(&v).filter(|d| !d.as_os_str().is_empty()));
    }
    dirs.extend(scene_prim_dirs(scene, &base));
    dirs.retain(|d| d.is_dir());
    dirs
}

/// The scene's `prims DIR` lines, resolved against `base`; none when it does not parse.
fn scene_prim_dirs(scene: &Path, base: &Path) -> Vec<PathBuf> {
    let Ok(text) = crate::scene::read_file(scene) else {
        return vec![];
    };
    let mut sources = SourceMap::new();
    let file = sources.add_file(scene, text);
    let mut diags = Diagnostics::new();
    crate::scene::parse(&sources, file, &mut diags).prim_dirs(base)
}
