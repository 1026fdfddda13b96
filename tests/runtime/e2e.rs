//! End to end: the primitive library compiled by the checker and the JIT, driven through the
//! scene reader and the renderer. Pixel values are checked against analytic references.

use std::path::Path;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::jit::Jit;
use primflow::runtime::{Frame, Registry, Renderer};

/// Load the library, read `text` as a scene, render with `threads` threads.
fn render_scene(text: &str, threads: usize, count_writes: bool) -> (Frame, Vec<String>) {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let registry = Registry::load(&mut sources, &[], &[], &mut diags).unwrap_or_else(|| {
        panic!("library does not compile:\n{}", diags.render(&sources));
    });
    let file = sources.add("e2e.scene", text);
    let mut renderer = Renderer::new(registry.program.clone());
    renderer.options.count_writes = count_writes;
    primflow::scene::load_into(&sources, file, &mut renderer, &mut diags);
    let mut jit = Jit::new(registry.program.clone()).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let out = pool.install(|| renderer.render(&mut jit));
    diags.extend(out.diags);
    (out.frame, diags.codes_at(&sources))
}

#[test]
fn two_triangles_sharing_an_edge_write_every_pixel_exactly_once() {
    // A 40x24 rectangle split along a diagonal that crosses pixel centres and tile edges.
    let scene = "\
image 48 32
tile 16
material Cs 1 1 1
begin screen_triangle
rast_param screen_vertex 4 4 0.5 1   44 4 0.5 1   4 28 0.5 1
end
begin screen_triangle
rast_param screen_vertex 44 4 0.5 1   44 28 0.5 1   4 28 0.5 1
end
";
    let (frame, codes) = render_scene(scene, 2, true);
    assert!(codes.is_empty(), "{codes:?}");
    for y in 0..32 {
        for x in 0..48 {
            let inside = (4..44).contains(&x) && (4..28).contains(&y);
            assert_eq!(frame.write_count_at(x, y), Some(u32::from(inside)), "pixel {x},{y}");
        }
    }
}

#[test]
fn linear_colour_is_the_plane_through_the_vertex_values() {
    let scene = "\
image 64 64
material_interp Cs linear
begin screen_triangle
rast_param screen_vertex 2 2 0.25 1   62 2 0.5 1   2 62 0.75 1
material Cs 1 0 0
sequence_point
material Cs 0 1 0
sequence_point
material Cs 0 0 1
sequence_point
end
";
    let (frame, codes) = render_scene(scene, 2, false);
    assert!(codes.is_empty(), "{codes:?}");
    for (x, y) in [(10u32, 10u32), (30, 20), (5, 50), (40, 15)] {
        // Barycentric weights of the pixel centre: the right-angle corner at (2, 2).
        let (cx, cy) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
        let (b1, b2) = ((cx - 2.0) / 60.0, (cy - 2.0) / 60.0);
        let b0 = 1.0 - b1 - b2;
        let cs = frame.param_at("Cs", x, y).unwrap();
        for (got, want) in cs.iter().zip([b0, b1, b2]) {
            assert!((f64::from(*got) - want).abs() < 1e-5, "Cs at {x},{y}: {cs:?} vs {want}");
        }
        let depth = f64::from(frame.depth_f32_at(x, y).unwrap());
        let want = 0.25 * b0 + 0.5 * b1 + 0.75 * b2;
        assert!((depth - want).abs() < 1e-6, "depth at {x},{y}: {depth} vs {want}");
    }
    assert!(!frame.written(60, 60), "outside the hypotenuse");
}

#[test]
fn the_example_scene_renders_identically_on_one_and_two_threads() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/triangles.scene");
    let text = std::fs::read_to_string(path).unwrap();
    let (one, codes) = render_scene(&text, 1, false);
    assert!(codes.is_empty(), "{codes:?}");
    let (two, _) = render_scene(&text, 2, false);
    assert_eq!(one.depth_values(), two.depth_values());
    assert_eq!(one.to_rgb8().into_raw(), two.to_rgb8().into_raw());
    // The near yellow triangle covers the far one; the constant one shows in its corner.
    assert!((one.depth_f32_at(250, 110).unwrap() - 0.6).abs() < 1e-6);
    assert_eq!(one.color_at(250, 110)[0], 1.0, "yellow to white: red is 1 throughout");
    let corner = one.param_at("Cs", 300, 232).unwrap();
    assert_eq!(corner, vec![0.8, 0.3, 0.9]);
}

mod fuzz {
    use super::*;
    use proptest::prelude::*;

    const BASE: &str = "\
image 24 16
tile 8
material_interp Cs linear
begin screen_triangle
rast_param screen_vertex 1 1 0.5 1   23 2 0.5 1   4 15 0.5 1
material Cs 1 0 0
sequence_point
material Cs 0 1 0
sequence_point
material Cs 0 0 1
sequence_point
end
material_interp Cs constant
begin screen_triangle
rast_param screen_vertex 20 1 0.7 1   23 15 0.2 1   2 12 0.9 1
end
";

    fn token() -> impl Strategy<Value = String> {
        prop_oneof![
            Just("begin".to_string()),
            Just("end".to_string()),
            Just("screen_triangle".to_string()),
            Just("sequence_point".to_string()),
            Just("material".to_string()),
            Just("material_interp".to_string()),
            Just("perspective_linear".to_string()),
            Just("constant".to_string()),
            Just("Cs".to_string()),
            Just("\n".to_string()),
            Just("nan".to_string()),
            Just("inf".to_string()),
            Just("-1e30".to_string()),
            "-?[0-9]{1,2}(\\.[0-9]{1,2})?",
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]
        /// Token deletions, insertions and replacements in a scene of the real library: the
        /// reader and the compiled kernels report or cope, never panic, and the frame keeps
        /// its size.
        #[test]
        fn mutated_scenes_render_through_the_jit_without_panics(
            edits in proptest::collection::vec((0usize..64, proptest::option::of(token())), 1..6)
        ) {
            let mut words: Vec<String> = BASE.split_inclusive([' ', '\n']).map(String::from).collect();
            for (at, replacement) in edits {
                let at = at % words.len();
                match replacement {
                    Some(t) => words.insert(at, format!("{t} ")),
                    None => {
                        words.remove(at);
                    }
                }
            }
            let text = words.concat();
            let mut sources = SourceMap::new();
            let mut diags = Diagnostics::new();
            let registry = Registry::load(&mut sources, &[], &[], &mut diags).unwrap();
            let file = sources.add("fuzz.scene", text);
            let mut renderer = Renderer::new(registry.program.clone());
            primflow::scene::load_into(&sources, file, &mut renderer, &mut diags);
            renderer.options.width = renderer.options.width.min(32);
            renderer.options.height = renderer.options.height.min(32);
            let mut jit = Jit::new(registry.program.clone()).unwrap();
            let out = renderer.render(&mut jit);
            prop_assert_eq!(out.frame.depth_values().len(), (out.frame.width * out.frame.height) as usize);
            let _ = out.diags.render(&sources);
        }
    }
}
