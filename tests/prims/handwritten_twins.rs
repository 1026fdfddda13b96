//! Each hand-written kernel and its JIT twin produce the same buffers on the same scene
//! (the benchmark's precondition), bit for bit.

use crate::support;
use primflow::handwritten::{Flavor, Handwritten};
use primflow::runtime::{Frame, Renderer, Value};
use support::*;

fn frames_equal(a: &Frame, b: &Frame, what: &str) {
    assert_eq!(a.depth_values(), b.depth_values(), "{what}: depth differs");
    assert_eq!(
        a.write_count_values(),
        b.write_count_values(),
        "{what}: write counts differ"
    );
    for (p, (pa, pb)) in a.all_plane_values().iter().zip(&b.all_plane_values()).enumerate() {
        let differing = pa.iter().zip(pb).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
        assert_eq!(differing, 0, "{what}: plane {p} differs in {differing} pixels");
    }
}

#[test]
fn screen_triangle_jit_and_handwritten_agree_bit_for_bit() {
    let program = library();
    // The second depth range keeps every visible depth below 0.5: the nearest of many
    // overlapping triangles is otherwise almost always above it, and depth conversion has
    // a different path on each side of 2^31.
    for ((persp, lin), (z_lo, z_hi)) in [
        ((0usize, 0usize), (-0.1, 1.1)),
        ((1, 0), (-0.1, 1.1)),
        ((0, 1), (0.0, 0.45)),
        ((2, 2), (-0.1, 1.1)),
        ((4, 4), (0.0, 0.45)),
        ((0, 0), (0.0, 0.2)),
    ] {
        let mut r = renderer(&program, 157, 93, true);
        if persp > 0 {
            r.material_interp("p", "perspective_linear", &[]).unwrap();
        }
        if lin > 0 {
            r.material_interp("l", "linear", &[]).unwrap();
        }
        let mut rng = Lcg(persp as u64 * 31 + lin as u64);
        for k in 0..400 {
            // Mostly small triangles, some large, a few beyond the exact path's 1024 px.
            let size = [6.0, 40.0, 160.0, 3000.0][k % 4 * (k % 7 != 0) as usize + (k % 7 == 0) as usize * 3];
            let (cx, cy) = (rng.range(-10.0, 167.0), rng.range(-10.0, 103.0));
            let mut v = [[0f32; 4]; 3];
            for p in &mut v {
                *p = [
                    rng.range(cx - size, cx + size) as f32,
                    rng.range(cy - size, cy + size) as f32,
                    rng.range(z_lo, z_hi) as f32,
                    rng.range(0.2, 4.0) as f32,
                ];
            }
            let vals = |rng: &mut Lcg, n: usize| -> [Vec<f32>; 3] {
                std::array::from_fn(|_| (0..n).map(|_| rng.range(-2.0, 2.0) as f32).collect())
            };
            let mut params = vec![];
            if persp > 0 {
                params.push(("p", vals(&mut rng, persp)));
            }
            if lin > 0 {
                params.push(("l", vals(&mut rng, lin)));
            }
            screen_triangle(&mut r, v, &params);
        }
        let jit = render(&r, 2);
        assert!(jit.depth_values().iter().filter(|&&d| d != 0).count() > 5000);
        for flavor in [Flavor::Scalar, Flavor::Sse, Flavor::Avx2] {
            let mut hand = Handwritten::new(program.clone(), flavor);
            let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
            let out = pool.install(|| r.render(&mut hand));
            assert!(out.diags.items.is_empty(), "{:?}", out.diags.items);
            frames_equal(
                &jit,
                &out.frame,
                &format!("{persp}+{lin} components, {}", flavor.describe()),
            );
        }
    }
}

/// Render `r` with the hand-written kernels of `flavor` on `threads` threads; asserts no
/// diagnostics (an unserved key would be one).
fn render_handwritten(r: &Renderer, flavor: Flavor, threads: usize) -> Frame {
    let mut hand = Handwritten::new(r.program().clone(), flavor);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let out = pool.install(|| r.render(&mut hand));
    assert!(
        out.diags.items.is_empty(),
        "{}: {:?}",
        flavor.describe(),
        out.diags.items
    );
    out.frame
}

