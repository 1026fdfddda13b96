//! Expansion (`RenderOptions::expand_calls`): a primitive that only calls primitives runs
//! once and its calls are binned as draws of their own. Every scene here is rendered with
//! expansion on and off (the per-tile path) and the frames must be bit-identical — depth,
//! every G-buffer plane, write counts — with the same diagnostics: polygons through the
//! hither plane, NURB patches sharing an edge, triangles through polygon (two levels), user
//! primitives that call screen_triangle in a loop, recurse until the call-depth limit, read
//! out of range at run time, or have pixel code of their own (never expanded); and the
//! hand-written polygon and NURB kernels, which record their calls the same way.

use crate::support;
use support::*;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::handwritten::{Flavor, Handwritten};
use primflow::ir::Program;
use primflow::jit::Jit;
use primflow::runtime::{KernelSource, RenderOutput, Renderer, Value};

/// User primitives (drawn through screen_triangle calls).
const USER_PRIMS: &str = r#"
// A zigzag strip of `count` triangles from `origin`, each `size` pixels, one
// screen_triangle call per loop iteration. With `bad_index` set, iteration i reads
// lift[i], out of range from i = 2 on (clamped, a run-time error at that read).
primitive tri_strip(float origin[2]; float size; int count; float depth; int bad_index;
                    interpolator_data interp_data[];
                    varying float X, Y;
                    inout varying fixed<32,32> Z)
{
    interpolation_data data[3] = {interp_data[0], interp_data[1], interp_data[2]};
    float lift[2] = {0, 0.25};
    for (int i = 0; i < count; i++) {
        float x = origin[0] + i * size * 0.5;
        float low = origin[1];
        float high = origin[1] + size;
        if (i % 2 == 1) {
            low = origin[1] + size;
            high = origin[1];
        }
        if (bad_index != 0)
            high = high + lift[i];
        float a[4] = {x, low, depth, 1};
        float b[4] = {x + size, low, depth, 1};
        float c[4] = {x + size * 0.5, high, depth + 0.01 * i, 1};
        float v[3][4] = {a, b, c};
        screen_triangle(v, data, X, Y, Z);
    }
}

// One triangle, then itself again `size` pixels to the right, with no end: the call-depth
// limit stops it.
primitive chain(float origin[2]; float size; float depth;
                interpolator_data interp_data[];
                varying float X, Y;
                inout varying fixed<32,32> Z)
{
    interpolation_data data[3] = {interp_data[0], interp_data[1], interp_data[2]};
    float a[4] = {origin[0], origin[1], depth, 1};
    float b[4] = {origin[0] + size, origin[1], depth, 1};
    float c[4] = {origin[0], origin[1] + size, depth, 1};
    float v[3][4] = {a, b, c};
    screen_triangle(v, data, X, Y, Z);
    float next[2] = {origin[0] + size * 0.75, origin[1] + size * 0.25};
    chain(next, size, depth - 0.01, data, X, Y, Z);
}

// A triangle through a call, and a rectangle of pixel code of its own: never expanded.
primitive tri_and_rect(float rect[4]; float depth;
                       interpolator_data interp_data[];
                       varying float X, Y;
                       inout varying fixed<32,32> Z)
{
    interpolation_data data[3] = {interp_data[0], interp_data[1], interp_data[2]};
    float a[4] = {rect[0], rect[3], depth + 0.1, 1};
    float b[4] = {rect[2], rect[3], depth + 0.1, 1};
    float c[4] = {rect[0], rect[1] - 8, depth + 0.1, 1};
    float v[3][4] = {a, b, c};
    screen_triangle(v, data, X, Y, Z);
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (X < rect[0] || X > rect[2] || Y < rect[1] || Y > rect[3])
        return;
    if (depth < Z)
        return;
    Z = depth;
}
"#;

/// The library plus [`USER_PRIMS`].
fn library_with_user_prims() -> Arc<Program> {
    library_with(&mut SourceMap::new(), &[("user.prim", USER_PRIMS)])
}

/// Render `r` with `source` on `threads` threads, expansion on or off.
fn render_mode(r: &mut Renderer, source: &mut (dyn KernelSource + Send), expand: bool, threads: usize) -> RenderOutput {
    r.options.expand_calls = expand;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let out = pool.install(|| r.render(source));
    r.options.expand_calls = true;
    out
}

