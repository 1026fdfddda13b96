//! Row terms through pixel locals: a varying local assigned once at the top of the pixel
//! code from a value that depends on Y alone (`float dy = Y - sy;`) makes the terms that read
//! it row terms (`dy * g`, scalar and array), evaluated once per row with the local
//! replaced by its value. The depths must equal a Rust reference with the same f32
//! operations, bit for bit, on every tier, including locals that must NOT be treated so:
//! one assigned twice, one assigned inside a branch, and one that reads X.

use crate::support;

use primflow::diag::SourceMap;
use primflow::runtime::{Renderer, Value};

const PRIM: &str = r#"
primitive row_locals(float rect[4]; float sy; float g[3]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float dx = X - 10;
    float dy = Y - sy;                   // a row local
    float dy2 = dy * 0.5 + g[2];         // a row local reading another
    float v[3] = dx * g + dy * g;        // dy * g: an array row term
    float w = dx * g[0] + dy2 * g[1];    // dy2 * g[1]: a scalar row term
    float twice = Y * 0.25;              // assigned twice: not a row local
    if (dx > 3)
        twice = dx * 0.125;
    float in_branch = 0;
    if (dx < 0) {
        float late = Y * 0.0625;         // assigned inside a branch: not a row local
        in_branch = late * g[0];
    }
    float mixed = dx + dy;               // reads X: not a row local
    Z = 0.5 + (v[0] + v[1] + v[2] + w + twice * g[1] + in_branch + mixed * g[2]) * 0.0009765625;
}
"#;

/// The prim's depth at pixel centre (x, y), in its operation order.
fn expected(sy: f32, g: [f32; 3], x: f32, y: f32) -> u32 {
    let dx = x - 10.0;
    let dy = y - sy;
    let dy2 = dy * 0.5 + g[2];
    let v: [f32; 3] = std::array::from_fn(|c| dx * g[c] + dy * g[c]);
    let w = dx * g[0] + dy2 * g[1];
    let twice = if dx > 3.0 { dx * 0.125 } else { y * 0.25 };
    let in_branch = if dx < 0.0 { (y * 0.0625) * g[0] } else { 0.0 };
    let mixed = dx + dy;
    let sum = (((((v[0] + v[1]) + v[2]) + w) + twice * g[1]) + in_branch) + mixed * g[2];
    let z = 0.5 + sum * 0.0009765625;
    (z * 4294967296.0).round_ties_even() as u32
}

#[test]
fn row_terms_through_locals_match_a_reference_on_every_tier() {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("row_locals.prim", PRIM)]);
    let (w, h) = (23u32, 19u32);
    let g = [0.3f32, -0.7, 0.11];
    let sy = 7.3f32;
    let mut r = Renderer::new(program.clone());
    r.set_image_size(w, h).unwrap();
    r.set_tile_size(8).unwrap();
    r.begin("row_locals").unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, w as f32, h as f32]))
        .unwrap();
    r.rast_param("sy", &Value(vec![sy])).unwrap();
    r.rast_param("g", &Value(g.to_vec())).unwrap();
    r.end().unwrap();
    let frame = support::all_tiers(&program, &r, "row locals");
    for y in 0..h {
        for x in 0..w {
            let want = expected(sy, g, x as f32 + 0.5, y as f32 + 0.5);
            assert_eq!(frame.depth_at(x, y), Some(want), "pixel ({x}, {y})");
        }
    }
}