/// The SSE kernel's own paths: wide triangles (per-row spans, whole groups without edge
/// tests or blends), narrow ones (edges per group), huge ones (float edges), vertices on
/// pixel centres and grid points (top-left ties), shared edges, depths on both sides of
/// 2^31 and exactly 1 (the saturating end of the conversion), with and without write
/// counts, for several perspective/linear shapes.
#[test]
fn sse_screen_triangle_matches_jit_bit_for_bit() {
    let program = library();
    for (shape, ((persp, lin), count_writes)) in [
        ((0usize, 0usize), false),
        ((1, 0), true),
        ((0, 3), false),
        ((4, 0), true),
        ((2, 2), false),
        ((16, 0), true),
    ]
    .into_iter()
    .enumerate()
    {
        // Several tiles (64 px) in each direction, and a width that is not whole groups.
        let (w, h) = (203u32, 141u32);
        let mut r = renderer(&program, w, h, count_writes);
        if persp > 0 {
            r.material_interp("p", "perspective_linear", &[]).unwrap();
        }
        if lin > 0 {
            r.material_interp("l", "linear", &[]).unwrap();
        }
        let mut rng = Lcg(1000 + shape as u64);
        let mut submit = |r: &mut Renderer, rng: &mut Lcg, v: [[f32; 4]; 3]| {
            let vals = |rng: &mut Lcg, n: usize| -> [Vec<f32>; 3] {
                std::array::from_fn(|_| (0..n).map(|_| rng.range(-2.0, 2.0) as f32).collect())
            };
            let mut params = vec![];
            if persp > 0 {
                params.push(("p", vals(rng, persp)));
            }
            if lin > 0 {
                params.push(("l", vals(rng, lin)));
            }
            screen_triangle(r, v, &params);
        };
        // A full-viewport backdrop at depth exactly 0 (farthest: everything lands on it),
        // as two triangles sharing the diagonal.
        let (fw, fh) = (w as f32, h as f32);
        let quad = |r: &mut Renderer,
                    rng: &mut Lcg,
                    x1: f32,
                    z: f32,
                    submit: &mut dyn FnMut(&mut Renderer, &mut Lcg, [[f32; 4]; 3])| {
            let q = [[0.0, 0.0], [x1, 0.0], [x1, fh], [0.0, fh]];
            let at = |i: usize, wc: f32| [q[i][0], q[i][1], z, wc];
            submit(r, rng, [at(0, 1.0), at(1, 2.0), at(2, 3.0)]);
            submit(r, rng, [at(0, 1.0), at(2, 3.0), at(3, 1.5)]);
        };
        quad(&mut r, &mut rng, fw, 0.0, &mut submit);
        for k in 0..300 {
            let size = match k % 5 {
                0 => 3.0,
                1 => 12.0,
                2 | 3 => 90.0,
                _ => 2500.0,
            };
            let (cx, cy) = (rng.range(-20.0, w as f64 + 20.0), rng.range(-20.0, h as f64 + 20.0));
            let mut v = [[0f32; 4]; 3];
            for p in &mut v {
                // Every third triangle on pixel centres or the 1/16 grid: exact ties.
                let (x, y) = match k % 3 {
                    0 => (
                        rng.range(cx - size, cx + size).floor() + 0.5,
                        rng.range(cy - size, cy + size).floor() + 0.5,
                    ),
                    1 => (
                        grid(&mut rng, cx - size, cx + size),
                        grid(&mut rng, cy - size, cy + size),
                    ),
                    _ => (rng.range(cx - size, cx + size), rng.range(cy - size, cy + size)),
                };
                // Depths across the whole range: both conversion paths (below and above
                // 0.5, i.e. 2^31) and out-of-range corners clipped per pixel.
                *p = [
                    x as f32,
                    y as f32,
                    rng.range(-0.2, 1.2) as f32,
                    rng.range(0.3, 3.0) as f32,
                ];
            }
            submit(&mut r, &mut rng, v);
        }
        // Last, the left third at depth exactly 1 (nearest: the saturating end of the
        // conversion), over everything.
        quad(&mut r, &mut rng, (fw / 3.0).floor(), 1.0, &mut submit);
        let jit = render(&r, 2);
        let saturated = jit.depth_values().iter().filter(|&&d| d == u32::MAX).count();
        assert_eq!(saturated as u32, (w / 3) * h, "the depth-1 strip covers the left third");
        let hand = render_handwritten(&r, Flavor::Sse, 2);
        frames_equal(
            &jit,
            &hand,
            &format!("{persp}+{lin}, counts {count_writes}, {}", Flavor::Sse.describe()),
        );
        if count_writes {
            let writes: u64 = hand.write_count_values().unwrap().iter().map(|&c| u64::from(c)).sum();
            assert!(writes > 3 * u64::from(w * h), "{writes} depth writes");
        }
    }
}

