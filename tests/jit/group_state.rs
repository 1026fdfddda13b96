//! Per-pixel semantics across pixel groups: a primitive is written as if it ran at one
//! pixel, so every pixel runs its pixel part from the state the setup left. The JIT runs the
//! pixel part once per group of 4 pixels, over and over within a tile; a uniform local that
//! the pixel part assigns (a loop counter, an array updated in place) must not carry one
//! group's last value into the next. Every case renders with both tiers, checks every pixel
//! of the rectangle against the value one pixel computes alone, and compares the tiers.

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use primflow::runtime::{Frame, Renderer, Value};
use primflow::workload::same_frame;

/// Three ways a uniform local is assigned in the pixel part: a top-level `for` whose
/// `i = 0` the split hoists into the setup (it is uniform and nothing before it in the
/// pixel part uses `i`; `n0` trips, `form` 0); a counter initialised before the first
/// per-pixel statement (`form` 1); a dynamically indexed uniform array incremented in place
/// (`form` 2). One pixel alone computes Z = X * 1e-4 plus 0.01 added n times (`form` 0 and
/// 1) or plus (1 + 2 + 3 + n) * 0.01 (`form` 2).
const COUNTERS: &str = r#"
primitive counters(
    float rect[4];
    int form;
    int n0;
    int n;
    int k;
    varying float X, Y;
    inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    int j = 0;
    float t[3] = {1, 2, 3};
    if (X < -1) return;
    float acc = X * 0.0001;
    for (int i = 0; i < n0; i++)
        acc = acc + 0.01;
    if (form == 1) {
        for (; j < n; j++)
            acc = acc + 0.01;
    } else if (form == 2) {
        for (int i = 0; i < n; i++)
            t[k] = t[k] + 1;
        acc = acc + (t[0] + t[1] + t[2]) * 0.01;
    }
    Z = acc;
}
"#;

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("counters.prim", COUNTERS)])
}

fn render(program: &Arc<Program>, tier: Tier, rect: [f32; 4], form: i32, n: i32, k: i32) -> Frame {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(40, 24).unwrap();
    r.set_tile_size(16).unwrap();
    r.begin("counters").unwrap();
    r.rast_param("rect", &Value(rect.to_vec())).unwrap();
    let n0 = if form == 0 { n } else { 0 };
    for (name, v) in [("form", form), ("n0", n0), ("n", n), ("k", k)] {
        r.rast_param(name, &Value(vec![v as f32])).unwrap();
    }
    r.end().unwrap();
    let mut jit = Jit::at_tier(program.clone(), tier).unwrap();
    let out = r.render(&mut jit);
    assert!(!out.diags.has_errors(), "{:?}", out.diags.items);
    out.frame
}

/// Z of one pixel at centre x, computed as the source does in f32.
fn one_pixel(x: f32, form: i32, n: i32) -> f32 {
    let mut acc = x * 0.0001;
    if form < 2 {
        for _ in 0..n {
            acc += 0.01;
        }
    } else {
        acc += (1.0 + 2.0 + 3.0 + n as f32) * 0.01;
    }
    acc
}

#[test]
fn uniform_locals_the_pixel_part_assigns_start_every_group_from_the_setup_value() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    // Off the group grid and across tile edges (16 px tiles): many groups per tile.
    let rect = [2.3, 3.0, 37.0, 21.0];
    for form in 0..3 {
        for n in [1, 3, 7] {
            let frames: Vec<Frame> = [Tier::Fast, Tier::Optimised]
                .into_iter()
                .map(|tier| render(&program, tier, rect, form, n, 1))
                .collect();
            assert!(
                same_frame(&frames[0], &frames[1]),
                "form {form} n {n}: tier 0 and tier 1 differ"
            );
            let frame = &frames[1];
            let mut checked = 0;
            for y in 0..24u32 {
                for x in 0..40u32 {
                    let (cx, cy) = (x as f32 + 0.5, y as f32 + 0.5);
                    let inside = cx >= rect[0] && cx <= rect[2] && cy >= rect[1] && cy <= rect[3];
                    assert_eq!(frame.written(x, y), inside, "form {form} n {n}: pixel ({x}, {y})");
                    if inside {
                        let got = frame.depth_f32_at(x, y).unwrap();
                        let want = one_pixel(cx, form, n);
                        assert!(
                            (got - want).abs() < 1e-6,
                            "form {form} n {n}: pixel ({x}, {y}) has Z {got}, one pixel alone computes {want}"
                        );
                        checked += 1;
                    }
                }
            }
            assert_eq!(checked, 35 * 18);
        }
    }
}
