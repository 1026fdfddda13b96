//! Uniform values meeting varying ones in pixel code, in the forms lowered without a
//! per-group broadcast: a ternary whose condition is uniform and whose arms are varying (a
//! scalar `select` of whole vectors, not a lane mask and a blend), and uniform frame words
//! as operands of a built-in (`cross`), of an array literal and of a matrix product (their
//! splats loaded from the uniform frame's vector section), a varying ternary whose arms are
//! uniform operations, and varying built-ins with uniform-operation arguments (both
//! evaluated once per kernel run). The depths must equal a Rust reference computed with the
//! same f32 operations, bit for bit, on every tier, for both values of the condition. Also:
//! tier 1 stores the splat of a frame word only when a group loads it.

use crate::support;

use primflow::diag::SourceMap;
use primflow::runtime::{Renderer, Value};

const PRIM: &str = r#"
primitive uniform_operands(float rect[4]; float a; float g[3]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    // Uniform locals the pixel code only reads: they live in the uniform frame.
    float s = g[0] * 2;
    float m[2][3] = {{g[0], g[1], g[2]}, {s, g[2], 1}};
    bool pick_x = a != 0;
    float lo = X * 0.015625, hi = Y * 0.015625 + 0.5;
    float v = pick_x ? lo : hi;
    float p[3] = {X, Y, s};
    float c[3] = cross(g, p);
    float mp[2] = m * p;
    // A varying condition choosing between uniform operations (evaluated once per run).
    float side = X < 10 ? -g[1] * 3 : g[2] + s;
    // Uniform operations as arguments of varying built-ins (also evaluated once per run).
    float bounded = clamp(X * 0.25, -g[0] * 2, g[2] + 1) + max(Y * 0.125, g[1] * g[1]);
    Z = v + (c[0] + c[1] + c[2] + mp[0] - mp[1] + side + bounded) * 0.0009765625;
}
"#;

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The prim's depth at pixel centre (x, y), in its operation order.
#[allow(clippy::manual_clamp)]
fn expected(a: f32, g: [f32; 3], x: f32, y: f32) -> u32 {
    let s = g[0] * 2.0;
    let v = if a != 0.0 { x * 0.015625 } else { y * 0.015625 + 0.5 };
    let p = [x, y, s];
    let c = cross(g, p);
    let mp0 = g[0] * p[0] + g[1] * p[1] + g[2] * p[2];
    let mp1 = s * p[0] + g[2] * p[1] + 1.0 * p[2];
    let side = if x < 10.0 { -g[1] * 3.0 } else { g[2] + s };
    // clamp is the JIT's max then min.
    let bounded = (x * 0.25).max(-g[0] * 2.0).min(g[2] + 1.0) + (y * 0.125).max(g[1] * g[1]);
    let z = v + ((((((c[0] + c[1]) + c[2]) + mp0) - mp1) + side) + bounded) * 0.0009765625;
    (z * 4294967296.0).round_ties_even() as u32
}

#[test]
fn uniform_conditions_and_frame_words_in_pixel_code_match_a_reference_on_every_tier() {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("uniform_operands.prim", PRIM)]);
    let (w, h) = (21u32, 10u32);
    let g = [0.375f32, -0.8125, 0.15625];
    let mut r = Renderer::new(program.clone());
    r.set_image_size(w, h).unwrap();
    r.set_tile_size(8).unwrap();
    // The top half takes the condition's true arm, the bottom half its false arm.
    for (a, y0, y1) in [(1.0f32, 0.0f32, 5.0f32), (0.0, 5.0, 10.0)] {
        r.begin("uniform_operands").unwrap();
        r.rast_param("rect", &Value(vec![0.0, y0, w as f32, y1])).unwrap();
        r.rast_param("a", &Value(vec![a])).unwrap();
        r.rast_param("g", &Value(g.to_vec())).unwrap();
        r.end().unwrap();
    }
    let frame = support::all_tiers(&program, &r, "uniform operands");
    for y in 0..h {
        for x in 0..w {
            let a = if y < 5 { 1.0 } else { 0.0 };
            let want = expected(a, g, x as f32 + 0.5, y as f32 + 0.5);
            assert_eq!(frame.depth_at(x, y), Some(want), "pixel ({x}, {y})");
        }
    }
}

const FRAME_SPLATS: &str = r#"
primitive frame_splats(float rect[4]; float a, b, c; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float in_groups = a + 1;    // a group operand: read from its splat
    float in_rows = b * 0.5;    // read only by the row term `Y * in_rows`
    float d = c * 2 > 100 ? 0 : 0.25;
    Z = (X * in_groups + Y * in_rows + d) * 0.0009765625;
}
"#;

/// Stores in printed CLIF whose value a `splat` defined.
fn splat_stores(clif: &str) -> usize {
    let splats: std::collections::HashSet<&str> = clif
        .lines()
        .filter_map(|l| l.trim().split_once(" = splat."))
        .map(|(v, _)| v)
        .collect();
    clif.lines()
        .filter_map(|l| l.trim().strip_prefix("store "))
        .filter(|rest| rest.split([' ', ',']).any(|w| splats.contains(w)))
        .count()
}

/// Tier 1 splats a uniform frame word to the vector section only when a group reads the
/// splat: `in_rows` (a row term's operand, read once per row as a scalar) gets no splat
/// store, `in_groups` and `d` do (and the render pass stores its x range, lo_x and hi_x,
/// as two splats). The depths stay the reference's.
#[test]
fn only_words_a_group_reads_are_splatted_to_the_frame() {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("frame_splats.prim", FRAME_SPLATS)]);
    let (w, h) = (13u32, 6u32);
    let (a, b, c) = (0.75f32, -1.5f32, 3.0f32);
    let mut r = Renderer::new(program.clone());
    r.set_image_size(w, h).unwrap();
    r.begin("frame_splats").unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, w as f32, h as f32]))
        .unwrap();
    for (name, v) in [("a", a), ("b", b), ("c", c)] {
        r.rast_param(name, &Value(vec![v])).unwrap();
    }
    r.end().unwrap();
    let (in_groups, in_rows, d) = (a + 1.0, b * 0.5, 0.25f32);
    support::assert_depth_in_every_jit(&r, "frame splats", |x, y| {
        let (x, y) = (x as f32 + 0.5, y as f32 + 0.5);
        let z = (x * in_groups + y * in_rows + d) * 0.0009765625;
        (z * 4294967296.0).round_ties_even() as u32
    });
    let inst = r.instances()[0].clone();
    let jit = primflow::jit::Jit::new(program.clone()).unwrap();
    let clif = jit.clif(inst.func, &inst.key).unwrap();
    assert_eq!(splat_stores(&clif), 2 + 2, "{clif}");
}
