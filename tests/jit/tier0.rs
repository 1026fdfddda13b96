//! Tier 0's lighter lowering (src/jit/lower.rs, `Lower::tier0`): `if (c) return;` in setup
//! is one branch, locals get no explicit zero, repeated argument loads are shared, stores
//! have no all-lanes fast path and the uniform frame keeps no splatted copies; and, at both
//! tiers, small uniform `if`s of setup code become straight-line code with selects (checked
//! against the source's values too). None of that may change a pixel or a run-time error:
//! every case here renders with tier 0 and tier 1 and compares the frames bit for bit and
//! the errors code for code. Also: the JIT reports what a compile cost in thread CPU time
//! (`Jit::compile_cost`).

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use primflow::runtime::{Frame, Renderer, Value};
use primflow::workload::same_frame;

/// Setup code with nested uniform `if`s that only assign (if-converted by both tiers), a local
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

/// Pixel code tier 0 lowers *flat* (src/mid/flat.rs: no early exit when a group's
/// last lane retires, uniform `if`s run as masked ones): a varying guard, a uniform `if`
/// with a guard and a uniform-indexed read that may fail on one side and a varying `if` on
/// the other. The failing read must report an error exactly when tier 1 runs it for some
/// lane.
const FLATTY: &str = r#"
primitive flatty(
    float rect[4];
    float mode;
    int k;
    varying float X, Y;
    inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float tab[3];
    tab[0] = 0.125;
    tab[1] = 0.25;
    tab[2] = 0.375;
    if (X + Y < mode) return;
    float v = 0;
    if (mode > 5) {
        if (X > 20) return;
        v = tab[k] + X * 0.001;
    } else {
        v = X * 0.01;
        if (Y > 15) v = v + 0.5;
    }
    Z = v * 0.5 + Y * 0.001;
}
"#;

/// Not flattenable: a uniform loop in the pixel code (it spends fuel whether or not a
/// lane runs it), so tier 0 keeps the early exits: with every lane retired by the guard,
/// the loop of `n` trips must not run (it would run out of fuel).
const LOOPY: &str = r#"
primitive loopy(
    float rect[4];
    float cut;
    int n;
    varying float X, Y;
    inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (X > cut) return;
    float acc = 0;
    for (int i = 0; i < n; i++)
        acc = acc + X * 0.001;
    Z = acc;
}
"#;

/// Setup code tier 0 does not lower (src/mid/dead.rs) next to code it must keep: a
/// chain of values nothing reads, and a store into an array nothing reads whose index may
/// fail (its run-time error is an effect). Also a guard tier 0 defers past speculative
/// setup code (`Lower::setup_stmts`).
const DEADLY: &str = r#"
primitive deadly(
    float rect[4];
    int k;
    varying float X, Y;
    inout varying fixed<32,32> Z)
{
    if (rect[0] > 100) return;
    float half = rect[0] * 0.5;
    bound(rect[0], rect[1], rect[2], rect[3]);
    float unused = half * 3.5;
    float never[2];
    never[k] = 1;
    float slope = rect[3] * 0.0001;
    if (slope > 1) return;
    Z = X * 0.001 + Y * slope;
}
"#;

/// A varying local with a uniform first value: flat pixel code starts the varying locals
/// the pixel code assigns at zero in each group, which must not replace that value
/// (today the checker leaves `v = 0.25` in the pixel code; were it moved to the setup,
/// `Lower::flat_group_locals` leaves locals the setup assigns alone).
const SEEDED: &str = r#"
primitive seeded(
    float rect[4];
    varying float X, Y;
    inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float v = 0.25;
    if (X > 10) v = X * 0.01;
    Z = v + Y * 0.0001;
}
"#;

