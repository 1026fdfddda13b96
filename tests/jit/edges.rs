//! Guards affine in X and Y through the JIT's block walk and pixel loops (block culling,
//! pass variants, small rectangles, both tiers): triangles of every awkward kind (slivers,
//! near-horizontal and near-vertical edges, vertices on pixel centres, huge coordinates,
//! both windings) against the hand-written kernel pixel for pixel, a mesh of shared edges
//! written exactly once per pixel, and user strips in float and in int (products that
//! wrap, inf/NaN/huge coefficients) against a one-pixel-at-a-time reference and tier 0.
//! (Written for the row-span experiment of docs/performance.md `rowspan`, which was not
//! merged; they hold for any way the compiler skips pixels.)

use crate::support;
use support::*;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::handwritten::{Flavor, Handwritten};
use primflow::ir::Program;
use primflow::runtime::{Frame, Renderer, Value};

const USER_PRIMS: &str = r#"
// Pixels within `w` of the line a*X + b*Y + c = 0 (two guards, one per side).
primitive strip(float a, b, c, w; float r[4]; float depth;
                varying float X, Y;
                inout varying fixed<32,32> Z)
{
    bound(r[0], r[1], r[2], r[3]);
    float v = X * a + Y * b + c;
    if (v > w)
        return;
    if (v < -w)
        return;
    if (depth < Z)
        return;
    Z = depth;
}

// The same in integers on a quarter-pixel grid: the products may wrap for large `a`.
primitive istrip(int a, b, c, w; float r[4]; float depth;
                 varying float X, Y;
                 inout varying fixed<32,32> Z)
{
    bound(r[0], r[1], r[2], r[3]);
    int sx = int(X * 4) - 3;
    int sy = int(Y * 4);
    int v = a * sx + b * sy + c;
    if (!(v <= w))
        return;
    if (v < -w)
        return;
    if (depth < Z)
        return;
    Z = depth;
}

// The same band through `abs`: one guard, not affine in X.
primitive astrip(float a, b, c, w; float r[4]; float depth;
                 varying float X, Y;
                 inout varying fixed<32,32> Z)
{
    bound(r[0], r[1], r[2], r[3]);
    if (abs(X * a + Y * b + c) > w)
        return;
    if (depth < Z)
        return;
    Z = depth;
}
"#;

fn library_with_user_prims() -> Arc<Program> {
    library_with(&mut SourceMap::new(), &[("user.prim", USER_PRIMS)])
}

fn written(frame: &Frame, w: u32, h: u32) -> Vec<bool> {
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| frame.written(x, y))
        .collect()
}

/// Awkward triangles: slivers, nearly horizontal and vertical edges, vertices on pixel
/// centres, huge coordinates (float edges), in both orientations.
fn awkward_triangles(w: f64, h: f64) -> Vec<[[f32; 4]; 3]> {
    let mut rng = Lcg(29);
    let mut out: Vec<[[f64; 2]; 3]> = vec![];
    for _ in 0..12 {
        let (x, y) = (rng.range(0.0, w), rng.range(0.0, h));
        let len = rng.range(5.0, 60.0);
        // Sliver: the third vertex a hair off the long edge.
        out.push([[x, y], [x + len, y + len * 0.3], [x + len * 0.5, y + len * 0.15 + 0.02]]);
        // Nearly horizontal and nearly vertical long edges.
        out.push([[x, y], [x + len, y + 0.001], [x + len * 0.4, y + rng.range(2.0, 9.0)]]);
        out.push([[x, y], [x + 0.001, y + len], [x - rng.range(2.0, 9.0), y + len * 0.6]]);
        // Vertices on pixel centres and edges through them.
        let (cx, cy) = (x.floor() + 0.5, y.floor() + 0.5);
        out.push([[cx, cy], [cx + 8.0, cy], [cx, cy + 8.0]]);
        out.push([[cx, cy], [cx + 12.0, cy + 4.0], [cx + 4.0, cy + 12.0]]);
        // Small (the small-rectangle path) and medium (mixed blocks).
        let s = rng.range(2.0, 7.0);
        out.push([[x, y], [x + s, y + rng.range(-s, s)], [x + rng.range(-s, s), y + s]]);
    }
    // Huge coordinates: float edges, one vertex far away.
    out.push([[10.0, 10.0], [1.0e6, 40.0], [30.0, 90.0]]);
    out.push([[5.5, 80.5], [120.5, -3.0e5], [150.0, 100.0]]);
    out.push([[-2.0e7, 50.0], [100.0, 20.0], [110.0, 60.0]]);
    let mut tris = vec![];
    for t in out {
        let z = [rng.range(0.05, 0.95), rng.range(0.05, 0.95), rng.range(0.05, 0.95)];
        let v: [[f32; 4]; 3] = std::array::from_fn(|j| [t[j][0] as f32, t[j][1] as f32, z[j] as f32, 1.0]);
        tris.push(v);
        // The other orientation.
        tris.push([v[0], v[2], v[1]]);
    }
    tris
}

