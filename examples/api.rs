//! primflow from Rust: compile the primitive library, describe a frame with the `Renderer`
//! calls a scene file makes, render it with the JIT and write a PNG.
//!
//! ```text
//! cargo run --example api -- api.png
//! ```
//!
//! A library user builds without the command line's dependencies:
//! `primflow = { path = "...", default-features = false }`. `tests/runtime/api_example.rs`
//! runs [`render`] and checks its pixels.

use primflow::diag::{Diagnostics, SourceMap};
use primflow::jit::Jit;
use primflow::runtime::{Frame, Registry, Renderer, Value};

/// A 160 x 120 frame: a perspective camera, a red-to-blue triangle (`polygon`, a `facet`
/// primitive: clipped and culled by the runtime's geometry stage) and a sphere behind it.
/// Errors come back as text: compile errors rendered with their source lines, API errors
/// with their code.
pub fn render() -> Result<Frame, String> {
    // The library is embedded in the binary; `dirs` would add directories of .prim files.
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let registry = Registry::load(&mut sources, &[], &[], &mut diags).ok_or_else(|| diags.render(&sources))?;

    let mut r = Renderer::new(registry.program.clone());
    let issue = |e: primflow::runtime::ApiIssue| format!("{e:?}");
    r.set_image_size(160, 120).map_err(issue)?;
    r.set_background([0.1, 0.1, 0.12]);
    r.perspective_checked(50.0, 1.0, 100.0).map_err(issue)?;

    // Cs interpolated linearly across the triangle: one colour per vertex.
    r.material_interp("Cs", "linear", &[]).map_err(issue)?;
    r.begin("polygon").map_err(issue)?;
    for (xyz, cs) in [
        ([-2.0, -1.5, -5.0], [1.0, 0.0, 0.0]),
        ([2.0, -1.5, -5.0], [0.0, 1.0, 0.0]),
        ([0.0, 1.8, -5.0], [0.0, 0.0, 1.0]),
    ] {
        r.material("Cs", &Value(cs.to_vec())).map_err(issue)?;
        r.vertex(xyz[0], xyz[1], xyz[2], 1.0).map_err(issue)?;
    }
    r.end().map_err(issue)?;

    // A grey sphere, its colour constant over it.
    r.material_interp("Cs", "constant", &[]).map_err(issue)?;
    r.material("Cs", &Value(vec![0.7, 0.7, 0.7])).map_err(issue)?;
    r.begin("sphere").map_err(issue)?;
    r.rast_param("center", &Value(vec![1.5, 0.5, -9.0])).map_err(issue)?;
    r.rast_param("radius", &Value(vec![2.0])).map_err(issue)?;
    r.end().map_err(issue)?;

    // Kernels are compiled on first use, one per primitive and variant.
    let mut jit = Jit::new(r.program().clone()).map_err(|e| format!("{e:?}"))?;
    let output = r.render(&mut jit);
    if output.diags.has_errors() {
        return Err(output.diags.render(&sources));
    }
    Ok(output.frame)
}

fn main() {
    let path = std::env::args().nth(1).unwrap_or_else(|| "api.png".to_string());
    match render() {
        Ok(frame) => match frame.to_rgb8().save(&path) {
            Ok(()) => println!("rendered {}x{} -> {path}", frame.width, frame.height),
            Err(e) => {
                eprintln!("cannot write {path}: {e}");
                std::process::exit(1);
            }
        },
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    }
}