/// A polygon scene: quads in perspective crossing the hither plane (clipped in the kernel),
/// quads wholly beyond it (trivially accepted: the variant without clipping), a pentagon,
/// and degenerate ones (collinear, two points, all between the eye and the hither plane).
fn polygon_scene(program: &std::sync::Arc<primflow::ir::Program>, persp: usize, lin: usize, count: bool) -> Renderer {
    let mut r = renderer(program, 131, 97, count);
    r.perspective(60.0, 1.0, 100.0);
    for c in 0..persp {
        r.material_interp(&format!("p{c}"), "perspective_linear", &[]).unwrap();
    }
    for c in 0..lin {
        r.material_interp(&format!("l{c}"), "linear", &[]).unwrap();
    }
    let mut rng = Lcg(77 + persp as u64 * 5 + lin as u64);
    let polygon = |r: &mut Renderer, rng: &mut Lcg, points: &[(f64, f64, f64)]| {
        r.begin("polygon").unwrap();
        for &(x, y, z) in points {
            for c in 0..persp {
                r.material(&format!("p{c}"), &Value(vec![rng.next() as f32])).unwrap();
            }
            for c in 0..lin {
                r.material(&format!("l{c}"), &Value(vec![rng.range(-1.0, 1.0) as f32]))
                    .unwrap();
            }
            r.vertex(x as f32, y as f32, z as f32, 1.0).unwrap();
        }
        r.end().unwrap();
    };
    for k in 0..120 {
        let (cx, cy) = (rng.range(-4.0, 4.0), rng.range(-3.0, 3.0));
        let size = rng.range(0.3, 2.5);
        let (z_far, z_near) = (-3.0 - 6.0 * rng.next(), -0.2 - rng.next());
        let z_near = if k % 2 == 0 { z_near } else { z_far + 1.0 };
        polygon(
            &mut r,
            &mut rng,
            &[
                (cx, cy, z_far),
                (cx + size, cy, z_far),
                (cx + size, cy + size, z_near),
                (cx, cy + size, z_near),
            ],
        );
    }
    // A pentagon crossing the plane with two vertices in front of it.
    polygon(
        &mut r,
        &mut rng,
        &[
            (-2.0, -2.0, -5.0),
            (2.0, -2.0, -5.0),
            (2.5, 0.5, -0.4),
            (0.0, 2.0, -0.3),
            (-2.5, 0.5, -4.0),
        ],
    );
    // Degenerate: collinear (zero area after projection), two points, and wholly between
    // the eye and the hither plane.
    polygon(
        &mut r,
        &mut rng,
        &[(-1.0, 0.0, -3.0), (0.0, 0.0, -3.0), (1.0, 0.0, -3.0), (2.0, 0.0, -3.0)],
    );
    polygon(&mut r, &mut rng, &[(-1.0, 0.0, -3.0), (1.0, 1.0, -3.0)]);
    polygon(
        &mut r,
        &mut rng,
        &[
            (-0.1, -0.1, -0.5),
            (0.1, -0.1, -0.5),
            (0.1, 0.1, -0.6),
            (-0.1, 0.1, -0.6),
        ],
    );
    r.take_warnings();
    r
}

#[test]
fn handwritten_polygon_matches_jit_bit_for_bit() {
    let program = library();
    for ((persp, lin), count) in [
        ((4usize, 0usize), true),
        ((4, 0), false),
        ((2, 2), true),
        ((0, 0), false),
    ] {
        let r = polygon_scene(&program, persp, lin, count);
        let trivially_accepted = r.instances().iter().filter(|i| i.key.trivial_accept).count();
        let clipped = r.instances().len() - trivially_accepted;
        assert!(
            trivially_accepted > 20 && clipped > 20,
            "{trivially_accepted} accepted, {clipped} with clipping"
        );
        let jit = render(&r, 2);
        let covered = jit.depth_values().iter().filter(|&&d| d != 0).count();
        assert!(covered > 3000, "{covered} pixels covered");
        for flavor in [Flavor::Scalar, Flavor::Sse, Flavor::Avx2] {
            let hand = render_handwritten(&r, flavor, 2);
            frames_equal(
                &jit,
                &hand,
                &format!("polygon {persp}+{lin}, counts {count}, {}", flavor.describe()),
            );
        }
    }
}