#[test]
fn awkward_triangles_match_the_hand_written_kernel_pixel_for_pixel() {
    let program = library();
    let (w, h) = (160, 120);
    for (k, tri) in awkward_triangles(w as f64, h as f64).into_iter().enumerate() {
        let mut r = renderer(&program, w, h, true);
        r.material_interp("c", "perspective_linear", &[]).unwrap();
        screen_triangle(&mut r, tri, &[("c", [vec![0.1], vec![0.6], vec![0.9]])]);
        let mut sse = Handwritten::new(program.clone(), Flavor::Sse);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let reference = pool.install(|| r.render(&mut sse)).frame;
        for (name, mut jit) in jits(&program) {
            let frame = render_with(&r, &mut jit, 1);
            assert!(
                primflow::workload::same_frame(&frame, &reference),
                "{name}: triangle {k} {tri:?} differs from the hand-written kernel"
            );
            assert_eq!(
                written(&frame, w, h),
                written(&reference, w, h),
                "{name}: triangle {k} coverage"
            );
        }
    }
}

#[test]
fn a_mesh_of_shared_edges_writes_every_pixel_exactly_once() {
    // A jittered grid of quads, each split into two triangles, covering the image: no
    // crack (every pixel written) and no pixel twice. Cells of 5 and of 37 pixels take the
    // small-rectangle path and the mixed blocks.
    let program = library();
    let (w, h) = (150, 110);
    for cell in [5.0f64, 37.0] {
        let mut rng = Lcg(cell as u64);
        let (nx, ny) = (
            (w as f64 / cell).ceil() as usize + 1,
            (h as f64 / cell).ceil() as usize + 1,
        );
        let mut grid = vec![[0.0f64; 2]; (nx + 1) * (ny + 1)];
        for j in 0..=ny {
            for i in 0..=nx {
                let edge = i == 0 || j == 0 || i == nx || j == ny;
                let jit = if edge { 0.0 } else { cell * 0.3 };
                grid[j * (nx + 1) + i] = [
                    (i as f64 - 0.5) * cell + rng.range(-jit, jit),
                    (j as f64 - 0.5) * cell + rng.range(-jit, jit),
                ];
            }
        }
        let mut r = renderer(&program, w, h, true);
        let vert = |p: [f64; 2]| [p[0] as f32, p[1] as f32, 0.5f32, 1.0f32];
        for j in 0..ny {
            for i in 0..nx {
                let p = |a: usize, b: usize| vert(grid[(j + b) * (nx + 1) + i + a]);
                screen_triangle(&mut r, [p(0, 0), p(1, 0), p(1, 1)], &[]);
                // Alternate the winding.
                screen_triangle(&mut r, [p(0, 0), p(0, 1), p(1, 1)], &[]);
            }
        }
        for (name, mut jit) in jits(&program) {
            let frame = render_with(&r, &mut jit, 1);
            let counts = frame.write_count_values().expect("counted");
            let off: Vec<usize> = (0..counts.len()).filter(|&i| counts[i] != 1).collect();
            assert!(
                off.is_empty(),
                "{name}, cell {cell}: {} pixels not written exactly once, first at {:?}",
                off.len(),
                off.first().map(|&i| (i as u32 % w, i as u32 / w))
            );
        }
    }
}

/// Pixels of the pass rectangle (centres in the closed `r`) whose `keep` holds.
fn reference(r: [f32; 4], w: u32, h: u32, keep: impl Fn(f32, f32) -> bool) -> Vec<bool> {
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (cx, cy) = (x as f32 + 0.5, y as f32 + 0.5);
            cx >= r[0] && cx <= r[2] && cy >= r[1] && cy <= r[3] && keep(cx, cy)
        })
        .collect()
}

