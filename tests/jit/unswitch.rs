//! Unswitching of the pixel loops (src/mid/unswitch.rs): tier 1 decides a uniform
//! `if` of the pixel code once per draw and lowers the pixel loops once per side. Every
//! case renders with both tiers (tier 0 never unswitches: it is the reference lowering)
//! and compares the frames bit for bit, and checks each pixel against a reference
//! computed here: coverage in f64, depth with the primitive's own f32 operations. The
//! setup words only one side reads (`fa`, `fb`, `fc` below, screen_triangle's float edges)
//! are stored in that side's dispatch block (`Lower::defer_frame_stores`): with the sides
//! swapped, every test here fails.

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::runtime::{Renderer, Value};
use primflow::workload::same_frame;

/// Two coverage forms chosen by a uniform `if` on an expression of arguments (no local),
/// the block walk's guard prefix under it; after the guards, nested uniform `if`s, a
/// uniform `if` inside a varying one, and a uniform `if` on a local the pixel code assigns
/// (not unswitchable: its value changes within a group).
const UNSWITCHY: &str = r#"
primitive unswitchy(
    float rect[4];
    float vert[6];
    float mode;
    float shade;
    varying float X, Y;
    inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    int ea[3], eb[3], ec[3];
    float fa[3], fb[3], fc[3];
    for (int i = 0; i < 3; i++) {
        int j = (i + 1) % 3;
        int xi = int(vert[2 * i]), yi = int(vert[2 * i + 1]);
        int xj = int(vert[2 * j]), yj = int(vert[2 * j + 1]);
        ea[i] = yi - yj;
        eb[i] = xj - xi;
        ec[i] = -2 * (ea[i] * xi + eb[i] * yi);
        fa[i] = ea[i];
        fb[i] = eb[i];
        fc[i] = ec[i] / 2;
    }
    int hits = 0;
    if (mode * 2 > 0) {
        int sx = int(X * 2), sy = int(Y * 2);
        if (ea[0] * sx + eb[0] * sy + ec[0] <= 0) return;
        if (ea[1] * sx + eb[1] * sy + ec[1] <= 0) return;
        if (ea[2] * sx + eb[2] * sy + ec[2] <= 0) return;
    } else {
        if (fa[0] * X + fb[0] * Y + fc[0] <= 0) return;
        if (fa[1] * X + fb[1] * Y + fc[1] <= 0) return;
        if (fa[2] * X + fb[2] * Y + fc[2] <= 0) return;
    }
    float v = X * 0.001;
    if (shade > 1) {
        if (shade > 2)
            v = v + 0.25;
        else
            v = v + 0.125;
        hits = hits + 1;
    }
    if (Y > 10) {
        if (mode * shade > 3)
            v = v + 0.0625;
    }
    if (hits > 0)
        v = v + 0.03125;
    Z = (mode > 0 ? 0.25 : 0.5) + v;
}
"#;

const VERT: [f32; 6] = [4.0, 3.0, 35.0, 8.0, 12.0, 22.0];
const W: u32 = 40;
const H: u32 = 24;

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("unswitchy.prim", UNSWITCHY)])
}

fn scene(program: &Arc<Program>, mode: f32, shade: f32) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(W, H).unwrap();
    r.set_tile_size(16).unwrap();
    r.begin("unswitchy").unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, W as f32, H as f32]))
        .unwrap();
    r.rast_param("vert", &Value(VERT.to_vec())).unwrap();
    r.rast_param("mode", &Value(vec![mode])).unwrap();
    r.rast_param("shade", &Value(vec![shade])).unwrap();
    r.end().unwrap();
    r
}

/// The covered pixel centres (strictly inside all three edges; f64 is exact here: integer
/// vertices, half-integer centres).
fn covered(x: u32, y: u32) -> bool {
    let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
    (0..3).all(|i| {
        let j = (i + 1) % 3;
        let (xi, yi) = (VERT[2 * i] as f64, VERT[2 * i + 1] as f64);
        let (xj, yj) = (VERT[2 * j] as f64, VERT[2 * j + 1] as f64);
        let (a, b) = (yi - yj, xj - xi);
        a * px + b * py - (a * xi + b * yi) > 0.0
    })
}

/// The depth the primitive computes at a covered pixel, with its f32 operations.
fn expected_z(mode: f32, shade: f32, x: u32, y: u32) -> f32 {
    let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
    let mut v = px * 0.001f32;
    if shade > 1.0 {
        v += if shade > 2.0 { 0.25 } else { 0.125 };
    }
    if py > 10.0 && mode * shade > 3.0 {
        v += 0.0625;
    }
    if shade > 1.0 {
        v += 0.03125;
    }
    (if mode > 0.0 { 0.25 } else { 0.5 }) + v
}

