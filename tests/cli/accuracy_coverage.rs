//! The exact area-coverage reference (`accuracy::coverage`): areas add up to the shapes'
//! areas, hand-computed pixels, shared edges, agreement with an independent adaptive Simpson
//! integration per pixel, and inputs that must cover nothing without panicking.

use std::f64::consts::PI;

use primflow::accuracy::coverage::{
    box_resolved_error, disc_coverage, disc_pixel_area, polygon_pixel_area, triangle_coverage, triangle_pixel_area,
    CoverageError, Point,
};
use proptest::prelude::*;

fn shoelace(poly: &[Point]) -> f64 {
    let n = poly.len();
    let twice: f64 = (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    (0.5 * twice).abs()
}

/// Adaptive Simpson of `f` over [a, b] to `tol`: the independent integrator of the tests.
fn simpson(f: &dyn Fn(f64) -> f64, a: f64, b: f64, tol: f64) -> f64 {
    /// One interval: its ends, f at its ends and middle, and its Simpson estimate.
    fn step(f: &dyn Fn(f64) -> f64, [a, b]: [f64; 2], [fa, fm, fb]: [f64; 3], whole: f64, tol: f64, depth: u32) -> f64 {
        let m = 0.5 * (a + b);
        let (flm, frm) = (f(0.5 * (a + m)), f(0.5 * (m + b)));
        let left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
        let right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
        if depth == 0 || (left + right - whole).abs() <= 15.0 * tol {
            return left + right + (left + right - whole) / 15.0;
        }
        step(f, [a, m], [fa, flm, fm], left, 0.5 * tol, depth - 1)
            + step(f, [m, b], [fm, frm, fb], right, 0.5 * tol, depth - 1)
    }
    let (fa, fm, fb) = (f(a), f(0.5 * (a + b)), f(b));
    let whole = (b - a) / 6.0 * (fa + 4.0 * fm + fb);
    step(f, [a, b], [fa, fm, fb], whole, tol, 48)
}

/// The disc's area inside [x0, x1] x [y0, y1] by adaptive Simpson over x of the chord's
/// length inside [y0, y1] (the integrand is split at the disc's x extent, where it is not
/// smooth, and nowhere else).
fn disc_rect_by_simpson(centre: Point, r: f64, [x0, x1]: [f64; 2], [y0, y1]: [f64; 2]) -> f64 {
    let chord = |x: f64| {
        let s = (r * r - (x - centre[0]).powi(2)).max(0.0).sqrt();
        ((centre[1] + s).min(y1) - (centre[1] - s).max(y0)).max(0.0)
    };
    let (a, b) = (x0.max(centre[0] - r), x1.min(centre[0] + r));
    if a >= b {
        return 0.0;
    }
    simpson(&chord, a, b, 1e-13)
}

#[test]
fn hand_computed_triangle_pixels() {
    // Half of pixel (0, 0), in both windings.
    assert_eq!(triangle_pixel_area([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], 0, 0), 0.5);
    assert_eq!(triangle_pixel_area([[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]], 0, 0), 0.5);
    // x + y <= 2: pixel (0, 0) whole, (1, 0) and (0, 1) half, (1, 1) none.
    let tri = [[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]];
    assert_eq!(triangle_pixel_area(tri, 0, 0), 1.0);
    assert_eq!(triangle_pixel_area(tri, 1, 0), 0.5);
    assert_eq!(triangle_pixel_area(tri, 0, 1), 0.5);
    assert_eq!(triangle_pixel_area(tri, 1, 1), 0.0);
    // A triangle inside one pixel: its own area (base 0.5, height 0.25).
    assert!((triangle_pixel_area([[3.25, 4.5], [3.75, 4.5], [3.5, 4.75]], 3, 4) - 0.0625).abs() < 1e-15);
    // A half-plane through the pixel centre at 30 degrees covers half of it.
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let big = [
        [5.5 + 10.0 * c, 5.5 + 10.0 * s],
        [5.5 - 10.0 * c, 5.5 - 10.0 * s],
        [5.5 + 10.0 * s, 5.5 - 10.0 * c],
    ];
    assert!((triangle_pixel_area(big, 5, 5) - 0.5).abs() < 1e-14);
}

#[test]
fn pixels_wholly_inside_are_exactly_one() {
    let tri = [[0.3, 0.7], [61.9, 4.1], [12.6, 57.3]];
    let cov = triangle_coverage(tri, 64, 64);
    // Pixels (10..14, 10..14) are well inside this triangle.
    for py in 10..14 {
        for px in 10..14 {
            assert_eq!(cov[py * 64 + px], 1.0, "pixel ({px}, {py})");
        }
    }
    let disc = disc_coverage([20.3, 19.8], 9.6, 40, 40);
    for py in 15..25 {
        for px in 15..25 {
            assert_eq!(disc[py * 40 + px], 1.0, "pixel ({px}, {py})");
        }
    }
    // A disc of radius 0.1 px in one pixel: its whole area there, nothing around.
    let tiny = disc_coverage([7.45, 2.61], 0.1, 10, 5);
    assert!((tiny[2 * 10 + 7] - PI * 0.01).abs() < 1e-15);
    assert_eq!(tiny.iter().filter(|a| **a > 0.0).count(), 1);
}

#[test]
fn disc_areas_sum_to_pi_r_squared() {
    // Sub-pixel radii (inside one pixel, across a pixel corner), and larger discs.
    for (centre, r) in [
        ([10.5, 10.5], 0.3),
        ([10.0, 10.0], 0.3),
        ([10.93, 9.02], 0.45),
        ([20.1, 19.7], 0.71),
        ([30.0, 30.0], 5.0),
        ([31.27, 29.61], 5.3),
        ([32.0, 32.5], 17.25),
        ([32.123456789, 31.987654321], 29.9),
    ] {
        let cov = disc_coverage(centre, r, 64, 64);
        assert!(cov.iter().all(|a| (0.0..=1.0).contains(a)));
        let sum: f64 = cov.iter().sum();
        assert!(
            (sum - PI * r * r).abs() < 1e-9,
            "centre {centre:?} r {r}: {sum} vs {}",
            PI * r * r
        );
    }
}

#[test]
fn a_disc_cut_by_the_image_edge_sums_to_its_part_in_the_image() {
    // Cut by the left and top edges, then by the right and bottom ones.
    for (centre, r) in [([2.3, 3.1], 6.4), ([37.7, 18.45], 4.2), ([-1.5, 12.0], 3.0)] {
        let (w, h) = (40, 20);
        let sum: f64 = disc_coverage(centre, r, w, h).iter().sum();
        let inside = disc_rect_by_simpson(centre, r, [0.0, w as f64], [0.0, h as f64]);
        assert!(inside < PI * r * r - 1.0, "the disc is really cut");
        assert!(
            (sum - inside).abs() < 1e-9,
            "centre {centre:?} r {r}: {sum} vs {inside}"
        );
    }
}

#[test]
fn disc_pixels_agree_with_adaptive_simpson() {
    // Every pixel a rim crosses, for radii from sub-pixel to large, against an independent
    // integration of the clipped chord.
    for (centre, r) in [
        ([5.37, 5.81], 0.42),
        ([8.0, 8.5], 2.5),
        ([50.31, 49.77], 37.3),
        ([3.5, 60.2], 55.55),
    ] {
        let mut worst = 0.0f64;
        for py in 0..100u32 {
            for px in 0..100u32 {
                let exact = disc_pixel_area(centre, r, px, py);
                if exact == 0.0 || exact == 1.0 {
                    continue;
                }
                let (x, y) = (px as f64, py as f64);
                let simpson = disc_rect_by_simpson(centre, r, [x, x + 1.0], [y, y + 1.0]);
                worst = worst.max((exact - simpson).abs());
            }
        }
        assert!(
            worst < 1e-10,
            "centre {centre:?} r {r}: worst pixel differs by {worst:e}"
        );
    }
}

#[test]
fn shapes_that_cover_nothing_and_unreasonable_inputs() {
    let nan = f64::NAN;
    assert_eq!(triangle_pixel_area([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]], 0, 0), 0.0);
    assert_eq!(triangle_pixel_area([[0.5, 0.5]; 3], 0, 0), 0.0);
    assert_eq!(triangle_pixel_area([[nan, 0.0], [1.0, 0.0], [0.0, 1.0]], 0, 0), 0.0);
    assert_eq!(
        triangle_pixel_area([[f64::INFINITY, 0.0], [1.0, 0.0], [0.0, 1.0]], 0, 0),
        0.0
    );
    assert!(triangle_coverage([[nan, 0.0], [9.0, 0.0], [0.0, 9.0]], 8, 8)
        .iter()
        .all(|a| *a == 0.0));
    assert_eq!(polygon_pixel_area(&[[0.0, 0.0], [1.0, 0.0]], 0, 0), 0.0);
    for r in [0.0, -1.0, nan, f64::INFINITY] {
        assert_eq!(disc_pixel_area([0.5, 0.5], r, 0, 0), 0.0, "r {r}");
        assert!(disc_coverage([0.5, 0.5], r, 4, 4).iter().all(|a| *a == 0.0));
    }
    assert_eq!(disc_pixel_area([nan, 0.5], 1.0, 0, 0), 0.0);
    // Empty images; shapes wholly outside the image.
    assert!(triangle_coverage([[0.0, 0.0], [9.0, 0.0], [0.0, 9.0]], 0, 5).is_empty());
    assert!(disc_coverage([1.0, 1.0], 3.0, 7, 0).is_empty());
    assert!(triangle_coverage([[-9.0, 0.0], [-1.0, 0.0], [-5.0, 9.0]], 8, 8)
        .iter()
        .all(|a| *a == 0.0));
    assert!(disc_coverage([20.0, -3.0], 2.5, 8, 8).iter().all(|a| *a == 0.0));
    // Huge shapes over the whole image: every pixel exactly covered.
    let huge = [[-1e9, -1e9], [1e9, -1e9], [0.0, 1e9]];
    assert!(triangle_coverage(huge, 16, 16).iter().all(|a| *a == 1.0));
    assert!(disc_coverage([3.0, 4.0], 1e100, 16, 16).iter().all(|a| *a == 1.0));
    // A huge triangle whose edge y = x crosses the image: below it all, on it half (to the
    // rounding of coordinates of 1e6).
    let edge = [[-1e6, -1e6], [1e6, 1e6], [-1e6, 1e6]];
    let cov = triangle_coverage(edge, 8, 8);
    for (i, a) in cov.iter().enumerate() {
        let (px, py) = (i % 8, i / 8);
        let want = if px < py {
            1.0
        } else if px == py {
            0.5
        } else {
            0.0
        };
        assert!((a - want).abs() < 1e-9, "pixel ({px}, {py}): {a}");
    }
    // Coordinates near the f64 limit: nothing exact is promised, but no NaN, no panic.
    for tri in [
        [[-1e300, -1e300], [1e300, 1e300], [-1e300, 1e300]],
        [[-1.7e308, -1.7e308], [1.7e308, -1.7e308], [0.0, 1.7e308]],
    ] {
        assert!(
            triangle_coverage(tri, 8, 8).iter().all(|a| (0.0..=1.0).contains(a)),
            "{tri:?}"
        );
    }
    assert!(disc_coverage([1e300, -1e300], 1e300, 8, 8)
        .iter()
        .all(|a| (0.0..=1.0).contains(a)));
}

