//! Huge coordinates: the homogeneous clipper with projected vertices tens of thousands of
//! view widths away, against a 2D f64 reference.

use super::{area_2d, assert_inside_and_finite, clip_square_2d};
use crate::support::*;

use primflow::pipeline::clip::{clip_polygon_to_view, ClipOptions, ClipPolygon, PyramidMode};
use primflow::pipeline::face::projected_area;

/// 2,000 triangles with projected coordinates up to 3e4 and 1e5 (as dEQP's clipping cases
/// place vertices 3e4 to 7e4 outside the view) clipped in f64 and f32: no NaN, every piece
/// inside the view volume, the clipped area that of the projected triangle clipped to the
/// square in f64. Source: the 2D Sutherland-Hodgman reference in f64; tolerance 1e-6 of the
/// area in f64, 1e-6 of a screen-sized area in f32 (one rounding of each output vertex).
#[test]
fn huge_coordinates_clip_without_nan_and_match_an_f64_reference() {
    let mut rng = SplitMix(7);
    let mut checked = 0;
    let mut partial = 0;
    let mut worst32 = 0.0f64;
    for _ in 0..2000 {
        let tri: Vec<[f64; 4]> = if rng.next().is_multiple_of(2) {
            (0..3)
                .map(|_| {
                    let w = rng.range(0.2, 16.0);
                    // x, y up to 30000 w (projected +-30000) and sometimes +-1e5 outright.
                    let big = if rng.next().is_multiple_of(4) { 1e5 } else { 30000.0 * w };
                    [rng.range(-big, big), rng.range(-big, big), rng.range(0.0, w), w]
                })
                .collect()
        } else {
            // Projected vertices 30000 away, with one edge through a random point of the
            // screen, so the triangle covers it only partly.
            let c = [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)];
            let a = rng.range(0.0, std::f64::consts::TAU);
            let (d, n) = ([a.cos(), a.sin()], [-a.sin(), a.cos()]);
            let reach = [(30000.0, 0.0), (-30000.0, 0.0), (rng.range(-3e4, 3e4), 30000.0)];
            reach
                .iter()
                .map(|&(along, across)| {
                    let w = rng.range(0.2, 16.0);
                    let x = c[0] + along * d[0] + across * n[0];
                    let y = c[1] + along * d[1] + across * n[1];
                    [x * w, y * w, rng.range(0.0, w), w]
                })
                .collect()
        };
        let projected: Vec<[f64; 2]> = tri.iter().map(|p| [p[0] / p[3], p[1] / p[3]]).collect();
        let reference = area_2d(&clip_square_2d(projected)).abs();
        let poly64 = ClipPolygon::from_positions(&tri);
        let pieces64 = clip_polygon_to_view(&poly64, &[], PyramidMode::Single, ClipOptions::default()).unwrap();
        let tri32: Vec<[f32; 4]> = tri.iter().map(|p| p.map(|c| c as f32)).collect();
        let poly32 = ClipPolygon::from_positions(&tri32);
        let pieces32 = clip_polygon_to_view(&poly32, &[], PyramidMode::Single, ClipOptions::default()).unwrap();
        for p in &pieces64 {
            assert_inside_and_finite(p, 1e-12);
        }
        for p in &pieces32 {
            assert_inside_and_finite(p, 1e-5);
        }
        let area64: f64 = pieces64.iter().map(|p| projected_area(p.positions()).abs()).sum();
        // The f32 reference is the same triangle rounded to f32, projected in f64.
        let projected32: Vec<[f64; 2]> = tri32
            .iter()
            .map(|p| [p[0] as f64 / p[3] as f64, p[1] as f64 / p[3] as f64])
            .collect();
        let reference32 = area_2d(&clip_square_2d(projected32)).abs();
        let area32: f64 = pieces32
            .iter()
            .map(|p| projected_area(p.positions().map(|v| v.map(|c| c as f64))).abs())
            .sum();
        if reference > 1e-3 {
            checked += 1;
            if reference < 4.0 - 1e-3 {
                partial += 1;
            }
            assert!(
                (area64 - reference).abs() <= 1e-6 * reference,
                "f64: {area64} vs {reference}"
            );
            // f32 output coordinates carry a rounding of ~6e-8 of the screen each; measure
            // the area error against the area of a screen-sized polygon at least.
            worst32 = worst32.max((area32 - reference32).abs() / reference32.max(1.0));
        } else {
            assert!(area64 <= 1e-3 + 1e-9);
        }
    }
    assert!(checked > 100, "only {checked} triangles reached the screen");
    assert!(partial > 50, "only {partial} triangles cut the screen partially");
    // f32 polygons are clipped in f64 too; only the final rounding of each output vertex
    // to f32 remains, well below 1e-6 of the screen area.
    assert!(worst32 <= 1e-6, "worst f32 relative area error {worst32}");
    eprintln!("huge coordinates: {checked} visible ({partial} partial), worst f32 relative area error {worst32:.2e}");
}
