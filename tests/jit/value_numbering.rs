//! Tier 0's value numbering while lowering (`Lower::numbered`, src/jit/lower.rs): constants
//! and pure operations computed earlier in the same block are reused. These tests pin down
//! what it must not merge: an expression whose operand local was assigned in between (setup
//! and pixel code, straight-line and through an if-converted `if`), and constants with the
//! same bits but different types (int 1, float 1.0, `true`, two fixed formats). Each against
//! an exact reference, tier 0 against tier 1 (which does not number values).

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::runtime::{Renderer, Value};
use primflow::workload::same_frame;

const CSE: &str = r#"
primitive cse(float rect[4]; float x, y; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float u = x;
    float a = u * y;
    u = u + 1;
    float b = u * y;                    // not a: u changed
    float c = x * y;                    // a again
    if (x > 0)
        u = u * 2;                      // an if-converted side (a select)
    float d = u * y;                    // not b
    int i1 = 1;
    float f1 = 1;
    bool t1 = true;
    fixed<16,0> h1 = 1;                // raw bits 1, like i1, t1 and g1
    fixed<32,0> g1 = 1;
    float ones = i1 + f1 + (t1 ? 1 : 0) + float(h1) + float(g1);
    float v = X;
    float p = v * y;
    v = v + 2;
    float q = v * y;                    // not p
    float r = X * y;                    // p again
    Z = (a + b + c + d + ones + p + q + r) / 1024;
}
"#;

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("cse.prim", CSE)])
}

#[test]
fn repeated_expressions_are_shared_only_where_their_operands_are_the_same_values() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let (x, y) = (1.5f32, 2.0f32);
    let mut r = Renderer::new(program.clone());
    r.set_image_size(40, 8).unwrap();
    r.begin("cse").unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, 40.0, 8.0])).unwrap();
    r.rast_param("x", &Value(vec![x])).unwrap();
    r.rast_param("y", &Value(vec![y])).unwrap();
    r.end().unwrap();
    let frames: Vec<_> = support::jits(&program)
        .into_iter()
        .map(|(name, mut jit)| (name, support::render_with(&r, &mut jit, 1)))
        .collect();
    assert!(same_frame(&frames[0].1, &frames[1].1), "tier 0 and tier 1 differ");
    // a = c = 3, b = 5, d = 10, ones = 5; p = r = 2X, q = 2X + 4: 27 + 6X, every term a
    // whole number, so the sum over 1024 is exact.
    let (x, y) = (f64::from(x), f64::from(y));
    for (name, f) in &frames {
        for px in 0..40u32 {
            let centre = f64::from(px) + 0.5;
            let (a, b, c, d) = (x * y, (x + 1.0) * y, x * y, (x + 1.0) * 2.0 * y);
            let z = (a + b + c + d + 5.0 + centre * y + (centre + 2.0) * y + centre * y) / 1024.0;
            for py in 0..8 {
                assert_eq!(
                    f.depth_at(px, py),
                    Some((z * 4294967296.0) as u32),
                    "{name} at ({px}, {py})"
                );
            }
        }
    }
}