fn assert_same_frame(a: &RenderOutput, b: &RenderOutput, what: &str) {
    let (fa, fb) = (&a.frame, &b.frame);
    let depth_diff = fa
        .depth_values()
        .iter()
        .zip(&fb.depth_values())
        .filter(|(x, y)| x != y)
        .count();
    assert_eq!(depth_diff, 0, "{what}: depth differs in {depth_diff} pixels");
    assert_eq!(
        fa.write_count_values(),
        fb.write_count_values(),
        "{what}: write counts differ"
    );
    assert_eq!(fa.num_planes(), fb.num_planes(), "{what}: plane count");
    for (p, (pa, pb)) in fa.all_plane_values().iter().zip(&fb.all_plane_values()).enumerate() {
        let differing = pa.iter().zip(pb).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
        assert_eq!(differing, 0, "{what}: plane {p} differs in {differing} pixels");
    }
    assert_eq!(a.diags.items, b.diags.items, "{what}: diagnostics differ");
}

/// Render with expansion on (1 and 2 threads) and off; assert all three agree bit for bit,
/// with the same diagnostics, and return (expanded, per-tile).
fn same_either_way(
    r: &mut Renderer,
    source: &mut (dyn KernelSource + Send),
    what: &str,
) -> (RenderOutput, RenderOutput) {
    let per_tile = render_mode(r, source, false, 1);
    let expanded = render_mode(r, source, true, 1);
    let expanded_two = render_mode(r, source, true, 2);
    assert_same_frame(&expanded, &per_tile, &format!("{what}: expanded vs per tile"));
    assert_same_frame(&expanded_two, &expanded, &format!("{what}: expanded, 2 threads vs 1"));
    // The run-time errors too, counts included (setup errors count once per draw).
    let report = |out: &RenderOutput| -> Vec<String> {
        out.diags
            .items
            .iter()
            .map(|d| format!("{} {}", d.code, d.message))
            .collect()
    };
    assert_eq!(
        report(&expanded),
        report(&per_tile),
        "{what}: errors, expanded vs per tile"
    );
    assert_eq!(
        report(&expanded_two),
        report(&expanded),
        "{what}: errors, 2 threads vs 1"
    );
    assert_eq!(per_tile.stats.expanded_instances, 0, "{what}: expansion off");
    (expanded, per_tile)
}

fn written(out: &RenderOutput) -> usize {
    out.frame.depth_values().iter().filter(|&&d| d != 0).count()
}

/// Three sequence points with `s` (a linear float) and `c` (a perspective_linear colour).
fn three_points(r: &mut Renderer, rng: &mut Lcg) {
    for _ in 0..3 {
        r.material("c", &Value((0..3).map(|_| rng.next() as f32).collect()))
            .unwrap();
        r.material("s", &Value(vec![rng.range(-1.0, 1.0) as f32])).unwrap();
        r.sequence_point().unwrap();
    }
}

fn bind_c_and_s(r: &mut Renderer) {
    r.material_interp("c", "perspective_linear", &[]).unwrap();
    r.material_interp("s", "linear", &[]).unwrap();
}

fn strip(r: &mut Renderer, origin: [f32; 2], size: f32, count: i32, depth: f32, bad_index: bool, rng: &mut Lcg) {
    r.begin("tri_strip").unwrap();
    r.rast_param("origin", &Value(origin.to_vec())).unwrap();
    r.rast_param("size", &Value(vec![size])).unwrap();
    r.rast_param("count", &Value(vec![count as f32])).unwrap();
    r.rast_param("depth", &Value(vec![depth])).unwrap();
    r.rast_param("bad_index", &Value(vec![f32::from(u8::from(bad_index))]))
        .unwrap();
    three_points(r, rng);
    r.end().unwrap();
}

