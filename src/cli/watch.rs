//! `primflow watch SCENE -o out.png`: render, then render again whenever a source it reads
//! changes, until interrupted.
//!
//! What is watched and what counts as a change: [`super::sources`]. Each render is `primflow
//! render` with the same arguments: its diagnostics, its summary line and its files; an
//! error (a compile error, a deleted scene) is printed and the watch goes on.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use super::sources::SourceWatch;
use super::RenderArgs;

pub(super) fn watch(args: &RenderArgs, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    let mut watch = match SourceWatch::new() {
        Ok(w) => w,
        Err(e) => {
            let _ = writeln!(err, "error: {e}");
            return 1;
        }
    };
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
        for dir in watch.watch_new(&args.scene, &args.prims) {
            let _ = match dir {
                Ok(dir) => writeln!(out, "watching {}", dir.display()),
                Err(message) => writeln!(err, "warning: {message}"),
            };
        }
        let _ = out.flush();
        let changed = match watch.next_change() {
            Ok(changed) => changed,
            Err(message) => {
                let _ = writeln!(err, "error: {message}");
                return 1;
            }
        };
        let names: Vec<String> = changed.iter().map(|p: &PathBuf| p.display().to_string()).collect();
        let _ = writeln!(out, "changed: {}", names.join(", "));
    }
}