/// A uniform `if` of the pixel code picking between two coverage forms, as screen_triangle
/// does: integer edge functions (at doubled coordinates, so pixel centres are integers) or
/// float ones, both computed by the setup from arrays declared without initialiser (tier 0
/// gives locals no explicit zero). `unset` is never assigned and `s` only when `mode > 5`:
/// both read as zero otherwise; `t` is zeroed after a first value. The depth says which
/// form ran.
const TWO_FORMS: &str = r#"
primitive two_forms(
    float rect[4];
    float vert[6];
    float mode;
    varying float X, Y;
    inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    bool exact = mode > 0;
    int ea[3], eb[3], ec[3];
    float fa[3], fb[3], fc[3];
    int unset[2];
    float s;
    if (mode > 5)
        s = 1;
    float t = mode;
    t = 0;
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
    if (exact) {
        int sx = int(X * 2), sy = int(Y * 2);
        if (ea[0] * sx + eb[0] * sy + ec[0] <= 0) return;
        if (ea[1] * sx + eb[1] * sy + ec[1] <= 0) return;
        if (ea[2] * sx + eb[2] * sy + ec[2] <= 0) return;
    } else {
        if (fa[0] * X + fb[0] * Y + fc[0] <= 0) return;
        if (fa[1] * X + fb[1] * Y + fc[1] <= 0) return;
        if (fa[2] * X + fb[2] * Y + fc[2] <= 0) return;
    }
    Z = (exact ? 0.25 : 0.5) + s * 0.125 + unset[1] * 0.0625 + t + X * 0.001;
}
"#;

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(
        sources,
        &[
            ("branchy.prim", BRANCHY),
            ("flatty.prim", FLATTY),
            ("loopy.prim", LOOPY),
            ("deadly.prim", DEADLY),
            ("seeded.prim", SEEDED),
            ("two_forms.prim", TWO_FORMS),
        ],
    )
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
    Jit::at_tier(program.clone(), tier).unwrap()
}

fn written(f: &Frame) -> usize {
    f.depth_values().iter().filter(|&&d| d != 0).count()
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
        if draws {
            // Both tiers if-convert these `if`s: the values themselves, from the source's
            // semantics (rect[0] = 2; an out-of-range `w[k]` clamps to `w[1]`).
            let (mut a, mut sum_s, mut w) = ([0.0f32; 3], 0.0f32, [0.0f32; 2]);
            if mode > 1.0 {
                a[0] = 2.0 * 0.5;
                a[1] = a[0] + 1.0;
                if mode > 2.0 {
                    sum_s = a[1] * 2.0;
                } else {
                    a[2] = 0.25;
                }
            } else {
                a[2] = mode;
            }
            if mode > 3.0 {
                w[k.clamp(0, 1) as usize] = 7.0;
            }
            let (x, y) = (10u32, 8u32);
            let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
            let want = (a[0] + a[1] + a[2] + sum_s + w[0] + w[1]) * 0.01 + px * 0.001 + py * 0.0001;
            let got = frame.depth_f32_at(x, y).unwrap();
            assert!((got - want).abs() < 1e-6, "mode {mode} k {k}: depth {got}, want {want}");
        }
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
    let r = primflow::workload::fill_scene(&program, 32, 1, Some("perspective_linear"), 4);
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
        assert!(
            c.codegen_cpu_micros <= c.cpu_micros,
            "{name}: Cranelift's part is part of the kernel's time: {c:?}"
        );
    }
    // The CLIF size reported is the kernel's as `clif` prints it.
    for tier in [Tier::Fast, Tier::Optimised] {
        let mut jit = Jit::at_tier(program.clone(), tier).unwrap();
        jit.kernel(inst.func, &inst.key).unwrap();
        let cost = jit.compile_cost(inst.func, &inst.key).unwrap();
        let printed = jit.clif(inst.func, &inst.key).unwrap();
        assert_eq!(cost.clif_insts, clif_instructions(&printed), "{tier:?}: {cost:?}");
    }
}

/// Instruction lines of printed CLIF: indented lines that are neither declarations (stack
/// slots, signatures, imported functions, global values, constants) nor value aliases
/// (`v5 -> v3`).
fn clif_instructions(clif: &str) -> u64 {
    let declaration = |first: &str| {
        ["ss", "sig", "fn", "gv", "const", "jt", "dss"].iter().any(|p| {
            first
                .strip_prefix(p)
                .is_some_and(|rest| !rest.is_empty() && rest.bytes().all(|b| b.is_ascii_digit()))
        })
    };
    clif.lines()
        .filter(|l| l.starts_with("    "))
        .filter(|l| !declaration(l.split_whitespace().next().unwrap_or("")) && !l.contains(" -> "))
        .count() as u64
}

/// One `prim` over `rect` with scalar parameters `params` on a 40 x 24 image in 16-pixel
/// tiles (so passes end mid-tile and mid-group).
fn one_prim(program: &Arc<Program>, prim: &str, rect: [f32; 4], params: &[(&str, f32)]) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(40, 24).unwrap();
    r.set_tile_size(16).unwrap();
    r.begin(prim).unwrap();
    r.rast_param("rect", &Value(rect.to_vec())).unwrap();
    for (name, v) in params {
        r.rast_param(name, &Value(vec![*v])).unwrap();
    }
    r.end().unwrap();
    r
}

