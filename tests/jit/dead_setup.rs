//! Tier 0 does not lower setup assignments nothing live reads (src/mid/dead.rs). Its
//! walk goes last statement to first and stops after one round unless an assignment it
//! skipped as dead turned out to be read above it: in a loop kept as a loop, a value
//! assigned at the bottom of the body is read at the top of the next trip, so those
//! assignments are only found live in later rounds. Stopping early would drop them, and
//! tier 0 would render different depths from tier 1.

use crate::support;

use primflow::jit::{Jit, Tier};
use primflow::runtime::{Frame, Renderer, Value};
use primflow::workload::same_frame;

/// `acc` reads `prev` before the body assigns it, and `prev` reads `cur` before the body
/// assigns that: three rounds of the walk (n is a parameter, so the loop is not unrolled).
const CARRIED: &str = r#"
primitive carried(
    float rect[4];
    int n;
    varying float X, Y;
    inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float prev = 0;
    float cur = 0.25;
    float acc = 0;
    for (int i = 0; i < n; i++) {
        acc = acc + prev;
        prev = cur;
        cur = cur * 2;
    }
    Z = acc * 0.01 + X * 0.001 + Y * 0.0001;
}
"#;

fn render(program: &std::sync::Arc<primflow::ir::Program>, n: f32, tier: Tier) -> Frame {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(24, 16).unwrap();
    r.begin("carried").unwrap();
    r.rast_param("rect", &Value(vec![1.0, 2.0, 20.0, 14.0])).unwrap();
    r.rast_param("n", &Value(vec![n])).unwrap();
    r.end().unwrap();
    let mut jit = Jit::at_tier(program.clone(), tier).unwrap();
    let out = r.render(&mut jit);
    assert!(out.diags.items.is_empty(), "n {n}: {:?}", out.diags.items);
    out.frame
}

#[test]
fn loop_carried_setup_values_stay_live_at_tier_0() {
    let mut sources = primflow::diag::SourceMap::new();
    let program = support::library_with(&mut sources, &[("carried.prim", CARRIED)]);
    let mut tier1 = vec![];
    for n in [0.0, 1.0, 2.0, 5.0] {
        let fast = render(&program, n, Tier::Fast);
        let slow = render(&program, n, Tier::Optimised);
        assert!(same_frame(&fast, &slow), "n {n}: tier 0 and tier 1 differ");
        let covered = fast.depth_values().iter().filter(|&&d| d != 0).count();
        assert_eq!(covered, 19 * 12, "n {n}: pixels written");
        tier1.push(slow);
    }
    // acc after n trips: 0, 0, 0.25, 3.75 (the first trip adds prev = 0, the second 0.25,
    // then 0.5, 1, 2): a tier that lost `prev = cur` or `cur = cur * 2` would stay at 0 or
    // at 1.0 and differ from tier 1 above.
    assert!(same_frame(&tier1[0], &tier1[1]), "n 0 and 1 both leave acc = 0");
    assert!(!same_frame(&tier1[1], &tier1[2]), "n = 2 adds 0.25 to acc");
    assert!(!same_frame(&tier1[2], &tier1[3]), "n = 5 adds 0.25 + 0.5 + 1 + 2 more");
}
