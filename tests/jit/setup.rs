//! The JIT's per-primitive setup and per-draw block walk (src/jit/lower.rs `body`,
//! `lower_bound`; src/mid/block.rs, src/jit/lower/block.rs): a bound run ends right after
//! `bound` only when nothing after it can widen the bound or record an error; block facts
//! take one side of a uniform `if` of the guard prefix; a pass span evaluates only the row
//! terms it reads. Every test renders user primitives (source below) through the runtime
//! and compares the pixels written, or the diagnostics, with what the source says.

use crate::support;
use support::*;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::runtime::{Frame, Renderer, Value};

const USER_PRIMS: &str = r#"
// A rectangle `r2` of depth `depth`, bound by `r1` first and then, when `widen` is set,
// by `r2`: the second bound must still reach the bound run. With `skip` set the setup
// returns after the bounds (nothing drawn).
primitive two_bounds(float r1[4]; float r2[4]; int widen; int skip; float depth;
                     varying float X, Y;
                     inout varying fixed<32,32> Z)
{
    bound(r1[0], r1[1], r1[2], r1[3]);
    if (widen != 0)
        bound(r2[0], r2[1], r2[2], r2[3]);
    float scaled = depth * 0.5;
    if (skip != 0)
        return;
    float d = scaled * 2;
    if (X < r2[0] || X > r2[2] || Y < r2[1] || Y > r2[3])
        return;
    if (d < Z)
        return;
    Z = d;
}

// A rectangle whose setup reads `table[i]` after its bound: with i out of range that is a
// run-time error, reported even when the bound lies outside the image (the bound run is
// then the only run).
primitive late_error(float r[4]; int i; float depth;
                     varying float X, Y;
                     inout varying fixed<32,32> Z)
{
    bound(r[0], r[1], r[2], r[3]);
    float table[2] = {0, 0.25};
    float d = depth + table[i];
    if (X < r[0] || X > r[2] || Y < r[1] || Y > r[3])
        return;
    if (d < Z)
        return;
    Z = d;
}

// Pixels with (axis 0) X <= k and Y <= k2, or (axis 1) Y <= k and X <= k2: the guard
// prefix has a uniform `if` whose sides assign a varying local and hold guards of their own.
primitive corner(int axis; float k; float k2; float depth;
                 varying float X, Y;
                 inout varying fixed<32,32> Z)
{
    bound(0, 0, 1e6, 1e6);                 // the whole image, without W0803
    float t;
    if (axis == 0) {
        t = X - k;
        if (Y > k2)
            return;
    } else {
        t = Y - k;
        if (X > k2)
            return;
    }
    if (t > 0)
        return;
    if (depth < Z)
        return;
    Z = depth;
}
"#;

fn library_with_user_prims() -> Arc<Program> {
    library_with(&mut SourceMap::new(), &[("user.prim", USER_PRIMS)])
}

fn written_pixels(frame: &Frame, width: u32, height: u32) -> Vec<(u32, u32)> {
    (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .filter(|&(x, y)| frame.written(x, y))
        .collect()
}

/// Pixels whose centre lies in the closed rectangle `r`.
fn centres_in(r: [f32; 4], width: u32, height: u32) -> Vec<(u32, u32)> {
    (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let (cx, cy) = (x as f32 + 0.5, y as f32 + 0.5);
            cx >= r[0] && cx <= r[2] && cy >= r[1] && cy <= r[3]
        })
        .collect()
}

fn two_bounds(r: &mut Renderer, r1: [f32; 4], r2: [f32; 4], widen: bool, skip: bool, depth: f32) {
    r.begin("two_bounds").unwrap();
    r.rast_param("r1", &Value(r1.to_vec())).unwrap();
    r.rast_param("r2", &Value(r2.to_vec())).unwrap();
    r.rast_param("widen", &Value(vec![f32::from(u8::from(widen))])).unwrap();
    r.rast_param("skip", &Value(vec![f32::from(u8::from(skip))])).unwrap();
    r.rast_param("depth", &Value(vec![depth])).unwrap();
    r.end().unwrap();
}

#[test]
fn a_bound_after_the_first_still_widens_the_primitive() {
    let program = library_with_user_prims();
    let (w, h) = (64, 64);
    // r1 covers one 16-pixel tile; r2 most of the image: binned by r1 alone, the pixels
    // of r2 in the other tiles would be missing.
    let (r1, r2) = ([2.0, 2.0, 10.0, 10.0], [2.0, 3.0, 60.0, 58.5]);
    for (name, mut jit) in jits(&program) {
        let mut r = renderer(&program, w, h, true);
        r.set_tile_size(16).unwrap();
        two_bounds(&mut r, r1, r2, true, false, 0.5);
        let frame = render_with(&r, &mut jit, 1);
        assert_eq!(written_pixels(&frame, w, h), centres_in(r2, w, h), "{name}: widened");
        let counts = frame.write_count_values().expect("counted");
        assert!(counts.iter().all(|&c| c <= 1), "{name}: a pixel written twice");

        // Not widened: only what r1 and r2 share (the pass rectangle is r1's).
        let mut r = renderer(&program, w, h, false);
        r.set_tile_size(16).unwrap();
        two_bounds(&mut r, r1, r2, false, false, 0.5);
        let frame = render_with(&r, &mut jit, 1);
        let shared = [2.0, 3.0, 10.0, 10.0];
        assert_eq!(
            written_pixels(&frame, w, h),
            centres_in(shared, w, h),
            "{name}: r1 only"
        );

        // A setup that returns after its bounds draws nothing.
        let mut r = renderer(&program, w, h, false);
        r.set_tile_size(16).unwrap();
        two_bounds(&mut r, r1, r2, true, true, 0.5);
        let frame = render_with(&r, &mut jit, 1);
        assert!(written_pixels(&frame, w, h).is_empty(), "{name}: skipped");
    }
}