#[test]
fn box_resolved_error_of_known_values() {
    let e = box_resolved_error(&[0.0, 0.5, 1.0, 0.25], &[0.0, 0.75, 0.5, 0.25]);
    assert_eq!(e.max_abs, 0.5);
    assert_eq!(e.mean_abs, 0.1875);
    assert!((e.rms - (0.3125f64 / 4.0).sqrt()).abs() < 1e-16);
    let zero = CoverageError {
        max_abs: 0.0,
        mean_abs: 0.0,
        rms: 0.0,
    };
    assert_eq!(box_resolved_error(&[], &[]), zero);
    // A NaN measurement is the worst pixel, not a skipped one.
    assert!(box_resolved_error(&[0.5, 0.5], &[f64::NAN, 0.5]).max_abs.is_nan());
    assert!(box_resolved_error(&[0.5, 0.5], &[0.5, f64::NAN]).max_abs.is_nan());
}

/// The box-filtered coverage an `n` x `n` grid of samples per pixel measures (what a
/// supersampling renderer resolves to).
fn sampled_triangle(tri: [Point; 3], w: u32, h: u32, n: u32) -> Vec<f64> {
    let inside = |x: f64, y: f64| {
        let e = |a: Point, b: Point| (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
        let d = [e(tri[0], tri[1]), e(tri[1], tri[2]), e(tri[2], tri[0])];
        d.iter().all(|v| *v >= 0.0) || d.iter().all(|v| *v <= 0.0)
    };
    let mut out = vec![];
    for py in 0..h {
        for px in 0..w {
            let mut hits = 0;
            for j in 0..n {
                for i in 0..n {
                    let x = px as f64 + (i as f64 + 0.5) / n as f64;
                    let y = py as f64 + (j as f64 + 0.5) / n as f64;
                    hits += inside(x, y) as u32;
                }
            }
            out.push(hits as f64 / (n * n) as f64);
        }
    }
    out
}

#[test]
fn supersampled_coverage_converges_to_the_exact_one() {
    let tri = [[1.3, 2.9], [29.6, 7.2], [9.1, 27.7]];
    let exact = triangle_coverage(tri, 32, 32);
    let errors: Vec<CoverageError> = [1, 4, 16]
        .into_iter()
        .map(|n| box_resolved_error(&exact, &sampled_triangle(tri, 32, 32, n)))
        .collect();
    // One sample per pixel is off by up to a whole pixel on the edges; an n x n grid by at
    // most about the edge length inside the pixel (<= sqrt 2) over n.
    assert!(errors[0].max_abs > 0.25, "{errors:?}");
    assert!(
        errors[0].max_abs > errors[1].max_abs && errors[1].max_abs > errors[2].max_abs,
        "{errors:?}"
    );
    assert!(errors[1].max_abs <= 2f64.sqrt() / 4.0, "{:?}", errors[1]);
    assert!(errors[2].max_abs <= 2f64.sqrt() / 16.0, "{:?}", errors[2]);
    assert!(
        errors[0].rms > errors[1].rms && errors[1].rms > errors[2].rms,
        "{errors:?}"
    );
}

/// A convex quadrilateral: four points at increasing angles on an ellipse.
fn convex_quad() -> impl Strategy<Value = [Point; 4]> {
    (
        (8.0..24.0f64, 8.0..24.0f64),
        (1.0..7.5f64, 1.0..7.5f64),
        0.0..std::f64::consts::TAU,
        prop::array::uniform4(0.2..1.5f64),
    )
        .prop_map(|((cx, cy), (rx, ry), start, gaps)| {
            let total: f64 = gaps.iter().sum();
            let mut angle = start;
            gaps.map(|g| {
                let p = [cx + rx * angle.cos(), cy + ry * angle.sin()];
                angle += g / total * std::f64::consts::TAU;
                p
            })
        })
}

fn point(lo: f64, hi: f64) -> impl Strategy<Value = Point> {
    prop::array::uniform2(lo..hi)
}

proptest! {
    #[test]
    fn triangle_areas_sum_to_the_shoelace_area(tri in prop::array::uniform3(point(0.0, 24.0))) {
        let cov = triangle_coverage(tri, 24, 24);
        prop_assert!(cov.iter().all(|a| (0.0..=1.0).contains(a)));
        let sum: f64 = cov.iter().sum();
        prop_assert!((sum - shoelace(&tri)).abs() < 1e-9, "{} vs {}", sum, shoelace(&tri));
    }

    #[test]
    fn image_coverage_is_the_pixel_area(tri in prop::array::uniform3(point(-8.0, 24.0))) {
        let cov = triangle_coverage(tri, 16, 16);
        for (i, a) in cov.iter().enumerate() {
            let (px, py) = (i as u32 % 16, i as u32 / 16);
            prop_assert_eq!(a.to_bits(), triangle_pixel_area(tri, px, py).to_bits());
        }
    }

    #[test]
    fn triangles_sharing_an_edge_add_up_to_the_quad(q in convex_quad()) {
        // Both diagonals; each triangle of the pair in both windings.
        for (t1, t2) in [
            ([q[0], q[1], q[2]], [q[2], q[3], q[0]]),
            ([q[1], q[2], q[3]], [q[1], q[0], q[3]]),
        ] {
            let (a, b) = (triangle_coverage(t1, 32, 32), triangle_coverage(t2, 32, 32));
            for py in 0..32u32 {
                for px in 0..32u32 {
                    let i = (py * 32 + px) as usize;
                    let quad = polygon_pixel_area(&q, px, py);
                    prop_assert!((a[i] + b[i] - quad).abs() < 1e-13, "pixel ({}, {}): {} + {} vs {}", px, py, a[i], b[i], quad);
                }
            }
        }
    }

    #[test]
    fn random_discs_sum_to_their_area(c in point(10.0, 30.0), r in 0.05..9.9f64) {
        let sum: f64 = disc_coverage(c, r, 40, 40).iter().sum();
        prop_assert!((sum - PI * r * r).abs() < 1e-9);
    }
}
