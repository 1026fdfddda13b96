//! NURB weights and control points at the extremes: weights near 0 and near the float range,
//! weight ratios at the 1e-6 limit, control points 1e3 to 1e14 px out, past the 1e15 limit
//! or not finite, bad tolerances.

use super::{compare, twice_and_holes};
use crate::nurb::{bicubic_net, covered};
use crate::support::*;

use std::sync::Arc;

use primflow::ir::Program;
use primflow::jit::Jit;
use primflow::runtime::{Frame, Value};

/// Render the bicubic patch with every weight `w`, control point 5 at `p5` (device space)
/// and `tolerance`: its frame and diagnostic codes.
fn render_net(w: f32, p5: Option<[f32; 3]>, tolerance: f32) -> (Frame, Vec<&'static str>) {
    let program = library();
    let mut r = renderer(&program, 64, 48, false);
    r.begin("nurb_surface").unwrap();
    r.rast_param("weight", &Value(vec![w])).unwrap();
    r.rast_param("tolerance", &Value(vec![tolerance])).unwrap();
    for (i, p) in bicubic_net().iter().enumerate() {
        let p = match p5 {
            Some(q) if i == 5 => q,
            _ => p.map(|c| c as f32),
        };
        r.vertex(p[0], p[1], p[2], 1.0).unwrap();
    }
    r.end().unwrap();
    let mut jit = Jit::new(program.clone()).unwrap();
    let out = r.render(&mut jit);
    (out.frame, out.diags.items.iter().map(|d| d.code).collect())
}

/// Weights at the ends of the float range (1e-45, 1e-30, 3e38, f32::MAX, all alike) draw
/// the same surface as weights of 1, bit for bit; a control point at 1e30, past 1e15,
/// infinite or NaN, and a tolerance of 0, -1 or NaN are rejected with W0801 and draw nothing.
/// Source: a common factor of all the weights cancels in the rational basis functions (Piegl
/// and Tiller, The NURBS Book, chapter 4) and docs/primitives.md's rejection rules;
/// tolerance 0 (the depth buffer bit for bit, 0 pixels for a rejected net).
#[test]
fn extreme_weights_draw_as_weights_of_one_and_bad_points_or_tolerances_are_rejected() {
    let (reference, diags) = render_net(1.0, None, 0.5);
    assert!(diags.is_empty(), "{diags:?}");
    assert!(covered(&reference) > 1000);
    // Weights are scaled so the largest is 1: the same surface, bit for bit.
    for w in [1e-45f32, 1e-30, 3e38, f32::MAX] {
        let (frame, diags) = render_net(w, None, 0.5);
        assert!(diags.is_empty(), "weights {w}: {diags:?}");
        assert!(frame.depth == reference.depth, "weights {w}: another surface");
    }
    // Rejected with W0801 naming the reason; nothing drawn.
    for (what, p5, tolerance) in [
        ("a control point at 1e30", Some([1e30, 10.0, 0.5]), 0.5),
        ("a control point past 1e15", Some([20.0, -2e15, 0.5]), 0.5),
        ("an infinite control point", Some([f32::INFINITY, 10.0, 0.5]), 0.5),
        ("a NaN control point", Some([20.0, f32::NAN, 0.5]), 0.5),
        ("tolerance 0", None, 0.0),
        ("tolerance -1", None, -1.0),
        ("tolerance NaN", None, f32::NAN),
    ] {
        let (frame, diags) = render_net(1.0, p5, tolerance);
        assert_eq!(covered(&frame), 0, "{what}: something was drawn");
        assert!(diags.contains(&"W0801"), "{what}: {diags:?}");
    }
    // Weights past the float range are not finite: rejected.
    let (frame, diags) = render_net(f32::INFINITY, None, 0.5);
    assert_eq!(covered(&frame), 0);
    assert!(diags.contains(&"W0801"), "{diags:?}");
}

/// A flat order-2 (bilinear) patch with corners `quad` (in order around it; device space,
/// depth 0.5) and corner weights `weights` (same order): its frame (write counts on) and the
/// diagnostic codes.
fn render_quad_patch(
    program: &Arc<Program>,
    jit: &mut Jit,
    size: u32,
    quad: [[f32; 2]; 4],
    weights: [f32; 4],
) -> (Frame, Vec<&'static str>) {
    let mut r = renderer(program, size, size, true);
    r.begin("nurb_surface").unwrap();
    let knots = {
        let mut k = vec![0.0, 0.0, 1.0, 1.0];
        k.resize(16, 1.0);
        Value(k)
    };
    for name in ["u_count", "v_count", "u_order", "v_order"] {
        r.rast_param(name, &Value(vec![2.0])).unwrap();
    }
    r.rast_param("u_knots", &knots).unwrap();
    r.rast_param("v_knots", &knots).unwrap();
    // Control point (i, j) is sequence point j * 2 + i: corners 0, 1, then 3, 2.
    for k in [0, 1, 3, 2] {
        r.rast_param("weight", &Value(vec![weights[k]])).unwrap();
        r.vertex(quad[k][0], quad[k][1], 0.5, 1.0).unwrap();
    }
    r.end().unwrap();
    let out = r.render(jit);
    (out.frame, out.diags.items.iter().map(|d| d.code).collect())
}

/// Is (x, y) inside the convex quad (either winding), in f64?
fn inside_quad(quad: &[[f32; 2]; 4], x: f64, y: f64) -> bool {
    let e: Vec<f64> = (0..4)
        .map(|i| {
            let (a, b) = (quad[i].map(f64::from), quad[(i + 1) % 4].map(f64::from));
            (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0])
        })
        .collect();
    e.iter().all(|&v| v >= 0.0) || e.iter().all(|&v| v <= 0.0)
}

