//! Each hand-written kernel and its JIT twin produce the same buffers on the same scene
//! (the benchmark's precondition), bit for bit.

mod common;
use common::*;
use primflow::handwritten::{Flavor, Handwritten};
use primflow::runtime::Frame;

fn frames_equal(a: &Frame, b: &Frame, what: &str) {
    assert_eq!(a.depth, b.depth, "{what}: depth differs");
    assert_eq!(a.write_counts, b.write_counts, "{what}: write counts differ");
    for (p, (pa, pb)) in a.planes.iter().zip(&b.planes).enumerate() {
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
        assert!(jit.depth.iter().filter(|&&d| d != 0).count() > 5000);
        for flavor in [Flavor::Scalar, Flavor::Simd] {
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
