//! Loop unrolling before lowering (src/mid/unroll.rs): a primitive with constant-trip loops
//! (unrolled) and loops whose trip count is a run-time value (kept) must render the same
//! frame and report the same run-time errors (out-of-range index, out of fuel, at the same
//! source sites) with unrolling on and off, and unrolling must actually remove the loops'
//! code.

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, JitOptions, Tier};
use primflow::runtime::{Renderer, Value};
use primflow::workload::same_frame;

const LOOPS: &str = r#"
primitive loops(
    float rect[4];
    int n;              // trip count of the run-time loops
    int spin;           // > 0: a loop that never ends
    int over;           // > 0: a constant-trip loop indexes out of range
    varying float X, Y;
    inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float w[4];
    for (int i = 0; i < 4; i++)
        w[i] = (i + 1) * 0.125;
    int acc = 0;
    for (int i = 0; i < n; i++)
        acc = acc + i;
    float a[3];
    for (int i = 0; i < n; i++)
        a[i] = i * 0.25;
    for (int i = 0; i < 5; i++) {
        int j = (i + 2) % 5;
        if (i < 3 && j < 4)
            a[i] = a[i] + w[j];
    }
    for (int i = 0; i < 4; i++) {
        if (over > 0)
            a[i] = a[i] * 2;
    }
    int s = spin;
    while (s > 0) {
        s = s + 1;
    }
    if (X > rect[2] - 1) return;
    Z = w[int(X) % 4] * 0.5 + a[int(Y) % 3] * 0.1 + acc * 0.001;
}
"#;

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("loops.prim", LOOPS)])
}

fn scene(program: &Arc<Program>, n: i32, spin: i32, over: i32) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(40, 24).unwrap();
    r.set_tile_size(16).unwrap();
    r.begin("loops").unwrap();
    r.rast_param("rect", &Value(vec![2.0, 3.0, 37.0, 21.0])).unwrap();
    r.rast_param("n", &Value(vec![n as f32])).unwrap();
    r.rast_param("spin", &Value(vec![spin as f32])).unwrap();
    r.rast_param("over", &Value(vec![over as f32])).unwrap();
    r.end().unwrap();
    r
}

fn jit(program: &Arc<Program>, unroll_loops: bool, tier: Tier) -> Jit {
    Jit::with_options(program.clone(), JitOptions { tier, unroll_loops }).unwrap()
}

#[test]
fn unrolled_and_kept_loops_give_the_same_pixels_and_errors() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    // (n, spin, over) -> the run-time errors reported (every failing site): none;
    // `a[i] = i * 0.25` out of range in a run-time loop; the `while` out of fuel (its setup
    // runs out: nothing is drawn); `a[i] = a[i] * 2` out of range in a constant-trip loop
    // (unrolled: a constant index), both where it writes and where it reads.
    let expected: [(i32, i32, i32, &[&str]); 4] = [
        (3, 0, 0, &[]),
        (5, 0, 0, &["W0801@19:11"]),
        (2, 1, 0, &["W0801@30:5"]),
        (3, 0, 1, &["W0801@27:15", "W0801@27:22"]),
    ];
    for (n, spin, over, codes) in expected {
        let r = scene(&program, n, spin, over);
        let mut frames = vec![];
        for unroll in [false, true] {
            for tier in [Tier::Fast, Tier::Optimised] {
                let out = r.render(&mut jit(&program, unroll, tier));
                assert!(!out.diags.has_errors(), "{:?}", out.diags.items);
                let mut got = out.diags.codes_at(&sources);
                got.dedup();
                assert_eq!(got, codes.to_vec(), "n={n} spin={spin} unroll={unroll} {tier:?}");
                frames.push(out.frame);
            }
        }
        let drawn = frames[0].depth_values().iter().filter(|&&d| d != 0).count();
        if spin > 0 {
            assert_eq!(drawn, 0, "out of fuel in setup: drawn");
        } else {
            assert!(drawn > 100, "draws");
        }
        for f in &frames[1..] {
            assert!(same_frame(&frames[0], f), "n={n} spin={spin}: frames differ");
        }
    }
}

#[test]
fn unrolling_removes_the_constant_loops_code() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let r = scene(&program, 3, 0, 0);
    let inst = &r.instances()[0];
    let kept = jit(&program, false, Tier::Optimised)
        .clif(inst.func, &inst.key)
        .unwrap();
    let unrolled = jit(&program, true, Tier::Optimised).clif(inst.func, &inst.key).unwrap();
    // Each kept loop spends fuel (a load of ctx.fuel and a store back) per trip: 5 loops
    // kept, 3 (the run-time ones and the while) after unrolling.
    let fuel_checks = |clif: &str| {
        clif.lines()
            .filter(|l| l.contains("v0+") && l.contains("store"))
            .count()
    };
    assert!(
        fuel_checks(&unrolled) < fuel_checks(&kept),
        "fewer stores to ctx: {} vs {}",
        fuel_checks(&unrolled),
        fuel_checks(&kept)
    );
    assert!(unrolled.lines().count() < kept.lines().count());

    // The screen triangle: its constant loops go, and so do the stack slots of its arrays.
    let fill = primflow::workload::fill_scene(&program, 32, 1, Some("perspective_linear"), 4);
    let inst = &fill.instances()[0];
    let kept = jit(&program, false, Tier::Optimised)
        .clif(inst.func, &inst.key)
        .unwrap();
    let unrolled = jit(&program, true, Tier::Optimised).clif(inst.func, &inst.key).unwrap();
    let slots = |clif: &str| clif.lines().filter(|l| l.contains("explicit_slot")).count();
    assert!(
        slots(&unrolled) + 10 <= slots(&kept),
        "arrays indexed by a constant-trip loop leave the stack: {} vs {} slots",
        slots(&unrolled),
        slots(&kept)
    );
}

/// Folding a `?:` whose condition is constant leaves its uniform arm: the expression
/// around it is then uniform too (the IR validator's `ExprVariability`, which made this an
/// internal compiler error at both tiers with unrolling on). Every pixel of the bound gets
/// `Z = n / 100`, unrolled or not.
#[test]
fn a_folded_select_leaves_its_enclosing_expression_uniform() {
    const FOLDS: &str = r#"
primitive folds(float rect[4]; int n; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    int v = 0;
    if (Y > 3) v = 1;
    float s = (1 < 0 ? v : 0) + n;
    Z = s * 0.01;
}
"#;
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("folds.prim", FOLDS)]);
    let mut r = Renderer::new(program.clone());
    r.set_image_size(16, 12).unwrap();
    r.begin("folds").unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, 16.0, 12.0])).unwrap();
    r.rast_param("n", &Value(vec![37.0])).unwrap();
    r.end().unwrap();
    let want = support::raw_depth(f64::from(37.0f32 * 0.01f32));
    for unroll in [false, true] {
        for tier in [Tier::Fast, Tier::Optimised] {
            let out = r.render(&mut jit(&program, unroll, tier));
            assert!(
                out.diags.items.is_empty(),
                "unroll={unroll} {tier:?}: {:?}",
                out.diags.items
            );
            let depths = out.frame.depth_values();
            assert_eq!(depths.len(), 16 * 12);
            assert!(depths.iter().all(|&d| d == want), "unroll={unroll} {tier:?}");
        }
    }
}