#[test]
fn a_run_time_error_after_the_bound_is_reported_even_off_screen() {
    let program = library_with_user_prims();
    for (rect, drawn) in [([-40.0f32, -40.0, -20.0, -20.0], false), ([4.0, 4.0, 20.0, 12.0], true)] {
        for (name, mut jit) in jits(&program) {
            let mut r = renderer(&program, 32, 32, false);
            r.set_tile_size(16).unwrap();
            r.begin("late_error").unwrap();
            r.rast_param("r", &Value(rect.to_vec())).unwrap();
            r.rast_param("i", &Value(vec![5.0])).unwrap();
            r.rast_param("depth", &Value(vec![0.25])).unwrap();
            r.end().unwrap();
            let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
            let out = pool.install(|| r.render(&mut jit));
            let warnings: Vec<_> = out.diags.items.iter().filter(|d| d.code == "W0801").collect();
            assert_eq!(warnings.len(), 1, "{name}, {rect:?}: {:?}", out.diags.items);
            assert!(warnings[0].message.contains("index"), "{}", warnings[0].message);
            // The clamped read gives table[1] = 0.25: depth 0.5 where drawn.
            let written = written_pixels(&out.frame, 32, 32);
            if drawn {
                assert_eq!(written, centres_in(rect, 32, 32), "{name}");
                let d = out.frame.depth_at(8, 8).expect("in the image");
                assert_eq!(d, 1u32 << 31, "{name}: depth 0.5 as fixed<32,32>");
            } else {
                assert!(written.is_empty(), "{name}");
            }
        }
    }
}

#[test]
fn block_facts_take_one_side_of_a_uniform_if_and_match_every_pixel() {
    let program = library_with_user_prims();
    // Large enough for block culling (blocks of 16 x 8 in 64-pixel tiles), bounds that cut
    // blocks, groups and tiles off-centre, and every combination of sides.
    let (w, h) = (150, 100);
    for axis in [0, 1] {
        for (k, k2) in [
            (37.3f32, 71.6f32),
            (0.2, 99.9),
            (149.0, 5.5),
            (-3.0, 50.0),
            (80.5, 80.5),
        ] {
            for (name, mut jit) in jits(&program) {
                let mut r = renderer(&program, w, h, true);
                r.begin("corner").unwrap();
                r.rast_param("axis", &Value(vec![axis as f32])).unwrap();
                r.rast_param("k", &Value(vec![k])).unwrap();
                r.rast_param("k2", &Value(vec![k2])).unwrap();
                r.rast_param("depth", &Value(vec![0.5])).unwrap();
                r.end().unwrap();
                let frame = render_with(&r, &mut jit, 1);
                let expected: Vec<(u32, u32)> = (0..h)
                    .flat_map(|y| (0..w).map(move |x| (x, y)))
                    .filter(|&(x, y)| {
                        let (cx, cy) = (x as f32 + 0.5, y as f32 + 0.5);
                        let (along, across) = if axis == 0 { (cx, cy) } else { (cy, cx) };
                        along - k <= 0.0 && across <= k2
                    })
                    .collect();
                assert_eq!(
                    written_pixels(&frame, w, h),
                    expected,
                    "{name}: axis {axis}, k {k}, k2 {k2}"
                );
                let counts = frame.write_count_values().expect("counted");
                assert!(counts.iter().all(|&c| c <= 1), "{name}: a pixel written twice");
            }
        }
    }
}

#[test]
fn small_and_large_triangles_match_the_hand_written_kernel_through_both_edge_paths() {
    // screen_triangle's `if (exact)` in the guard prefix: small triangles (exact integer
    // edges, full code per group), large ones spanning over 1024 pixels (float edges, block
    // facts on the other side of the `if`), through the JIT and the hand-written SSE twin.
    use primflow::handwritten::{Flavor, Handwritten};
    let program = library();
    let (w, h) = (200, 160);
    let mut r = renderer(&program, w, h, false);
    r.material_interp("c", "perspective_linear", &[]).unwrap();
    let mut rng = Lcg(17);
    for i in 0..60 {
        let big = i % 10 == 0;
        let (cx, cy) = (rng.range(0.0, w as f64), rng.range(0.0, h as f64));
        let size = if big { 1500.0 } else { rng.range(3.0, 12.0) };
        let v: [[f32; 4]; 3] = std::array::from_fn(|j| {
            let a = rng.range(0.0, std::f64::consts::TAU) + j as f64 * 2.1;
            [
                (cx + size * a.cos()) as f32,
                (cy + size * a.sin()) as f32,
                rng.range(0.05, 0.95) as f32,
                rng.range(1.0, 3.0) as f32,
            ]
        });
        let c: [Vec<f32>; 3] = std::array::from_fn(|_| vec![rng.next() as f32]);
        screen_triangle(&mut r, v, &[("c", c)]);
    }
    let mut sse = Handwritten::new(program.clone(), Flavor::Sse);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let reference = pool.install(|| r.render(&mut sse)).frame;
    assert!(written_pixels(&reference, w, h).len() > 1000);
    for (name, mut jit) in jits(&program) {
        let frame = render_with(&r, &mut jit, 1);
        assert!(
            primflow::workload::same_frame(&frame, &reference),
            "{name}: differs from the hand-written kernel"
        );
    }
}