#[test]
fn each_side_of_unswitched_uniform_ifs_renders_as_the_reference() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let inside = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x, y)))
        .filter(|&(x, y)| covered(x, y))
        .count();
    assert!(inside > 100, "the triangle covers pixels: {inside}");
    // mode picks the coverage form (integer / float edges); shade the nested sides; their
    // product the `if` inside the varying one.
    for mode in [1.0f32, -1.0] {
        for shade in [0.5f32, 1.5, 3.5] {
            let what = format!("mode {mode} shade {shade}");
            let frame = support::all_tiers(&program, &scene(&program, mode, shade), &what);
            let mut written = 0;
            for y in 0..H {
                for x in 0..W {
                    assert_eq!(frame.written(x, y), covered(x, y), "{what}: pixel ({x}, {y})");
                    if !covered(x, y) {
                        continue;
                    }
                    written += 1;
                    let z = frame.depth_f32_at(x, y).unwrap();
                    let want = expected_z(mode, shade, x, y);
                    assert!((z - want).abs() < 1e-6, "{what}: pixel ({x}, {y}) z {z} want {want}");
                }
            }
            assert_eq!(written, inside, "{what}");
        }
    }
}

/// Several draws of one kernel in one frame with different sides: each copy of the pixel
/// loops must serve exactly its own draws (the decision is per draw, not per kernel).
#[test]
fn draws_taking_different_sides_share_one_kernel() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let mut r = Renderer::new(program.clone());
    r.set_image_size(W, H).unwrap();
    r.set_tile_size(16).unwrap();
    // Left half integer edges, right half float edges, both clipped by their rectangles.
    for (mode, x0, x1) in [(1.0f32, 0.0f32, 20.0f32), (-1.0, 20.0, 40.0)] {
        r.begin("unswitchy").unwrap();
        r.rast_param("rect", &Value(vec![x0, 0.0, x1, H as f32])).unwrap();
        r.rast_param("vert", &Value(VERT.to_vec())).unwrap();
        r.rast_param("mode", &Value(vec![mode])).unwrap();
        r.rast_param("shade", &Value(vec![3.5])).unwrap();
        r.end().unwrap();
    }
    let frame = support::all_tiers(&program, &r, "two draws");
    for y in 0..H {
        for x in 0..W {
            assert_eq!(frame.written(x, y), covered(x, y), "pixel ({x}, {y})");
            if covered(x, y) {
                let mode = if x < 20 { 1.0 } else { -1.0 };
                let z = frame.depth_f32_at(x, y).unwrap();
                let want = expected_z(mode, 3.5, x, y);
                assert!((z - want).abs() < 1e-6, "pixel ({x}, {y}) z {z} want {want}");
            }
        }
    }
}

/// screen_triangle's `if (exact)`: a small triangle (integer edges) and one spanning more
/// than 1024 pixels (float edges) through both tiers; the pixels of the small one against
/// the exact reference rasterizer.
#[test]
fn screen_triangle_exact_and_float_sides_match_tier_0() {
    let program = support::library();
    let (w, h) = (64u32, 48u32);
    let small = [[3.3f32, 2.7, 0.5, 1.0], [41.6, 9.1, 0.5, 1.0], [17.2, 39.8, 0.5, 1.0]];
    let huge = [
        [-1500.0f32, 40.5, 0.25, 1.0],
        [60.25, -900.0, 0.25, 1.0],
        [70.5, 47.0, 0.25, 1.0],
    ];
    for (name, v) in [("small", small), ("huge", huge)] {
        let mut r = support::renderer(&program, w, h, false);
        r.set_tile_size(16).unwrap();
        support::screen_triangle(&mut r, v, &[]);
        let mut frames = vec![];
        for (tier_name, mut jit) in support::jits(&program) {
            let f = support::render_with(&r, &mut jit, 1);
            frames.push((tier_name, f));
        }
        assert!(same_frame(&frames[0].1, &frames[1].1), "{name}: tiers differ");
        let frame = &frames[0].1;
        let count = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| frame.written(x, y))
            .count();
        if name == "small" {
            let v64 = v.map(|p| [p[0] as f64, p[1] as f64]);
            let want = support::reference_coverage(v64, w, h);
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(
                        frame.written(x, y),
                        want[(y * w + x) as usize],
                        "{name}: pixel ({x}, {y})"
                    );
                }
            }
        }
        assert!(count > 200, "{name}: covers pixels ({count})");
    }
}
