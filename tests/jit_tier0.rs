//! Tier 0's lighter lowering (src/jit/lower.rs, `Lower::tier0`): small uniform `if`s of setup
//! code become straight-line code with selects, `if (c) return;` in setup is one branch,
//! locals get no explicit zero, repeated argument loads are shared, stores have no
//! all-lanes fast path and the uniform frame keeps no splatted copies. None of that may
//! change a pixel or a run-time error: every case here renders with tier 0 and tier 1 and
//! compares the frames bit for bit and the errors code for code. Also: the JIT reports what
//! a compile cost in thread CPU time (`Jit::compile_cost`).

use std::sync::Arc;

use primflow::bench::same_frame;
use primflow::diag::{Diagnostics, SourceMap};
use primflow::ir::Program;
use primflow::jit::{Jit, JitOptions, Tier};
use primflow::runtime::{Frame, Registry, Renderer, Value};

/// Setup code with nested uniform `if`s that only assign (if-converted by tier 0), a local
/// read on a path where nothing assigned it (zero), a dynamically indexed store inside an
/// `if` (not if-converted: taken with `k` out of range it records an error, untaken it must
/// not) and an early `return`.
const BRANCHY: &str = r#"
primitive branchy(
    float rect[4];
    float mode;
    int k;
    varying float X, Y;
    inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[3];
    float s;
    if (mode > 1) {
        a[0] = rect[0] * 0.5;
        a[1] = a[0] + 1;
        if (mode > 2)
            s = a[1] * 2;
        else
            a[2] = 0.25;
    } else {
        a[2] = mode;
    }
    float w[2];
    if (mode > 3)
        w[k] = 7;
    if (mode < -10) return;
    Z = (a[0] + a[1] + a[2] + s + w[0] + w[1]) * 0.01 + X * 0.001 + Y * 0.0001;
}
"#;

fn library(sources: &mut SourceMap) -> Arc<Program> {
    let mut diags = Diagnostics::new();
    let (mut files, _) = Registry::load_sources(sources, &[], &[], &mut diags);
    files.push(sources.add("branchy.prim", BRANCHY));
    let reg = Registry::compile(sources, files, &mut diags);
    assert!(!diags.has_errors(), "{}", diags.render(sources));
    reg.expect("compiles").program
}

fn branchy_scene(program: &Arc<Program>, mode: f32, k: i32) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(40, 24).unwrap();
    r.set_tile_size(16).unwrap();
    r.begin("branchy").unwrap();
    r.rast_param("rect", &Value(vec![2.0, 3.0, 37.0, 21.0])).unwrap();
    r.rast_param("mode", &Value(vec![mode])).unwrap();
    r.rast_param("k", &Value(vec![k as f32])).unwrap();
    r.end().unwrap();
    r
}

fn jit(program: &Arc<Program>, tier: Tier) -> Jit {
    Jit::with_options(
        program.clone(),
        JitOptions {
            tier,
            ..JitOptions::default()
        },
    )
    .unwrap()
}

fn written(f: &Frame) -> usize {
    f.depth.iter().filter(|&&d| d != 0).count()
}

/// Render `r` with both tiers: the frame and the run-time error codes must agree.
fn both_tiers(sources: &SourceMap, program: &Arc<Program>, r: &Renderer, what: &str) -> (Frame, Vec<String>) {
    let mut results = vec![];
    for tier in [Tier::Fast, Tier::Optimised] {
        let out = r.render(&mut jit(program, tier));
        assert!(!out.diags.has_errors(), "{what}: {:?}", out.diags.items);
        let mut codes = out.diags.codes_at(sources);
        codes.dedup();
        results.push((out.frame, codes));
    }
    let (slow, fast) = (results.pop().unwrap(), results.pop().unwrap());
    assert!(same_frame(&fast.0, &slow.0), "{what}: tier 0 and tier 1 frames differ");
    assert_eq!(fast.1, slow.1, "{what}: tier 0 and tier 1 report different errors");
    fast
}