fn strip_params(r: &mut Renderer, name: &str, coef: [f32; 4], rect: [f32; 4]) {
    r.begin(name).unwrap();
    for (p, v) in ["a", "b", "c", "w"].iter().zip(coef) {
        r.rast_param(p, &Value(vec![v])).unwrap();
    }
    r.rast_param("r", &Value(rect.to_vec())).unwrap();
    r.rast_param("depth", &Value(vec![0.5])).unwrap();
    r.end().unwrap();
}

/// Strips across the whole image (mixed blocks) and inside small bounds (the small-rectangle
/// path), with steep, shallow, axis-parallel, huge, infinite and NaN coefficients.
fn strip_cases() -> Vec<([f32; 4], [f32; 4])> {
    let whole = [0.0, 0.0, 1.0e9, 1.0e9];
    let small = [20.3, 30.0, 31.0, 38.5];
    let mut out = vec![];
    for rect in [whole, small] {
        for coef in [
            [1.0, 0.37, -60.0, 3.5],
            [-0.05, 1.0, -40.0, 2.0],
            [1.0, 0.0, -25.5, 0.5],
            [0.0, 1.0, -33.0, 4.0],
            [3.0e5, -1.0e5, 7.0, 2.0e6],
            [1.0e-30, 1.0, -35.0, 3.0],
            [1.0e30, -1.0e30, 0.0, 1.0e31],
            [f32::INFINITY, 1.0, 0.0, 5.0],
            [1.0, 1.0, -60.0, f32::NAN],
            [0.7, -0.7, 0.0, 0.0],
        ] {
            out.push((coef, rect));
        }
    }
    out
}

#[test]
fn float_strips_match_a_per_pixel_reference_and_tier_0() {
    let program = library_with_user_prims();
    let (w, h) = (130, 90);
    for (coef, rect) in strip_cases() {
        let [a, b, c, wd] = coef;
        // The pixel code's operations in source order, in f32.
        let expected = reference(rect, w, h, |x, y| {
            let v = x * a + y * b + c;
            !(v > wd) && !(v < -wd)
        });
        let abs_expected = reference(rect, w, h, |x, y| !((x * a + y * b + c).abs() > wd));
        for (prim, want) in [("strip", &expected), ("astrip", &abs_expected)] {
            let mut r = renderer(&program, w, h, true);
            strip_params(&mut r, prim, coef, rect);
            for (name, mut jit) in jits(&program) {
                let frame = render_with(&r, &mut jit, 1);
                assert_eq!(&written(&frame, w, h), want, "{name}: {prim} {coef:?} in {rect:?}");
                let counts = frame.write_count_values().expect("counted");
                assert!(counts.iter().all(|&n| n <= 1), "{name}: a pixel written twice");
            }
        }
    }
}

#[test]
fn int_strips_match_a_per_pixel_reference_even_when_products_wrap() {
    let program = library_with_user_prims();
    let (w, h) = (130, 90);
    let whole = [0.0, 0.0, 1.0e9, 1.0e9];
    let small = [20.3, 30.0, 31.0, 38.5];
    for rect in [whole, small] {
        for coef in [
            [4i32, 1, -240, 12],
            [-1, 6, -500, 9],
            [1, 0, -100, 0],
            [0, 1, -140, 7],
            // a * sx wraps for sx >= 108: nothing may assume the product is affine.
            [20_000_000, 1, 0, 1_000_000_000],
            [-3, 2, 2_000_000_000, 2_000_000_000],
        ] {
            let [a, b, c, wd] = coef;
            let expected = reference(rect, w, h, |x, y| {
                let sx = ((x * 4.0) as i32).wrapping_sub(3);
                let sy = (y * 4.0) as i32;
                let v = a.wrapping_mul(sx).wrapping_add(b.wrapping_mul(sy)).wrapping_add(c);
                v <= wd && !(v < wd.wrapping_neg())
            });
            let mut r = renderer(&program, w, h, true);
            strip_params(&mut r, "istrip", coef.map(|v| v as f32), rect);
            for (name, mut jit) in jits(&program) {
                let frame = render_with(&r, &mut jit, 1);
                assert_eq!(written(&frame, w, h), expected, "{name}: {coef:?} in {rect:?}");
            }
        }
    }
}