#[test]
fn polygons_through_the_hither_plane_are_bit_identical_expanded() {
    let program = library();
    let mut r = renderer(&program, 120, 90, true);
    r.set_tile_size(16).unwrap();
    r.perspective_checked(60.0, 1.0, 50.0).unwrap();
    r.material_interp("c", "perspective_linear", &[]).unwrap();
    let mut rng = Lcg(7);
    for _ in 0..40 {
        let (cx, cy) = (rng.range(-4.0, 2.0), rng.range(-3.0, 1.0));
        // Near corners in front of the eye but behind the hither plane (clipped there).
        let (z_near, z_far) = (-0.3 - rng.range(0.0, 1.0), -5.0 - rng.range(0.0, 4.0));
        r.begin("polygon").unwrap();
        for (x, y, z) in [
            (cx, cy, z_far),
            (cx + 2.0, cy, z_far),
            (cx + 2.0, cy + 2.0, z_near),
            (cx, cy + 2.0, z_near),
        ] {
            r.material("c", &Value((0..4).map(|_| rng.next() as f32).collect()))
                .unwrap();
            r.vertex(x as f32, y as f32, z as f32, 1.0).unwrap();
        }
        r.end().unwrap();
    }
    let mut jit = Jit::new(program.clone()).unwrap();
    let (expanded, per_tile) = same_either_way(&mut r, &mut jit, "polygons, JIT");
    assert!(expanded.diags.items.is_empty(), "{:?}", expanded.diags.items);
    assert!(written(&expanded) > 3000, "only {} pixels", written(&expanded));
    // Every polygon instance (the geometry stage may have split a clipped one) was replaced
    // by its fan, at least one triangle each; per tile, none was.
    let instances = r.instances().len();
    assert!(instances >= 40);
    assert_eq!(expanded.stats.expanded_instances, instances);
    assert!(expanded.stats.expanded_calls >= instances);
    assert_eq!(per_tile.stats.expanded_calls, 0);
    // The hand-written polygon records its fan the same way.
    for flavor in [Flavor::Scalar, Flavor::Sse, Flavor::Avx2] {
        let mut hand = Handwritten::new(program.clone(), flavor);
        let (hand_expanded, _) = same_either_way(&mut r, &mut hand, &format!("polygons, {}", flavor.describe()));
        assert_same_frame(
            &hand_expanded,
            &expanded,
            &format!("polygons, {} vs JIT", flavor.describe()),
        );
        assert_eq!(hand_expanded.stats.expanded_calls, expanded.stats.expanded_calls);
        assert_eq!(hand_expanded.stats.tile_invocations, expanded.stats.tile_invocations);
    }
}

/// Two 4 x 4 bicubic patches sharing their middle column ([`shared_column_patches`]).
fn shared_edge_patches(r: &mut Renderer) {
    let [left, right] = shared_column_patches();
    for net in [left, right] {
        r.begin("nurb_surface").unwrap();
        r.rast_param("tolerance", &Value(vec![0.5])).unwrap();
        for (k, p) in net.iter().enumerate() {
            r.rast_param("weight", &Value(vec![if k == 5 { 2.5 } else { 1.0 }]))
                .unwrap();
            r.material("s", &Value(vec![(k % 4) as f32 * 0.25 + (k / 4) as f32]))
                .unwrap();
            r.vertex(p[0] as f32, p[1] as f32, p[2] as f32, 1.0).unwrap();
        }
        r.end().unwrap();
    }
}

#[test]
fn nurb_patches_sharing_an_edge_are_bit_identical_expanded() {
    let program = library();
    let mut r = renderer(&program, 96, 64, true);
    r.set_tile_size(16).unwrap();
    r.perspective_checked(40.0, 1.0, 50.0).unwrap();
    r.material_interp("N", "implicit", &[]).unwrap();
    r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
    r.material_interp("s", "linear", &[]).unwrap();
    shared_edge_patches(&mut r);
    assert!(r.take_warnings().is_empty());
    let mut jit = Jit::new(program.clone()).unwrap();
    let (expanded, per_tile) = same_either_way(&mut r, &mut jit, "NURB patches, JIT");
    assert!(expanded.diags.items.is_empty(), "{:?}", expanded.diags.items);
    assert!(written(&expanded) > 1500, "only {} pixels", written(&expanded));
    // Crack-free and no pixel written twice along the shared edge, expanded too.
    let counts = expanded.frame.write_count_values().unwrap();
    assert!(counts.iter().all(|&c| c <= 1), "a pixel written twice");
    // Both patches expanded, through polygon, into their triangles.
    assert_eq!(expanded.stats.expanded_instances, 2);
    assert!(
        expanded.stats.expanded_calls > 100,
        "{} triangles",
        expanded.stats.expanded_calls
    );
    assert!(expanded.stats.tile_invocations > per_tile.stats.tile_invocations);
    // The hand-written NURB records the same triangles (in one step, not through polygon).
    for flavor in [Flavor::Scalar, Flavor::Avx2] {
        let mut hand = Handwritten::new(program.clone(), flavor);
        let (hand_expanded, _) = same_either_way(&mut r, &mut hand, &format!("NURB, {}", flavor.describe()));
        assert_same_frame(
            &hand_expanded,
            &expanded,
            &format!("NURB, {} vs JIT", flavor.describe()),
        );
        assert_eq!(hand_expanded.stats.expanded_calls, expanded.stats.expanded_calls);
    }
}

