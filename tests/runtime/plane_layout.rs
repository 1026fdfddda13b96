//! The frame's G-buffer planes are `runtime::frame::plane_pitch` elements apart (a few cache
//! lines more than a plane): every kernel form writes each parameter into its own plane and
//! the frame's accessors read it back from there, with 16 planes (with the depth buffer more
//! lines than an L1 set has ways, the case the padding is for; the most the hand-written
//! kernels serve) at a size whose planes would otherwise be a multiple of
//! 4 KiB apart, at a ragged size, and into a reused frame of another size.

use crate::support;

use primflow::handwritten::{Flavor, Handwritten};
use primflow::jit::Jit;
use primflow::runtime::{Frame, Renderer};
use support::*;

const PARAMS: usize = 16;

/// Parameter `c`'s value in the backdrop (`layer` 0) and in the front triangle (`layer` 1):
/// the same at the three vertices, so linear interpolation gives it exactly at every pixel
/// (the plane's slopes are zero).
fn value(layer: usize, c: usize) -> f32 {
    if layer == 0 {
        c as f32 + 0.25
    } else {
        -(c as f32) - 0.5
    }
}

const FRONT: [[f32; 4]; 3] = [[3.2, 2.7, 0.75, 1.0], [29.6, 6.1, 0.75, 2.0], [9.4, 19.3, 0.75, 1.5]];

/// A full-viewport quad at depth 0.25 (two triangles) and one triangle in front of it, each
/// with `PARAMS` one-component linear parameters of constant values.
fn scene(program: &std::sync::Arc<primflow::ir::Program>, w: u32, h: u32) -> Renderer {
    let mut r = renderer(program, w, h, false);
    r.set_tile_size(16).unwrap();
    for c in 0..PARAMS {
        r.material_interp(&format!("p{c}"), "linear", &[]).unwrap();
    }
    let names: Vec<String> = (0..PARAMS).map(|c| format!("p{c}")).collect();
    let params = |layer: usize| -> Vec<(&str, [Vec<f32>; 3])> {
        names
            .iter()
            .enumerate()
            .map(|(c, n)| {
                (
                    n.as_str(),
                    [vec![value(layer, c)], vec![value(layer, c)], vec![value(layer, c)]],
                )
            })
            .collect()
    };
    let (fw, fh) = (w as f32, h as f32);
    let at = |x: f32, y: f32| [x, y, 0.25, 1.0];
    screen_triangle(&mut r, [at(0.0, 0.0), at(fw, 0.0), at(fw, fh)], &params(0));
    screen_triangle(&mut r, [at(0.0, 0.0), at(fw, fh), at(0.0, fh)], &params(0));
    screen_triangle(&mut r, FRONT, &params(1));
    r
}

/// Every pixel of every plane holds the value of the layer the exact coverage says is in
/// front there.
fn assert_planes(frame: &Frame, w: u32, h: u32, what: &str) {
    assert_eq!(frame.num_planes(), PARAMS as u32, "{what}");
    let front = reference_coverage(FRONT.map(|v| [f64::from(v[0]), f64::from(v[1])]), w, h);
    assert!(
        front.iter().filter(|&&c| c).count() > 100,
        "{what}: the front triangle covers pixels"
    );
    for c in 0..PARAMS {
        let name = format!("p{c}");
        for y in 0..h {
            for x in 0..w {
                let layer = usize::from(front[(y * w + x) as usize]);
                let got = frame.param_at(&name, x, y);
                assert_eq!(got, Some(vec![value(layer, c)]), "{what}: {name} at ({x}, {y})");
            }
        }
    }
}

#[test]
fn sixteen_planes_each_hold_their_own_parameter_for_every_kernel() {
    let program = library();
    // 64 x 64: planes of exactly 16 KiB; 37 x 23: a ragged width (not whole groups).
    for (w, h) in [(64u32, 64u32), (37, 23)] {
        let r = scene(&program, w, h);
        for (tier, mut jit) in jits(&program) {
            for threads in [1, 2] {
                let frame = render_with(&r, &mut jit, threads);
                assert_planes(&frame, w, h, &format!("{w}x{h} JIT {tier}, {threads} threads"));
            }
        }
        for flavor in [Flavor::Scalar, Flavor::Sse, Flavor::Avx2] {
            let mut hand = Handwritten::new(program.clone(), flavor);
            let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
            let out = pool.install(|| r.render(&mut hand));
            assert!(out.diags.items.is_empty(), "{:?}", out.diags.items);
            assert_planes(&out.frame, w, h, &format!("{w}x{h} {}", flavor.describe()));
        }
    }
}

#[test]
fn a_reused_frame_of_another_size_keeps_the_planes_apart() {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let mut frame = Frame::empty();
    // Bigger, smaller, bigger again: the plane pitch changes with the size each time.
    for (w, h) in [(64u32, 64u32), (37, 23), (64, 48)] {
        let r = scene(&program, w, h);
        let report = pool.install(|| r.render_into(&mut jit, &mut frame));
        assert!(report.diags.items.is_empty(), "{:?}", report.diags.items);
        assert_planes(&frame, w, h, &format!("{w}x{h} into a reused frame"));
    }
}