#[test]
fn flat_tier_0_pixel_code_gives_the_same_pixels_and_errors_as_early_exits() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let rect = [2.3, 3.0, 37.0, 21.0];
    // (rect, mode, k, an error expected)
    let cases: [([f32; 4], f32, f32, bool); 7] = [
        // The uniform `if`'s else side, every pixel of the rectangle.
        (rect, 0.0, 7.0, false),
        // Its then side: the guards retire X + Y < 6 and X > 20; `tab[1]`.
        (rect, 6.0, 1.0, false),
        // The same with k out of range: an error, the read clamped (same pixels).
        (rect, 6.0, 7.0, true),
        // The then side not taken: its failing read runs for no lane, so no error.
        (rect, 4.0, 7.0, false),
        // Every lane retired by the first guard before the failing read: no error.
        (rect, 100.0, 7.0, false),
        // A pass empty in x (centres 5.5 and 6.5 lie outside [5.6, 5.9]): nothing, no
        // error, although tier 0 runs the group at x = 4 with no lane.
        ([5.6, 3.0, 5.9, 21.0], 6.0, 7.0, false),
        // One column (x = 5.5) ending mid-group, in two tiles.
        ([5.2, 3.0, 5.9, 21.0], 6.0, 2.0, false),
    ];
    // The pixels `flatty` writes, from its source: centres in the rectangle, X + Y >= mode,
    // and X <= 20 on the then side.
    let expected = |rect: [f32; 4], mode: f32| {
        (0..24)
            .flat_map(|y| (0..40).map(move |x| (x as f32 + 0.5, y as f32 + 0.5)))
            .filter(|&(x, y)| x >= rect[0] && x <= rect[2] && y >= rect[1] && y <= rect[3])
            .filter(|&(x, y)| x + y >= mode && (mode <= 5.0 || x <= 20.0))
            .count()
    };
    assert_eq!(expected(rect, 0.0), 35 * 18);
    assert_eq!(expected([5.6, 3.0, 5.9, 21.0], 6.0), 0);
    let mut frames = vec![];
    for (rect, mode, k, error) in cases {
        let r = one_prim(&program, "flatty", rect, &[("mode", mode), ("k", k)]);
        let what = format!("flatty {rect:?} mode {mode} k {k}");
        let (frame, codes) = both_tiers(&sources, &program, &r, &what);
        assert_eq!(!codes.is_empty(), error, "{what}: errors {codes:?}");
        assert_eq!(written(&frame), expected(rect, mode), "{what}: pixels");
        frames.push(frame);
    }
    // k out of range clamps to tab[2]: not the pixels of k = 1.
    assert!(!same_frame(&frames[1], &frames[2]));
    // A uniform-if side and the early exits are really gone from tier 0's pixel code.
    let inst = &one_prim(&program, "flatty", rect, &[("mode", 0.0), ("k", 0.0)]).instances()[0].clone();
    let blocks = |tier| {
        jit(&program, tier)
            .clif(inst.func, &inst.key)
            .unwrap()
            .lines()
            .filter(|l| l.starts_with("block"))
            .count()
    };
    let (fast, optimised) = (blocks(Tier::Fast), blocks(Tier::Optimised));
    assert!(fast * 3 < optimised, "tier 0 {fast} blocks, tier 1 {optimised}");
}

#[test]
fn tier_0_keeps_early_exits_before_a_uniform_loop_in_pixel_code() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let rect = [2.3, 3.0, 37.0, 21.0];
    // Every pixel retires before the 2^30-trip loop: nothing written, no fuel error.
    let r = one_prim(&program, "loopy", rect, &[("cut", -1.0), ("n", 1073741824.0)]);
    let (frame, codes) = both_tiers(&sources, &program, &r, "loopy, all retired");
    assert!(codes.is_empty(), "{codes:?}");
    assert_eq!(written(&frame), 0);
    // Live lanes running the loop, group after group: tests/jit/group_state.rs.
}