#[test]
fn triangles_expand_through_polygon_in_two_levels() {
    let program = library();
    let mut r = renderer(&program, 64, 48, true);
    r.set_tile_size(8).unwrap();
    r.perspective_checked(50.0, 1.0, 50.0).unwrap();
    bind_c_and_s(&mut r);
    let mut rng = Lcg(3);
    for _ in 0..12 {
        r.begin("triangle").unwrap();
        let (cx, cy, cz) = (rng.range(-2.0, 1.0), rng.range(-1.5, 1.0), rng.range(-6.0, -2.0));
        for k in 0..3 {
            r.material("c", &Value((0..3).map(|_| rng.next() as f32).collect()))
                .unwrap();
            r.material("s", &Value(vec![rng.range(-1.0, 1.0) as f32])).unwrap();
            let (dx, dy) = [(0.0, 0.0), (1.5, 0.2), (0.3, 1.4)][k];
            r.vertex((cx + dx) as f32, (cy + dy) as f32, cz as f32, 1.0).unwrap();
        }
        r.end().unwrap();
    }
    let mut jit = Jit::new(program.clone()).unwrap();
    let (expanded, _) = same_either_way(&mut r, &mut jit, "triangles");
    assert!(expanded.diags.items.is_empty(), "{:?}", expanded.diags.items);
    assert!(written(&expanded) > 300, "only {} pixels", written(&expanded));
    // triangle -> polygon -> one screen_triangle each.
    assert_eq!(expanded.stats.expanded_instances, 12);
    assert_eq!(expanded.stats.expanded_calls, 12);
}

#[test]
fn a_user_primitive_calling_screen_triangle_in_a_loop_is_bit_identical_expanded() {
    let program = library_with_user_prims();
    let mut r = renderer(&program, 100, 70, true);
    r.set_tile_size(16).unwrap();
    bind_c_and_s(&mut r);
    let mut rng = Lcg(21);
    let mut triangles = 0;
    for k in 0..10 {
        let count = 3 + k % 7;
        let origin = [rng.range(-10.0, 70.0) as f32, rng.range(-5.0, 60.0) as f32];
        strip(
            &mut r,
            origin,
            rng.range(4.0, 14.0) as f32,
            count,
            rng.range(0.1, 0.9) as f32,
            false,
            &mut rng,
        );
        triangles += count as usize;
    }
    // A strip whose triangles are all NaN: binned nowhere, draws nothing, either way.
    strip(&mut r, [f32::NAN, 3.0], 5.0, 4, 0.5, false, &mut rng);
    // A plain triangle between strips keeps its place in the order.
    r.begin("screen_triangle").unwrap();
    r.rast_param(
        "screen_vertex",
        &Value(vec![0.0, 0.0, 0.55, 1.0, 100.0, 10.0, 0.55, 1.0, 30.0, 70.0, 0.55, 1.0]),
    )
    .unwrap();
    three_points(&mut r, &mut rng);
    r.end().unwrap();
    strip(&mut r, [20.0, 20.0], 12.0, 6, 0.6, false, &mut rng);
    triangles += 6;
    assert!(r.take_warnings().is_empty());

    let mut jit = Jit::new(program.clone()).unwrap();
    let (expanded, per_tile) = same_either_way(&mut r, &mut jit, "strips");
    assert!(expanded.diags.items.is_empty(), "{:?}", expanded.diags.items);
    assert!(written(&expanded) > 2000, "only {} pixels", written(&expanded));
    assert_eq!(expanded.stats.expanded_instances, 12);
    assert_eq!(expanded.stats.expanded_calls, triangles + 4);
    assert_eq!(per_tile.stats.expanded_calls, 0);

    // Only the NaN strip: four recorded triangles, none in any tile, nothing drawn.
    let mut r = renderer(&program, 100, 70, true);
    bind_c_and_s(&mut r);
    strip(&mut r, [f32::NAN, 3.0], 5.0, 4, 0.5, false, &mut Lcg(1));
    let (expanded, per_tile) = same_either_way(&mut r, &mut jit, "NaN strip");
    assert_eq!(expanded.stats.expanded_calls, 4);
    assert_eq!(
        (expanded.stats.tile_invocations, per_tile.stats.tile_invocations),
        (0, 0)
    );
    assert_eq!(written(&expanded), 0);
}

