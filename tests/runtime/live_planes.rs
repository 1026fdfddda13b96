//! Dead-parameter elimination (`runtime::live`): a frame shaded by language shaders
//! allocates planes only for the parameters its shaders read (or the caller keeps), its
//! primitives' kernels are compiled without the other bindings, and every pixel it keeps is
//! the pixel of the frame that keeps every plane.

use primflow::diag::{Diagnostics, SourceMap};
use primflow::jit::Jit;
use primflow::runtime::{Registry, RenderOutput, Renderer};

/// Render `text` with the library, keeping `keep` whatever the shaders read.
fn render(text: &str, keep: &[&str]) -> RenderOutput {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let registry = Registry::load(&mut sources, &[], &[], &mut diags).expect("library compiles");
    let file = sources.add("live.scene", text);
    let mut renderer = Renderer::new(registry.program.clone());
    primflow::scene::load_into(&sources, file, &mut renderer, &mut diags);
    assert!(!diags.has_errors(), "{}", diags.render(&sources));
    renderer.options.keep_params = keep.iter().map(|s| s.to_string()).collect();
    let mut jit = Jit::new(registry.program.clone()).unwrap();
    let out = renderer.render(&mut jit);
    assert!(!out.diags.has_errors(), "{}", out.diags.render(&sources));
    out
}

/// A lit quad whose parameters no shader reads sit between those it does, in every
/// binding kind: per-vertex (`linear`, interleaved with the live `Cs` in the interpolation
/// data), a shared interpolator (binding data) and a constant.
fn scene(shading: &str) -> String {
    let vertex = |x: f32, y: f32, c: f32| {
        format!(
            "material dead_linear {c} {} 0.5\nmaterial Cs {c} 0.5 {}\nvertex {x} {y} 0\n",
            1.0 - c,
            1.0 - c
        )
    };
    format!(
        "image 48 40
perspective 40 0.5 50
look_at 0 0 4   0 0 0   0 1 0
{shading}
material_interp dead_linear linear
material_interp Cs linear
material_interp uv cylindrical_interpolation cylinder_start=0 cylinder_end=2
material dead_linear 0 0 0
material Cs 1 1 1
material uv 0 0
material dead_constant 7
material_interp N perspective_linear
material N 0 0 1
begin polygon
{}{}{}{}end
",
        vertex(-1.0, -1.0, 0.0),
        vertex(1.0, -1.0, 0.25),
        vertex(1.0, 1.0, 1.0),
        vertex(-1.2, 0.8, 0.5),
    )
}

const LIT: &str = "lightsource ambientlight intensity=0.2\nlightsource distantlight intensity=0.8 from=1,2,1 to=0,0,0\nshader plastic Ks=0.5 roughness=0.1";
const DEAD: [&str; 3] = ["dead_linear", "uv", "dead_constant"];

fn names(out: &RenderOutput) -> Vec<&str> {
    out.frame.params.iter().map(|p| p.name.as_str()).collect()
}

#[test]
fn planes_no_shader_reads_are_not_allocated() {
    let out = render(&scene(LIT), &[]);
    let names = names(&out);
    for dead in DEAD {
        assert!(!names.contains(&dead), "`{dead}` has planes: {names:?}");
    }
    for live in ["Cs", "N", "Ci"] {
        assert!(names.contains(&live), "`{live}` has no planes: {names:?}");
    }
    // The surface binding's plane (set by the `shader` line, so first), then Cs, N and Ci.
    assert_eq!(out.frame.num_planes(), 10, "{names:?}");
    let explain = out.language_shading.join("\n");
    assert!(
        explain.contains("not allocated, not interpolated by any primitive: `dead_linear`, `uv`, `dead_constant`"),
        "{explain}"
    );
    assert!(
        explain.contains("G-buffer planes 1-3: `Cs` (read by surface(s) matte, plastic)"),
        "{explain}"
    );
}

#[test]
fn kernels_are_compiled_without_the_dead_bindings() {
    let stripped = render(&scene(LIT), &[]);
    let kept = render(&scene(LIT), &DEAD);
    let polygon_keys = |out: &RenderOutput| -> Vec<String> {
        out.kernels
            .iter()
            .filter(|k| k.primitive == "polygon")
            .map(|k| k.key.clone())
            .collect()
    };
    let (s, k) = (polygon_keys(&stripped), polygon_keys(&kept));
    assert_eq!(s, vec!["constant:1,linear:3,perspective_linear:3".to_string()]);
    assert_eq!(
        k,
        vec!["constant:1,linear:3,linear:3,cylindrical_interpolation:2,constant:1,perspective_linear:3".to_string()]
    );
}

#[test]
fn the_kept_pixels_are_those_of_the_full_frame() {
    let stripped = render(&scene(LIT), &[]);
    let full = render(&scene(LIT), &DEAD);
    assert_eq!(full.frame.num_planes(), 10 + 3 + 2 + 1);
    let (w, h) = (stripped.frame.width, stripped.frame.height);
    let mut covered = 0;
    for y in 0..h {
        for x in 0..w {
            for name in ["Cs", "N", "__surface", "Ci"] {
                assert_eq!(
                    stripped.frame.param_at(name, x, y),
                    full.frame.param_at(name, x, y),
                    "`{name}` at ({x}, {y})"
                );
            }
            assert_eq!(
                stripped.frame.color_at(x, y),
                full.frame.color_at(x, y),
                "colour at ({x}, {y})"
            );
            covered += usize::from(stripped.frame.depth_at(x, y).is_some_and(|d| d != 0));
        }
    }
    // The quad covers a good part of the frame, and its colours vary with the per-vertex Cs.
    assert!(covered > 300, "{covered} pixels covered");
    let cs = |x, y| stripped.frame.param_at("Cs", x, y).unwrap()[0];
    assert!((cs(12, 30) - cs(36, 10)).abs() > 0.2, "Cs does not vary over the quad");
    // The kept parameters still interpolate what the API gave them.
    assert_eq!(full.frame.param_at("dead_constant", w / 2, h / 2), Some(vec![7.0]));
}

#[test]
fn a_parameter_the_caller_keeps_has_its_planes() {
    let out = render(&scene(LIT), &["dead_constant"]);
    let names = names(&out);
    assert!(names.contains(&"dead_constant") && !names.contains(&"uv"), "{names:?}");
    assert_eq!(out.frame.param_at("dead_constant", 24, 20), Some(vec![7.0]));
    assert!(out
        .language_shading
        .join("\n")
        .contains("`dead_constant` (kept for the caller"));
}

#[test]
fn a_frame_without_language_shading_keeps_every_plane() {
    let out = render(&scene(""), &[]);
    let names = names(&out);
    for p in ["dead_linear", "Cs", "uv", "dead_constant", "N"] {
        assert!(names.contains(&p), "`{p}` missing: {names:?}");
    }
}
