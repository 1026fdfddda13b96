//! The range analysis's intervals (src/mid/bounds.rs): products take the corners and round
//! outward, and a bound past the f32 range (or NaN) is dropped.

use primflow::mid::bounds::{corners, Interval};

#[test]
fn interval_products_take_the_corners_and_round_outward() {
    let a = Interval { lo: -2.0, hi: 3.0 };
    let b = Interval { lo: 16.0, hi: 16.0 };
    let p = corners(a, b, |x, y| x * y).unwrap();
    assert!(p.lo < -32.0 && p.lo > -32.001, "{p:?}");
    assert!(p.hi > 48.0 && p.hi < 48.001, "{p:?}");
}

#[test]
fn bounds_past_f32_range_are_dropped() {
    let a = Interval { lo: 0.0, hi: 1e30 };
    assert!(corners(a, a, |x, y| x * y).is_none());
    assert!(Interval::new(f64::NAN, 0.0).is_none());
}