#[test]
fn a_long_strip_is_bound_in_parallel_and_stays_bit_identical() {
    // One instance recording 700 draws: its bound pass runs in parallel chunks (above
    // `PARALLEL_BOUNDS` in runtime/expand.rs). Overlapping triangles at rising depth, most of
    // them off screen (no tiles) and many too thin to cover a pixel centre; a short strip
    // after it keeps its place in the order.
    let program = library_with_user_prims();
    let mut r = renderer(&program, 120, 48, true);
    r.set_tile_size(16).unwrap();
    bind_c_and_s(&mut r);
    let mut rng = Lcg(33);
    strip(&mut r, [-30.0, 6.0], 1.5, 700, 0.2, false, &mut rng);
    strip(&mut r, [10.0, 20.0], 9.0, 12, 0.3, false, &mut rng);
    let mut jit = Jit::new(program.clone()).unwrap();
    let (expanded, per_tile) = same_either_way(&mut r, &mut jit, "long strip");
    assert!(expanded.diags.items.is_empty(), "{:?}", expanded.diags.items);
    assert_eq!(expanded.stats.expanded_calls, 712);
    assert!(written(&expanded) > 400, "only {} pixels", written(&expanded));
    // Every draw binned into the same tiles whatever the thread count.
    let two = render_mode(&mut r, &mut jit, true, 2);
    assert_eq!(two.stats.tile_invocations, expanded.stats.tile_invocations);
    assert!(expanded.stats.tile_invocations > per_tile.stats.tile_invocations);
}

#[test]
fn run_time_errors_of_an_expanded_setup_are_reported_once_at_their_site() {
    let program = library_with_user_prims();
    let mut r = renderer(&program, 80, 40, false);
    r.set_tile_size(8).unwrap();
    bind_c_and_s(&mut r);
    let mut rng = Lcg(5);
    strip(&mut r, [2.0, 4.0], 10.0, 8, 0.5, true, &mut rng);
    strip(&mut r, [30.0, 20.0], 8.0, 5, 0.4, true, &mut rng);
    let mut jit = Jit::new(program.clone()).unwrap();
    let (expanded, _) = same_either_way(&mut r, &mut jit, "out-of-range read");
    // One W0801 for the one site (both strips, every tile), pointing at `lift[i]`.
    let warnings: Vec<_> = expanded.diags.items.iter().filter(|d| d.code == "W0801").collect();
    assert_eq!(warnings.len(), 1, "{:?}", expanded.diags.items);
    assert!(warnings[0].message.contains("`tri_strip`"), "{}", warnings[0].message);
    assert!(warnings[0].message.contains("index"), "{}", warnings[0].message);
    let span = warnings[0].labels[0].span;
    let (start, end) = (span.start as usize, span.end as usize);
    assert!(
        USER_PRIMS[..start].ends_with("lift[") && &USER_PRIMS[start..end] == "i",
        "the warning points at `{}`",
        &USER_PRIMS[start..end]
    );
    assert!(written(&expanded) > 300);
}