#[test]
fn tier_0_skips_dead_setup_code_but_keeps_its_errors_and_deferred_returns() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    // (rect, k, an error expected, pixels written)
    let cases: [([f32; 4], f32, bool, usize); 4] = [
        ([2.3, 3.0, 37.0, 21.0], 1.0, false, 35 * 18),
        // `never[5]`: nothing reads `never`, but the failed index is an error.
        ([2.3, 3.0, 37.0, 21.0], 5.0, true, 35 * 18),
        // The first guard returns before `bound`: nothing drawn.
        ([120.0, 3.0, 137.0, 21.0], 1.0, false, 0),
        // The second one, deferred by tier 0 past the speculative code around it.
        ([2.3, 3.0, 37.0, 20000.0], 1.0, false, 0),
    ];
    for (rect, k, error, pixels) in cases {
        let r = one_prim(&program, "deadly", rect, &[("k", k)]);
        let what = format!("deadly {rect:?} k {k}");
        let (frame, codes) = both_tiers(&sources, &program, &r, &what);
        assert_eq!(!codes.is_empty(), error, "{what}: errors {codes:?}");
        assert_eq!(written(&frame), pixels, "{what}: pixels");
    }
    // The dead chain is not in tier 0's CLIF (`half * 3.5`: the constant 3.5); tier 1
    // lowers it (and Cranelift drops it later).
    let inst = one_prim(&program, "deadly", [2.3, 3.0, 37.0, 21.0], &[("k", 1.0)]).instances()[0].clone();
    let clif = jit(&program, Tier::Fast).clif(inst.func, &inst.key).unwrap();
    assert!(!clif.contains("f32const 0x1.c00000p1"), "{clif}");
    let clif1 = jit(&program, Tier::Optimised).clif(inst.func, &inst.key).unwrap();
    assert!(clif1.contains("f32const 0x1.c00000p1"), "{clif1}");
}

#[test]
fn flat_pixel_code_keeps_a_varying_local_set_in_the_setup() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let r = one_prim(&program, "seeded", [2.3, 3.0, 37.0, 21.0], &[]);
    let (frame, codes) = both_tiers(&sources, &program, &r, "seeded");
    assert!(codes.is_empty(), "{codes:?}");
    assert_eq!(written(&frame), 35 * 18);
    // X <= 10 keeps 0.25 (+ Y * 0.0001), in fixed<32,32>: the pixel (5, 7).
    let z = f64::from(frame.depth_at(5, 7).unwrap()) / 4294967296.0;
    assert!((z - (0.25 + 7.5 * 0.0001)).abs() < 1e-6, "{z}");
}

#[test]
fn a_uniform_if_between_two_coverage_forms_renders_both_sides_at_tier_0() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let vert = [4.0f32, 3.0, 35.0, 8.0, 12.0, 22.0];
    // The covered pixel centres, from the same edge functions in f64.
    let mut inside = 0;
    for y in 0..24 {
        for x in 0..40 {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let covered = (0..3).all(|i| {
                let j = (i + 1) % 3;
                let (xi, yi) = (vert[2 * i] as f64, vert[2 * i + 1] as f64);
                let (xj, yj) = (vert[2 * j] as f64, vert[2 * j + 1] as f64);
                let (a, b) = (yi - yj, xj - xi);
                a * px + b * py - (a * xi + b * yi) > 0.0
            });
            inside += covered as usize;
        }
    }
    assert!(inside > 100, "the triangle covers pixels: {inside}");
    let scene = |mode: f32| {
        let mut r = Renderer::new(program.clone());
        r.set_image_size(40, 24).unwrap();
        r.set_tile_size(16).unwrap();
        r.begin("two_forms").unwrap();
        r.rast_param("rect", &Value(vec![0.0, 0.0, 40.0, 24.0])).unwrap();
        r.rast_param("vert", &Value(vert.to_vec())).unwrap();
        r.rast_param("mode", &Value(vec![mode])).unwrap();
        r.end().unwrap();
        r
    };
    // Integer edges, float edges, and integer edges with `s` assigned.
    let mut frames = vec![];
    for mode in [1.0f32, -1.0, 6.0] {
        let r = scene(mode);
        let (frame, codes) = both_tiers(&sources, &program, &r, &format!("mode {mode}"));
        assert!(codes.is_empty(), "mode {mode}: {codes:?}");
        assert_eq!(written(&frame), inside, "mode {mode}: covered pixels");
        // Loops kept (not unrolled): the edge arrays are indexed by the loop counter,
        // so tier 0 runs the range analysis it otherwise skips; same frame.
        let mut kept = Jit::with_options(
            program.clone(),
            primflow::jit::JitOptions {
                tier: Tier::Fast,
                unroll_loops: false,
            },
        )
        .unwrap();
        let out = r.render(&mut kept);
        assert!(!out.diags.has_errors(), "mode {mode}: {:?}", out.diags.items);
        assert!(same_frame(&frame, &out.frame), "mode {mode}: loops kept differ");
        frames.push(frame);
    }
    // Each side ran where it should: the depths tell the modes apart, the pixels do not.
    let depth_of = |f: &Frame| f.depth_values().into_iter().find(|&d| d != 0).unwrap();
    let depths: Vec<u32> = frames.iter().map(depth_of).collect();
    assert!(
        depths[0] != depths[1] && depths[0] != depths[2] && depths[1] != depths[2],
        "{depths:?}"
    );
}