#[test]
fn if_converted_setup_gives_the_same_pixels_and_errors_as_branches() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    // mode picks the branches: else side; outer then + inner else; both thens; the
    // dynamically indexed store in range; out of range (an error, index clamped); the
    // early return.
    let cases: [(f32, i32, bool, bool); 6] = [
        (0.5, 0, false, true),
        (2.0, 0, false, true),
        (3.0, 0, false, true),
        (4.0, 1, false, true),
        (4.0, 5, true, true),
        (-20.0, 5, false, false),
    ];
    let mut frames: Vec<Frame> = vec![];
    for (mode, k, error, draws) in cases {
        let r = branchy_scene(&program, mode, k);
        let (frame, codes) = both_tiers(&sources, &program, &r, &format!("mode {mode} k {k}"));
        assert_eq!(!codes.is_empty(), error, "mode {mode} k {k}: errors {codes:?}");
        assert_eq!(written(&frame) > 0, draws, "mode {mode} k {k}: draws");
        frames.push(frame);
    }
    // The branches matter: each of the first four modes writes different depths.
    for i in 0..4 {
        for j in i + 1..4 {
            assert!(
                !same_frame(&frames[i], &frames[j]),
                "modes {i} and {j} give the same frame"
            );
        }
    }
    // Out of range, `w[k]` clamps to `w[1]`: the same pixels as k = 1.
    assert!(same_frame(&frames[3], &frames[4]));
}

#[test]
fn screen_triangle_float_coverage_and_snapped_planes_agree_across_tiers() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let mut r = Renderer::new(program.clone());
    r.set_image_size(128, 160).unwrap();
    r.set_tile_size(32).unwrap();
    // Wider than 1024 pixels: the float edge functions (`if (!exact)` taken).
    let big = [
        [-1500.0, -700.0, 0.25, 1.0],
        [2000.0, 30.0, 0.5, 2.0],
        [20.0, 1900.0, 0.75, 1.5],
    ];
    // Degenerate as given (the second and third vertices are the first plus d and 2d, so
    // the products cancel exactly) but not once snapped to 1/16 pixel: the planes come from
    // the snapped corners (`if (plane_det == 0 ...)` taken).
    let d = [50.015625f32, 70.015625f32];
    let sliver = [
        [10.0, 10.0, 0.9, 1.0],
        [10.0 + d[0], 10.0 + d[1], 0.9, 1.0],
        [10.0 + 2.0 * d[0], 10.0 + 2.0 * d[1], 0.9, 1.0],
    ];
    for v in [big, sliver] {
        r.begin("screen_triangle").unwrap();
        r.rast_param("screen_vertex", &Value(v.iter().flatten().copied().collect()))
            .unwrap();
        for _ in 0..3 {
            r.sequence_point().unwrap();
        }
        r.end().unwrap();
    }
    let (frame, codes) = both_tiers(&sources, &program, &r, "big and sliver triangles");
    assert!(codes.is_empty(), "{codes:?}");
    assert_eq!(written(&frame), 128 * 160, "the big triangle covers the image");
}

#[test]
fn the_jit_reports_compile_cost_in_thread_cpu_time() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let r = primflow::bench::fill_scene(&program, 32, 1, Some("perspective_linear"), 4);
    let inst = &r.instances()[0];
    let mut tiered = Jit::tiered(program.clone()).unwrap();
    assert!(
        tiered.compile_cost(inst.func, &inst.key).is_none(),
        "nothing compiled yet"
    );
    tiered.kernel(inst.func, &inst.key).unwrap();
    let tier0 = tiered.compile_cost(inst.func, &inst.key).expect("tier 0 compiled");
    tiered.wait_for_tier_up();
    let tier1 = tiered
        .tier_up_compile_cost(inst.func, &inst.key)
        .expect("tier 1 compiled in the background");
    for (name, c) in [("tier 0", tier0), ("tier 1", tier1)] {
        assert!(c.wall_micros > 0, "{name}: {c:?}");
        assert!(
            c.batch_cpu_micros >= c.cpu_micros,
            "{name}: the batch includes the kernel: {c:?}"
        );
        if cfg!(target_os = "linux") {
            assert!(c.cpu_micros > 0, "{name}: thread CPU time is measured: {c:?}");
        }
    }
}
