//! `render`'s output files are written whole or not at all: every path's format and directory
//! are checked before the scene is rendered, images go to a temporary file beside the target
//! and are renamed into place, and a failure on one output writes none of them.

use crate::support::cli;

use std::path::{Path, PathBuf};

const SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/triangles.scene");

/// A fresh directory per test.
fn temp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("primflow-output-files-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn names_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    names.sort();
    names
}

#[test]
fn a_refused_format_leaves_an_existing_file_as_it_was_and_renders_nothing() {
    let dir = temp_dir("format");
    for ext in ["jpg", "bmp", "tiff", "gif", "PNGX"] {
        let target = dir.join(format!("out.{ext}"));
        let before = b"precious bytes that must survive".to_vec();
        std::fs::write(&target, &before).unwrap();
        let (code, out, err) = cli(&["render", SCENE, "-o", target.to_str().unwrap()]);
        assert_eq!(code, 1, "{ext}: {err}");
        assert!(err.contains("only PNG is supported"), "{ext}: {err}");
        assert!(err.contains(&format!("out.{ext}")), "{ext}: {err}");
        assert!(!out.contains("rendered"), "{ext}: checked before rendering: {out}");
        assert_eq!(std::fs::read(&target).unwrap(), before, "{ext}: the file was touched");
    }
    // Nothing else was left behind.
    assert_eq!(
        names_in(&dir),
        ["out.PNGX", "out.bmp", "out.gif", "out.jpg", "out.tiff"]
    );
}

#[test]
fn a_bad_depth_path_fails_before_the_main_image_is_written() {
    let dir = temp_dir("depth");
    let main = dir.join("main.png");
    let existing = dir.join("existing.png");
    std::fs::write(&existing, b"old").unwrap();
    let bad_depth = dir.join("no-such-dir/depth.png");
    for (target, depth) in [(&main, bad_depth.clone()), (&existing, dir.join("depth.jpg"))] {
        let (code, out, err) = cli(&[
            "render",
            SCENE,
            "-o",
            target.to_str().unwrap(),
            "--depth",
            depth.to_str().unwrap(),
        ]);
        assert_eq!(code, 1, "{err}");
        assert!(err.contains("cannot write the depth image"), "{err}");
        assert!(err.contains("nothing rendered"), "{err}");
        assert!(!out.contains("rendered"), "{out}");
    }
    assert!(!main.exists(), "no main image");
    assert_eq!(std::fs::read(&existing).unwrap(), b"old");
    assert_eq!(names_in(&dir), ["existing.png"]);
}

#[test]
fn a_bad_param_path_or_name_writes_no_file() {
    let dir = temp_dir("param");
    let main = dir.join("main.png");
    let depth = dir.join("depth.png");
    let (code, _, err) = cli(&[
        "render",
        SCENE,
        "-o",
        main.to_str().unwrap(),
        "--param",
        "Cs",
        dir.join("missing/cs.png").to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("cannot write the parameter image"), "{err}");
    // A name the scene does not have is known only after rendering: still nothing written.
    let (code, _, err) = cli(&[
        "render",
        SCENE,
        "-o",
        main.to_str().unwrap(),
        "--depth",
        depth.to_str().unwrap(),
        "--param",
        "nosuch",
        dir.join("n.png").to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("no shading parameter `nosuch`"), "{err}");
    assert!(err.contains("no file written"), "{err}");
    assert_eq!(names_in(&dir), Vec::<String>::new());
}

#[test]
fn a_successful_render_replaces_the_files_whole_and_leaves_no_temporary_file() {
    let dir = temp_dir("ok");
    let main = dir.join("main.png");
    let depth = dir.join("depth.png");
    std::fs::write(&main, b"an older, shorter file").unwrap();
    let (code, out, err) = cli(&[
        "render",
        SCENE,
        "-o",
        main.to_str().unwrap(),
        "--depth",
        depth.to_str().unwrap(),
        "--param",
        "Cs",
        dir.join("cs.png").to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("main.png") && out.contains("depth.png") && out.contains("cs.png"),
        "{out}"
    );
    assert_eq!(names_in(&dir), ["cs.png", "depth.png", "main.png"]);
    let rgb = image::open(&main).unwrap().to_rgb8();
    assert_eq!(rgb.dimensions(), (320, 240));
    assert_eq!(rgb.get_pixel(2, 2).0, [26, 26, 31], "background 0.1 0.1 0.12");
    assert_eq!(image::open(&depth).unwrap().to_luma16().dimensions(), (320, 240));
}
