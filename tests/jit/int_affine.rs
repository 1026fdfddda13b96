//! Int expressions affine in the pixel column, carried along the row by tier 1
//! (src/mid/affine.rs, src/jit/lower/carry.rs), against a per-pixel reference computed here
//! with Rust's wrapping integer operations and f32 conversions, on every tier (tier 0
//! evaluates every expression where it stands). Cases: the exact conversions `int(X * c)`
//! for c = 16, 2, 3, 512, 4096 and negative c, conversions that are not carried (c = 257,
//! 0.5, a float local holding X), products by uniform ints near i32::MAX (wrapping
//! coefficients), a local reassigned later, X under a varying `if`, a local read by itself,
//! a local read both in a carried expression and in a loop (its assignment must stay), and
//! screen triangles' exact edge tests with 0, 4 and 16 shading parameters against the
//! 64-bit reference rasterizer. Images have odd sizes and tiles of several sizes, so groups
//! are ragged and rows start at several offsets.

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::runtime::{Frame, Renderer, Value};

/// `n` by `mode`; the depth encodes `n % 1024` exactly (0.5 + r / 2^24). Pixels whose edge
/// test (mode 9, 10) fails return and keep the cleared depth.
const AFFINE: &str = r#"
primitive affine(float rect[4]; float mode; float u, v; int big, m, ea, eb, ec;
                 varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    int n = 0;
    if (mode == 0) {
        int sx = int(X * 16) - int(u * 16);
        n = sx * 3 + 1;
    }
    if (mode == 1) n = int(X * 2) + int(Y * 2) * 7;
    if (mode == 2) n = int(X * 3) - 5 + int(3 * X) * m;
    if (mode == 3) n = int(X * 512) + 1;
    if (mode == 4) n = int(X * 4096) + int(u * 16);
    if (mode == 5) {
        int sx = int(X * 16) - int(u * 16), sy = int(Y * 16) - int(v * 16);
        n = big * sx + m * sy + big * m * sx;
    }
    if (mode == 6) n = -int(X * 6) - int(X * -7) * 5 - (int(X * -16) - int(X * 24)) * big;
    if (mode == 7) {
        int sx = int(X * 16) - int(u * 16);
        int a = sx * m;
        sx = sx + 1;
        n = sx * m + a;
    }
    if (mode == 8) {
        if (X > 20.5 + Y)
            n = int(X * 16) * m + 3;
        else
            n = int(X * 3) - int(X * 2) * big;
    }
    if (mode == 9) {
        int sx = int(X * 16) - int(u * 16), sy = int(Y * 16) - int(v * 16);
        int e = ea * sx + eb * sy + ec;
        if (e <= 0) return;
        if (ea * sx - eb * sy - ec <= 0) return;
        n = e;
    }
    if (mode == 10) {
        float x = X;
        n = int(X * 257) + int(X * 0.5) * m + int(x * 16) * 3;
        if (n * big <= 0) return;
    }
    if (mode == 11) {
        int t = 0;
        for (int i = 0; i < 3; i++)
            t = t + int(X * 2) * i;
        n = t - int(X * 8) * eb;
    }
    if (mode == 12) {
        // sx is read in a carried expression and in a loop: its assignment stays.
        int sx = int(X * 16) - int(u * 16);
        n = sx * 5 - 2;
        for (int i = 0; i < 2; i++)
            n = n + sx;
    }
    Z = 0.5 + float(n % 1024) / 16777216;
}
"#;

const MODES: u32 = 13;
const U: f32 = 3.7;
const V: f32 = -1.3;
/// Exactly representable in f32 (the int parameters arrive as floats).
const BIG: i32 = 2_147_483_520;
const M: i32 = -2_147_483_392;
const EA: i32 = 48;
const EB: i32 = -37;
const EC: i32 = 900;