/// Flat bilinear patches whose corner weights are alike, spread by 1e-2, or spread to just
/// above the 1e-6 ratio the prim accepts (all tiny, 1e-30, or all huge, 3e38, with one at
/// the ratio limit): a rational bilinear patch with positive weights covers exactly its
/// corners' quad (its boundary curves are straight: rational linear), so every pixel of the
/// quad is drawn and no other; only the tessellation cap's W0801 may be reported. Where the
/// cap is not reached each pixel is written once; where it is (ratios of 1e-3 and below)
/// that is not asserted: today 3 to 13 pixels of this quad are written an odd number of
/// times (3 to 89) there, where the straight triangles fold over (hard_cases/mod.rs).
/// Source: the convex quad in f64 (Piegl and Tiller, The NURBS Book, chapter 4: positive
/// weights keep the convex-hull property and degree-1 boundaries straight); tolerance:
/// coverage exact except within `SNAP_BAND` of the quad's edges, depth 0.5 within 2^-20,
/// no pixel twice below the cap.
#[test]
fn flat_patches_with_extreme_weight_ratios_cover_exactly_their_quad() {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let quad = [[6.3f32, 5.2], [41.7, 8.1], [44.4, 40.6], [3.9, 37.3]];
    for weights in [
        [1.0f32, 1.0, 1.0, 1.0],
        [1.0, 0.5, 2.0, 0.1],
        [1.0, 1e-2, 1.0, 1.0],
        [1.0, 1.001e-6, 1.0, 1.0],
        [1.001e-6, 1.0, 1.001e-6, 1.0],
        [1e-30, 1e-30, 1.001e-36, 1e-30],
        [3e38, 3.001e32, 3e38, 3e38],
    ] {
        let (frame, codes) = render_quad_patch(&program, &mut jit, 48, quad, weights);
        assert!(codes.iter().all(|&c| c == "W0801"), "weights {weights:?}: {codes:?}");
        // Within a factor of 100 the step bound stays under the cap: no warning at all.
        let (lo, hi) = (
            weights.iter().copied().fold(f32::MAX, f32::min),
            weights.iter().copied().fold(0.0, f32::max),
        );
        if hi <= 100.0 * lo {
            assert!(codes.is_empty(), "weights {weights:?}: {codes:?}");
        }
        let cmp = compare(&frame, |x, y| inside_quad(&quad, x, y).then_some((0.5, 0)));
        assert!(
            cmp.wrong.is_empty(),
            "weights {weights:?}: {} pixels off the quad {:?}",
            cmp.wrong.len(),
            &cmp.wrong[..cmp.wrong.len().min(8)]
        );
        if codes.is_empty() {
            assert_eq!(cmp.twice, 0, "weights {weights:?}: pixels written twice");
        }
        assert!(cmp.covered > 900, "weights {weights:?}: {} pixels", cmp.covered);
        assert!(
            cmp.depth_err <= 1.0 / 1_048_576.0,
            "weights {weights:?}: depth off by {:e}",
            cmp.depth_err
        );
    }
}

/// Flat bilinear patches with corners 1e3 to 1e14 px out (the limit is 1e15): one covering
/// the whole view is written exactly once at every pixel (its tessellation's triangles
/// share their edges: the D3D11 top-left rule, through the exact, two-limb and f32 edge
/// paths of screen_triangle); one whose nearly horizontal edge crosses the view, with its
/// corners within 2^24 px (the exact paths), covers exactly the pixels below that edge.
/// The step bound counts the parametric distortion of a non-parallelogram quad, so far
/// corners ask for more than 128 steps: drawn at the cap with W0801 (docs/primitives.md),
/// which is the only diagnostic allowed. Source: the quad in f64; tolerance: 0 pixels
/// written twice or not at all, coverage exact except within `SNAP_BAND` of the edge.
#[test]
fn flat_patches_with_huge_corners_cover_the_view_once() {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let size = 48;
    for far in [1e3f32, 1e5, 1e6, 8e6, 1e8, 1e10, 1e12, 1e14] {
        let cover = [
            [-far, -0.9 * far],
            [1.1 * far, -far],
            [far, far],
            [-0.8 * far, 1.2 * far],
        ];
        let (frame, codes) = render_quad_patch(&program, &mut jit, size, cover, [1.0; 4]);
        assert!(codes.iter().all(|&c| c == "W0801"), "{far:e}: {codes:?}");
        let counts = frame.write_count_values().unwrap();
        assert_eq!(
            twice_and_holes(&counts),
            (0, 0),
            "{far:e}: pixels written twice, not written"
        );
        if far <= 8e6 {
            let edge = [[-far, 20.3], [far, 27.9], [1.2 * far, far], [-1.1 * far, 0.9 * far]];
            let (frame, codes) = render_quad_patch(&program, &mut jit, size, edge, [1.0; 4]);
            assert!(codes.iter().all(|&c| c == "W0801"), "{far:e}: {codes:?}");
            let cmp = compare(&frame, |x, y| inside_quad(&edge, x, y).then_some((0.5, 0)));
            assert!(
                cmp.wrong.is_empty() && cmp.twice == 0,
                "{far:e}: {} pixels off the quad {:?}, {} written twice",
                cmp.wrong.len(),
                &cmp.wrong[..cmp.wrong.len().min(8)],
                cmp.twice
            );
            assert!(cmp.covered > 48 * 18, "{far:e}: {} pixels", cmp.covered);
        }
    }
}
