//! NURB weights and control points at the extremes: weights near 0 and near the float range,
//! control points past the 1e15 limit or not finite, bad tolerances.

use crate::nurb::{bicubic_net, covered};
use crate::support::*;

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
