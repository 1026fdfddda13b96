//! Which files the preview page may read and write: the sources of the scene's render, and
//! nothing else.
//!
//! A path the page sends is taken as the server names files itself (relative to its working
//! directory, or absolute). It is allowed when it names a `.scene` or `.prim` file directly
//! inside one of the directories a render reads ([`super::super::sources::directories`]:
//! the scene's, the `--prims`, `PRIMFLOW_PRIMS` and scene `prims DIR` directories), compared
//! canonicalised, so `..`, symbolic links and other spellings of a path outside cannot pass;
//! a file that exists is checked where it really is (a link inside pointing outside is
//! refused). Subdirectories are not included, as they are not watched either. Every other
//! path is refused, and the server answers 403.

use std::path::{Component, Path, PathBuf};

/// The path of the file `requested` names, when the page may read and write it; else why not.
pub(super) fn allowed(requested: &str, dirs: &[PathBuf]) -> Result<PathBuf, String> {
    let refuse = |why: &str| Err(format!("`{requested}` {why}"));
    if requested.is_empty() || requested.contains('\0') {
        return refuse("is not a file name");
    }
    let path = PathBuf::from(requested);
    if !super::super::sources::is_source(&path) {
        return refuse("is not a .scene or .prim file");
    }
    if !matches!(path.components().next_back(), Some(Component::Normal(_))) {
        return refuse("is not a file name");
    }
    let allowed_dirs: Vec<PathBuf> = dirs.iter().filter_map(|d| std::fs::canonicalize(d).ok()).collect();
    let inside = |file: &Path| {
        let parent = match file.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        std::fs::canonicalize(parent).is_ok_and(|p| allowed_dirs.contains(&p))
    };
    if !inside(&path) {
        return refuse("is not in the scene's directory or a primitive directory");
    }
    // An existing file (or link) is checked where it really is.
    if std::fs::symlink_metadata(&path).is_ok() {
        match std::fs::canonicalize(&path) {
            Ok(real) if inside(&real) && super::super::sources::is_source(&real) => {}
            _ => return refuse("leads outside the scene's directory and the primitive directories"),
        }
    }
    Ok(path)
}

/// Write `text` to `path` whole: into a temporary file beside it, then renamed over it, so
/// the watcher never renders a half-written file.
pub(super) fn save(path: &Path, text: &str) -> Result<(), String> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let temp = path.with_file_name(format!(".{name}.primflow-serve-{}.tmp", std::process::id()));
    let written = std::fs::write(&temp, text).and_then(|()| std::fs::rename(&temp, path));
    if let Err(e) = written {
        let _ = std::fs::remove_file(&temp);
        return Err(format!("cannot save {}: {e}", path.display()));
    }
    Ok(())
}

/// The sources the page offers to edit: the scene (whether or not it exists yet), then the
/// `.prim` files of each of `dirs` in order (each directory once), sorted by name.
pub(super) fn listing(scene: &Path, dirs: &[PathBuf]) -> Vec<String> {
    let mut files = vec![scene.display().to_string()];
    let mut seen: Vec<PathBuf> = vec![];
    for dir in dirs {
        let Ok(canonical) = std::fs::canonicalize(dir) else {
            continue;
        };
        if seen.contains(&canonical) {
            continue;
        }
        seen.push(canonical);
        let Ok(entries) = std::fs::read_dir(dir) else { continue };
        let mut names: Vec<PathBuf> = entries
            .filter_map(|e| e.ok())
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "prim") && p.is_file())
            .collect();
        names.sort();
        files.extend(names.iter().map(|p| p.display().to_string()));
    }
    files
}