#[test]
fn recursion_stops_at_the_call_depth_limit_expanded_too() {
    let program = library_with_user_prims();
    let mut r = renderer(&program, 160, 100, true);
    r.set_tile_size(16).unwrap();
    bind_c_and_s(&mut r);
    r.begin("chain").unwrap();
    r.rast_param("origin", &Value(vec![1.0, 1.0])).unwrap();
    r.rast_param("size", &Value(vec![8.0])).unwrap();
    r.rast_param("depth", &Value(vec![0.9])).unwrap();
    three_points(&mut r, &mut Lcg(9));
    r.end().unwrap();
    let mut jit = Jit::new(program.clone()).unwrap();
    let (expanded, _) = same_either_way(&mut r, &mut jit, "chain");
    // Chain at depth d (0..=15) draws its triangle at depth d + 1; chain at depth 16 calls
    // deeper than the limit: neither its triangle nor the next link is drawn. Each skipped
    // call is reported once, at the call.
    let warnings: Vec<_> = expanded.diags.items.iter().filter(|d| d.code == "W0801").collect();
    assert_eq!(warnings.len(), 2, "{:?}", expanded.diags.items);
    let calls: Vec<&str> = warnings
        .iter()
        .map(|w| {
            assert!(w.message.contains("in `chain`") && w.message.contains("too deep") && w.message.ends_with("once"));
            let span = w.labels[0].span;
            &USER_PRIMS[span.start as usize..span.end as usize]
        })
        .collect();
    assert!(calls[0].starts_with("screen_triangle(v, data"), "{calls:?}");
    assert!(calls[1].starts_with("chain(next, size"), "{calls:?}");
    assert_eq!(expanded.stats.expanded_instances, 1);
    assert_eq!(expanded.stats.expanded_calls, 16);
    assert!(written(&expanded) > 16 * 20);
}

#[test]
fn a_primitive_with_pixel_code_of_its_own_is_never_expanded() {
    let program = library_with_user_prims();
    let mut r = renderer(&program, 64, 64, true);
    r.set_tile_size(16).unwrap();
    bind_c_and_s(&mut r);
    let mut rng = Lcg(13);
    for k in 0..5 {
        let x = 4.0 + 10.0 * k as f32;
        r.begin("tri_and_rect").unwrap();
        r.rast_param("rect", &Value(vec![x, 20.0, x + 12.0, 40.0])).unwrap();
        r.rast_param("depth", &Value(vec![0.3 + 0.1 * k as f32])).unwrap();
        three_points(&mut r, &mut rng);
        r.end().unwrap();
        strip(&mut r, [x - 5.0, 30.0], 9.0, 3, 0.45, false, &mut rng);
    }
    let mut jit = Jit::new(program.clone()).unwrap();
    let (expanded, _) = same_either_way(&mut r, &mut jit, "mixed");
    assert!(expanded.diags.items.is_empty(), "{:?}", expanded.diags.items);
    // Only the strips expand.
    assert_eq!(expanded.stats.expanded_instances, 5);
    assert_eq!(expanded.stats.expanded_calls, 15);
    // The rectangles' own pixels are there (depth 0.3 + 0.1 k inside each rect's right part).
    assert!(expanded.frame.written(4 + 11, 38));
}

#[test]
fn an_expansion_over_budget_renders_per_tile_and_stays_identical() {
    let program = library_with_user_prims();
    let mut r = renderer(&program, 100, 70, true);
    r.set_tile_size(16).unwrap();
    bind_c_and_s(&mut r);
    let mut rng = Lcg(17);
    strip(&mut r, [5.0, 5.0], 10.0, 3, 0.5, false, &mut rng);
    strip(&mut r, [5.0, 30.0], 10.0, 12, 0.6, false, &mut rng);
    strip(&mut r, [40.0, 10.0], 10.0, 2, 0.7, false, &mut rng);
    let mut jit = Jit::new(program.clone()).unwrap();
    let (full, _) = same_either_way(&mut r, &mut jit, "budget");
    assert_eq!(full.stats.expanded_instances, 3);
    // Room for a few triangles only: the 12-triangle strip goes per tile, the others expand.
    let per_call = full.stats.expanded_calls; // 17 triangles
    assert_eq!(per_call, 17);
    r.options.expand_budget_words = 6 * 60;
    // One thread: instances expand in order (on more threads, which instance runs out of
    // budget depends on timing; the pixels do not).
    let limited = render_mode(&mut r, &mut jit, true, 1);
    assert_same_frame(&limited, &full, "over budget vs expanded");
    assert_eq!(limited.stats.expanded_instances, 2);
    assert_eq!(limited.stats.expand_over_budget, 1);
    assert_eq!(limited.stats.expanded_calls, 5);
    let limited_two = render_mode(&mut r, &mut jit, true, 2);
    assert_same_frame(&limited_two, &full, "over budget, 2 threads vs expanded");
    assert!(limited_two.stats.expand_over_budget >= 1);
}
