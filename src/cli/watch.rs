//! `primflow watch SCENE -o out.png`: render, then render again whenever a source it reads
//! changes, until interrupted.
//!
//! What is watched: the directory of the scene file, every `--prims` directory, every
//! `PRIMFLOW_PRIMS` directory and the scene's own `prims DIR` directories (looked up again
//! after each render, as the scene may name new ones). Only events on `.scene` and `.prim`
//! files start a render, so the images the render writes (and their temporary files) never
//! do. Events arriving within [`SETTLE`] of each other are one change (an editor's save is
//! often a write, a rename and an attribute change). Each render is `primflow render` with
//! the same arguments: its diagnostics, its summary line and its files; an error (a
//! compile error, a deleted scene) is printed and the watch goes on.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use notify::{RecursiveMode, Watcher};

use super::RenderArgs;
use crate::diag::{Diagnostics, SourceMap};

/// How long the watch waits after an event for more of the same change.
const SETTLE: Duration = Duration::from_millis(30);

pub(super) fn watch(args: &RenderArgs, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    let (tx, rx) = mpsc::channel();
    let mut watcher = match notify::recommended_watcher(tx) {
        Ok(w) => w,
        Err(e) => {
            let _ = writeln!(err, "error: cannot watch files: {e}");
            return 1;
        }
    };
    let mut watched: Vec<PathBuf> = vec![];
    loop {
        if args.scene.exists() {
            let started = Instant::now();
            super::render(args, out, err);
            let _ = writeln!(out, "render done in {:.1} ms", started.elapsed().as_secs_f64() * 1e3);
        } else {
            let _ = writeln!(
                err,
                "warning: the scene {} is gone; waiting for it to come back",
                args.scene.display()
            );
            let _ = err.flush();
        }
        for dir in directories(args) {
            let canonical = std::fs::canonicalize(&dir).unwrap_or(dir.clone());
            if watched.contains(&canonical) {
                continue;
            }
            match watcher.watch(&dir, RecursiveMode::NonRecursive) {
                Ok(()) => {
                    let _ = writeln!(out, "watching {}", dir.display());
                    watched.push(canonical);
                }
                Err(e) => {
                    let _ = writeln!(err, "warning: cannot watch {}: {e}", dir.display());
                }
            }
        }
        let _ = out.flush();
        // Wait for a change to a source, then for the change to settle.
        let mut changed: Vec<PathBuf> = vec![];
        while changed.is_empty() {
            match rx.recv() {
                Ok(event) => changed.extend(sources_in(event)),
                Err(_) => {
                    let _ = writeln!(err, "error: the file watcher stopped");
                    return 1;
                }
            }
        }
        while let Ok(event) = rx.recv_timeout(SETTLE) {
            changed.extend(sources_in(event));
        }
        changed.sort();
        changed.dedup();
        let names: Vec<String> = changed.iter().map(|p| p.display().to_string()).collect();
        let _ = writeln!(out, "changed: {}", names.join(", "));
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
        .filter(|p| p.extension().is_some_and(|x| x == "scene" || x == "prim"))
        // `dir/./a.scene` as `dir/a.scene`.
        .map(|p| p.components().collect())
        .collect()
}

/// The directories a render of `args` reads sources from, that exist now.
fn directories(args: &RenderArgs) -> Vec<PathBuf> {
    let base = match args.scene.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut dirs = vec![base.clone()];
    dirs.extend(args.prims.iter().cloned());
    if let Some(v) = std::env::var_os(crate::runtime::PRIMS_ENV) {
        dirs.extend(std::env::split_paths(&v).filter(|d| !d.as_os_str().is_empty()));
    }
    dirs.extend(scene_prim_dirs(&args.scene, &base));
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