/// `n` at pixel column `px`, row `py` for `mode`; `None` where the pixel code returns.
fn expected_n(mode: u32, px: u32, py: u32) -> Option<i32> {
    let (x, y) = (px as f32 + 0.5, py as f32 + 0.5);
    let conv = |f: f32| f as i32;
    let sx = conv(x * 16.0).wrapping_sub(conv(U * 16.0));
    let sy = conv(y * 16.0).wrapping_sub(conv(V * 16.0));
    Some(match mode {
        0 => sx.wrapping_mul(3).wrapping_add(1),
        1 => conv(x * 2.0).wrapping_add(conv(y * 2.0).wrapping_mul(7)),
        2 => conv(x * 3.0)
            .wrapping_sub(5)
            .wrapping_add(conv(3.0 * x).wrapping_mul(M)),
        3 => conv(x * 512.0).wrapping_add(1),
        4 => conv(x * 4096.0).wrapping_add(conv(U * 16.0)),
        5 => BIG
            .wrapping_mul(sx)
            .wrapping_add(M.wrapping_mul(sy))
            .wrapping_add(BIG.wrapping_mul(M).wrapping_mul(sx)),
        6 => conv(x * 6.0)
            .wrapping_neg()
            .wrapping_sub(conv(x * -7.0).wrapping_mul(5))
            .wrapping_sub(conv(x * -16.0).wrapping_sub(conv(x * 24.0)).wrapping_mul(BIG)),
        7 => {
            let a = sx.wrapping_mul(M);
            sx.wrapping_add(1).wrapping_mul(M).wrapping_add(a)
        }
        8 => {
            if x > 20.5 + y {
                conv(x * 16.0).wrapping_mul(M).wrapping_add(3)
            } else {
                conv(x * 3.0).wrapping_sub(conv(x * 2.0).wrapping_mul(BIG))
            }
        }
        9 => {
            let e = EA.wrapping_mul(sx).wrapping_add(EB.wrapping_mul(sy)).wrapping_add(EC);
            let e2 = EA.wrapping_mul(sx).wrapping_sub(EB.wrapping_mul(sy)).wrapping_sub(EC);
            if e <= 0 || e2 <= 0 {
                return None;
            }
            e
        }
        10 => {
            let n = conv(x * 257.0)
                .wrapping_add(conv(x * 0.5).wrapping_mul(M))
                .wrapping_add(conv(x * 16.0).wrapping_mul(3));
            if n.wrapping_mul(BIG) <= 0 {
                return None;
            }
            n
        }
        12 => sx.wrapping_mul(5).wrapping_sub(2).wrapping_add(sx).wrapping_add(sx),
        _ => {
            let t = (0..3).fold(0i32, |t, i| t.wrapping_add(conv(x * 2.0).wrapping_mul(i)));
            t.wrapping_sub(conv(x * 8.0).wrapping_mul(EB))
        }
    })
}

/// The depth the primitive writes for `n`, as raw fixed<32,32> bits.
fn encoded(n: i32) -> u32 {
    let z = 0.5f32 + (n % 1024) as f32 / 16777216.0;
    (z as f64 * 4294967296.0) as u32
}

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("affine.prim", AFFINE)])
}

fn scene(program: &Arc<Program>, mode: u32, size: (u32, u32), tile: u32, rect: [f32; 4]) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(size.0, size.1).unwrap();
    r.set_tile_size(tile).unwrap();
    r.begin("affine").unwrap();
    r.rast_param("rect", &Value(rect.to_vec())).unwrap();
    r.rast_param("mode", &Value(vec![mode as f32])).unwrap();
    r.rast_param("u", &Value(vec![U])).unwrap();
    r.rast_param("v", &Value(vec![V])).unwrap();
    for (name, value) in [("big", BIG), ("m", M), ("ea", EA), ("eb", EB), ("ec", EC)] {
        r.rast_param(name, &Value(vec![value as f32])).unwrap();
    }
    r.end().unwrap();
    r
}

/// Every pixel of `frame` against the reference: inside the pass rectangle `rect` (closed,
/// pixel centres) the encoded `n`, elsewhere and where the code returns the cleared depth.
fn check(frame: &Frame, mode: u32, size: (u32, u32), rect: [f32; 4], cleared: u32, what: &str) -> usize {
    let mut written = 0;
    for py in 0..size.1 {
        for px in 0..size.0 {
            let (cx, cy) = (px as f32 + 0.5, py as f32 + 0.5);
            let inside = cx >= rect[0] && cx <= rect[2] && cy >= rect[1] && cy <= rect[3];
            let want = match (inside, expected_n(mode, px, py)) {
                (true, Some(n)) => {
                    written += 1;
                    encoded(n)
                }
                _ => cleared,
            };
            assert_eq!(frame.depth_at(px, py), Some(want), "{what}: pixel ({px}, {py})");
        }
    }
    written
}

