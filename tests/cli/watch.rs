//! `primflow watch`: the built binary renders, re-renders when the scene or a `.prim` file
//! is saved (the new pixels land in the image), prints a compile error and goes on, and
//! reports a deleted scene instead of exiting.

use std::path::Path;
use std::process::{Child, Command};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// The watch process, killed when the test ends (passing or not).
struct Watch {
    child: Child,
    lines: Receiver<String>,
}

impl Drop for Watch {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Watch {
    /// Lines of stdout and stderr (prefixed `err: `) until one contains `needle`; panics
    /// after 30 s.
    fn until(&self, needle: &str) -> Vec<String> {
        let deadline = Instant::now() + Duration::from_secs(30);
        let mut seen = vec![];
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    let done = line.contains(needle);
                    seen.push(line);
                    if done {
                        return seen;
                    }
                }
                Err(_) => break,
            }
        }
        panic!("no line with {needle:?} within 30 s; saw {seen:#?}");
    }
}

fn start(dir: &Path, args: &[&str]) -> Watch {
    let (child, lines) = crate::support::spawn_with_lines(
        Command::new(env!("CARGO_BIN_EXE_primflow"))
            .arg("watch")
            .args(args)
            .current_dir(dir)
            .env_remove("PRIMFLOW_PRIMS"),
    );
    Watch { child, lines }
}

/// A primitive filling the pixels left of `edge` at depth 0.5, and a scene drawing it red.
fn halfplane(edge: u32) -> String {
    format!(
        "primitive halfplane(varying float X, Y; inout varying fixed<32,32> Z) {{\n    if (X > {edge}) return;\n    Z = 0.5;\n    interpolator_return;\n}}\n"
    )
}
const SCENE: &str = "image 16 4\nprims my\nmaterial_interp Cs constant\nmaterial Cs 1 0 0\nbegin halfplane\nend\n";

fn red_pixels(path: &Path) -> usize {
    let image = image::open(path).unwrap().to_rgb8();
    (0..16).filter(|&x| image.get_pixel(x, 1).0 == [255, 0, 0]).count()
}

#[test]
fn watch_renders_again_on_save_and_survives_errors_and_deletion() {
    let dir = std::env::temp_dir().join(format!("primflow-watch-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("my")).unwrap();
    std::fs::write(dir.join("my/halfplane.prim"), halfplane(4)).unwrap();
    std::fs::write(dir.join("a.scene"), SCENE).unwrap();
    let image = dir.join("out.png");

    let watch = start(&dir, &["a.scene", "-o", "out.png"]);
    watch.until("render done");
    assert_eq!(red_pixels(&image), 4);
    // The scene's `prims my` directory is watched once it has been read.
    watch.until("watching ./my");

    // A saved .prim file: rendered again, with the new edge.
    std::fs::write(dir.join("my/halfplane.prim"), halfplane(10)).unwrap();
    let seen = watch.until("render done");
    assert!(
        seen.iter()
            .any(|l| l.starts_with("changed: ") && l.contains("halfplane.prim")),
        "{seen:#?}"
    );
    assert_eq!(red_pixels(&image), 10);

    // A compile error: printed at its line, no image written, the watch goes on.
    std::fs::write(
        dir.join("my/halfplane.prim"),
        "primitive halfplane(varying float X, Y) {\n  float = ;\n}\n",
    )
    .unwrap();
    // (stderr's lines may arrive after stdout's "render done": two pipes, two readers)
    watch.until("halfplane.prim:2:");
    assert_eq!(red_pixels(&image), 10);

    // The scene deleted: reported; written again: rendered.
    std::fs::remove_file(dir.join("a.scene")).unwrap();
    watch.until("is gone; waiting");
    std::fs::write(dir.join("my/halfplane.prim"), halfplane(2)).unwrap();
    std::fs::write(dir.join("a.scene"), SCENE).unwrap();
    watch.until("render done");
    assert_eq!(red_pixels(&image), 2);
    drop(watch);
    std::fs::remove_dir_all(&dir).unwrap();
}