/// Row terms through built-ins and elements of row-local arrays: `cross(g, a)` of a row
/// local is a row local itself, `dot`, `length`, `normalize`, `clamp` ... of row locals are
/// row terms, and so is `a[1]` (the prologue substitutes `a`'s value and takes the element;
/// reading the local's storage there instead would read a value no group has written yet);
/// `q`, which only row terms read, is not assigned in the groups at all.
const BUILTINS: &str = r#"
primitive row_builtins(float rect[4]; float sy; float g[3]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float dx = X - 10;
    float dy = Y - sy;                          // a row local
    float a[3] = dy * g + g;                    // a row-local array
    float n[3] = cross(g, a);                   // a built-in of a row local: a row local
    float s = dot(a, n) + length(a) * a[1];     // built-ins and an element of a row local
    float m = clamp(a[0], -1, 1) + min(n[2], 0.5) + max(n[0], -0.5) + sqrt(abs(a[2]))
              + floor(dy * 0.3) + ceil(a[1]) + round(a[0] * 3) + sign(a[1]);
    float u[3] = normalize(a);
    float e = mix(a[0], a[1], 0.25) + step(0.1, a[2]) + smoothstep(0, 2, a[0]) + distance(a, g);
    float q[3] = cross(a, g);                   // only row terms read it: no group does
    float qq = dot(q, q) * 0.5;
    float lx = dx * a[2] + s;                   // a row-local element times X
    float mixed = max(dx, dy);                  // reads X: not a row term
    float late = 0;
    if (dx < 2)
        late = dot(a, a);                       // in a branch: still a row term (pure)
    Z = 0.5 + (lx + m * dx + u[0] * dx + n[1] + e + mixed * g[2] + late + qq) * 0.0009765625;
}
"#;

/// `BUILTINS`'s depth at pixel centre (x, y), with the JIT's operations for each built-in
/// (`clamp` is its max then min, written out).
#[allow(clippy::manual_clamp)]
fn expected_builtins(sy: f32, g: [f32; 3], x: f32, y: f32) -> u32 {
    let dot = |p: [f32; 3], q: [f32; 3]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
    let dx = x - 10.0;
    let dy = y - sy;
    let a: [f32; 3] = std::array::from_fn(|c| dy * g[c] + g[c]);
    let n = [
        g[1] * a[2] - g[2] * a[1],
        g[2] * a[0] - g[0] * a[2],
        g[0] * a[1] - g[1] * a[0],
    ];
    let len = dot(a, a).sqrt();
    let s = dot(a, n) + len * a[1];
    let sign = |v: f32| {
        if v > 0.0 {
            1.0
        } else if v < 0.0 {
            -1.0
        } else {
            0.0
        }
    };
    let m = a[0].max(-1.0).min(1.0)
        + n[2].min(0.5)
        + n[0].max(-0.5)
        + a[2].abs().sqrt()
        + (dy * 0.3).floor()
        + a[1].ceil()
        + (a[0] * 3.0).round_ties_even()
        + sign(a[1]);
    let u0 = a[0] / len;
    let t = ((a[0] - 0.0) / (2.0 - 0.0)).max(0.0).min(1.0);
    let smooth = (t * t) * (3.0 - 2.0 * t);
    let d: [f32; 3] = std::array::from_fn(|c| a[c] - g[c]);
    let e = ((a[0] + (a[1] - a[0]) * 0.25) + if a[2] < 0.1 { 0.0 } else { 1.0 }) + smooth + dot(d, d).sqrt();
    let q = [
        a[1] * g[2] - a[2] * g[1],
        a[2] * g[0] - a[0] * g[2],
        a[0] * g[1] - a[1] * g[0],
    ];
    let qq = dot(q, q) * 0.5;
    let lx = dx * a[2] + s;
    let mixed = dx.max(dy);
    let late = if dx < 2.0 { dot(a, a) } else { 0.0 };
    let sum = ((((((lx + m * dx) + u0 * dx) + n[1]) + e) + mixed * g[2]) + late) + qq;
    let z = 0.5 + sum * 0.0009765625;
    (z * 4294967296.0).round_ties_even() as u32
}

#[test]
fn row_terms_through_builtins_and_row_local_elements_match_a_reference_on_every_tier() {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("row_builtins.prim", BUILTINS)]);
    let (w, h) = (23u32, 19u32);
    let g = [0.3f32, -0.7, 0.11];
    let sy = 7.3f32;
    let mut r = Renderer::new(program.clone());
    r.set_image_size(w, h).unwrap();
    r.set_tile_size(8).unwrap();
    r.begin("row_builtins").unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, w as f32, h as f32]))
        .unwrap();
    r.rast_param("sy", &Value(vec![sy])).unwrap();
    r.rast_param("g", &Value(g.to_vec())).unwrap();
    r.end().unwrap();
    let frame = support::all_tiers(&program, &r, "row built-ins");
    for y in 0..h {
        for x in 0..w {
            let want = expected_builtins(sy, g, x as f32 + 0.5, y as f32 + 0.5);
            assert_eq!(frame.depth_at(x, y), Some(want), "pixel ({x}, {y})");
        }
    }
}