#[test]
fn carried_int_expressions_match_the_wrapping_reference_in_every_tier() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let size = (67, 29);
    // The cleared depth: a pixel no primitive writes (an empty pass rectangle).
    let empty = support::all_tiers(
        &program,
        &scene(&program, 0, size, 16, [-9.0, -9.0, -8.0, -8.0]),
        "empty",
    );
    let cleared = empty.depth_at(0, 0).expect("pixel in the image");
    for mode in 0..MODES {
        for (tile, rect) in [
            (16, [0.0, 0.0, 1.0e9, 1.0e9]),
            (8, [5.3, 2.0, 61.5, 27.2]),
            (32, [13.0, 7.5, 18.7, 9.9]),
        ] {
            let what = format!("mode {mode}, tile {tile}, rect {rect:?}");
            let frame = support::all_tiers(&program, &scene(&program, mode, size, tile, rect), &what);
            let written = check(&frame, mode, size, rect, cleared, &what);
            assert!(written > 0, "{what}: no pixel written");
        }
    }
}

/// A whole-image rectangle of the wide image (2000 pixels, ragged at the end): the carried
/// values run over long rows, and `int(X * 4096)` reaches 8.2e6 (still exact).
#[test]
fn long_rows_stay_exact() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let size = (2001, 3);
    let rect = [0.0, 0.0, 1.0e9, 1.0e9];
    for mode in [0, 4, 5, 6, 9] {
        let what = format!("wide mode {mode}");
        let frame = support::all_tiers(&program, &scene(&program, mode, size, 64, rect), &what);
        // A pixel the code returns at keeps the cleared depth, 0.
        check(&frame, mode, size, rect, 0, &what);
    }
}

/// Screen triangles (exact edge tests carried along rows) with 0, 4 and 16 shading
/// parameters: coverage equals the 64-bit reference rasterizer on every tier.
#[test]
fn screen_triangles_cover_the_reference_pixels_with_any_parameter_count() {
    let program = support::library();
    let (w, h) = (53, 41);
    let triangles: [[[f32; 4]; 3]; 4] = [
        [[3.2, 4.9, 0.5, 1.0], [49.7, 11.3, 0.5, 1.0], [17.1, 38.8, 0.5, 1.0]],
        [[40.0, 2.5, 0.5, 1.0], [8.5, 8.5, 0.5, 1.0], [30.25, 39.75, 0.5, 1.0]],
        [[0.0, 0.0, 0.5, 1.0], [52.9, 0.1, 0.5, 1.0], [0.2, 40.9, 0.5, 1.0]],
        [[21.03, 17.97, 0.5, 1.0], [23.9, 18.2, 0.5, 1.0], [22.4, 21.6, 0.5, 1.0]],
    ];
    for k in [0usize, 4, 16] {
        for tri in &triangles {
            let mut r = support::renderer(&program, w, h, false);
            r.set_tile_size(16).unwrap();
            for c in 0..k {
                r.material_interp(&format!("p{c}"), "perspective_linear", &[]).unwrap();
            }
            let params: Vec<(String, [Vec<f32>; 3])> = (0..k)
                .map(|c| (format!("p{c}"), [0, 1, 2].map(|i| vec![(i * 7 + c) as f32 * 0.125])))
                .collect();
            let named: Vec<(&str, [Vec<f32>; 3])> = params.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
            support::screen_triangle(&mut r, *tri, &named);
            let what = format!("K={k} {tri:?}");
            let frame = support::all_tiers(&program, &r, &what);
            let v = tri.map(|p| [p[0] as f64, p[1] as f64]);
            let want = support::reference_coverage(v, w, h);
            for py in 0..h {
                for px in 0..w {
                    let got = frame.written(px, py);
                    assert_eq!(got, want[(py * w + px) as usize], "{what}: pixel ({px}, {py})");
                }
            }
        }
    }
}
