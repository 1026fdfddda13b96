//! The camera helpers that build a whole `device_from_object` matrix
//! (src/runtime/transform.rs): the orthographic box and the perspective frustum land on the
//! viewport's corners and on depth 1 (near) and 0 (far), and row-major matrices round-trip.

use glam::{Mat4, Vec4};
use primflow::runtime::transform::{from_rows, ortho, perspective, to_rows};

fn device(m: &Mat4, x: f32, y: f32, z: f32) -> [f64; 3] {
    let p = *m * Vec4::new(x, y, z, 1.0);
    let w = f64::from(p.w);
    [f64::from(p.x) / w, f64::from(p.y) / w, f64::from(p.z) / w]
}

fn close(a: [f64; 3], b: [f64; 3]) {
    for i in 0..3 {
        assert!((a[i] - b[i]).abs() < 1e-4, "{a:?} vs {b:?}");
    }
}

#[test]
fn ortho_maps_box_corners() {
    let m = ortho(-1.0, 1.0, -1.0, 1.0, 1.0, 3.0, [200, 100]);
    close(device(&m, -1.0, 1.0, -1.0), [0.0, 0.0, 1.0]);
    close(device(&m, 1.0, -1.0, -3.0), [200.0, 100.0, 0.0]);
    close(device(&m, 0.0, 0.0, -2.0), [100.0, 50.0, 0.5]);
}

#[test]
fn perspective_near_is_one_far_is_zero() {
    let m = perspective(90.0, 1.0, 10.0, 200, 100);
    // Centre of view at the near plane and at the far plane.
    close(device(&m, 0.0, 0.0, -1.0), [100.0, 50.0, 1.0]);
    close(device(&m, 0.0, 0.0, -10.0), [100.0, 50.0, 0.0]);
    // fov 90: y = +distance is the top edge; x = aspect * distance the right edge.
    close(device(&m, 0.0, 5.0, -5.0), [100.0, 0.0, 1.0 / 9.0 * (10.0 / 5.0 - 1.0)]);
    close(device(&m, 2.0 * 5.0, 0.0, -5.0), [200.0, 50.0, 1.0 / 9.0]);
}

#[test]
fn row_major_round_trip() {
    let rows: [f32; 16] = std::array::from_fn(|i| i as f32);
    let m = from_rows(&rows);
    // Row 0 is (0 1 2 3): x_dev = 0*x + 1*y + 2*z + 3*w.
    assert_eq!((m * Vec4::new(0.0, 1.0, 0.0, 0.0)).x, 1.0);
    assert_eq!(to_rows(&m), rows);
}
