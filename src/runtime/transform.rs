//! Small camera helpers that return a whole `device_from_object` matrix (glam, column
//! vectors, `p_device = M * p_object`), for callers that build the device transform
//! themselves and hand it to `Renderer::set_transform`. The renderer's own cameras go through
//! the geometry pipeline ([`crate::pipeline::transform`]) and agree with these.
//!
//! Device space: x and y in pixels (x right, y down: row 0 is the top image row), z in depth
//! units in [0, 1] where LARGER IS NEARER, all after dividing by w. Both helpers treat the
//! object space as the eye space of a camera at the origin looking down -z with y up, so a
//! scene written for them appears upright.

use glam::{Mat4, Vec4};

/// Orthographic: the eye-space box x in [left, right], y in [bottom, top], z in [-far, -near]
/// maps to the viewport (0..width, height..0) of `viewport` = [width, height] and depth (near -> 1, far -> 0).
pub fn ortho(left: f32, right: f32, bottom: f32, top: f32, near: f32, far: f32, viewport: [u32; 2]) -> Mat4 {
    let (w, h) = (viewport[0] as f32, viewport[1] as f32);
    let sx = w / (right - left);
    let sy = h / (top - bottom);
    let sz = 1.0 / (far - near);
    // Rows: x_dev = (x - left) * sx; y_dev = (top - y) * sy; z_dev = (z + far) * sz.
    Mat4::from_cols(
        Vec4::new(sx, 0.0, 0.0, 0.0),
        Vec4::new(0.0, -sy, 0.0, 0.0),
        Vec4::new(0.0, 0.0, sz, 0.0),
        Vec4::new(-left * sx, top * sy, far * sz, 1.0),
    )
}

/// Perspective with vertical field of view `fov_y_degrees`, aspect `width/height`, and
/// near/far distances: eye-space points map to homogeneous device coordinates whose divide
/// by w (= -z, the distance) gives pixels and a reversed depth, 1 at the near plane and 0 at
/// the far plane (nearer is larger, so precision is spread like a reversed-Z buffer).
pub fn perspective(fov_y_degrees: f32, near: f32, far: f32, width: u32, height: u32) -> Mat4 {
    let (w, h) = (width as f32, height as f32);
    let focal = 1.0 / (fov_y_degrees.to_radians() * 0.5).tan();
    let aspect = w / h;
    // Clip: x_c = focal/aspect * x, y_c = focal * y, w_c = -z.
    // Device (homogeneous): x_h = w/2 (x_c + w_c), y_h = h/2 (w_c - y_c),
    // z_h = n/(f-n) z + n f/(f-n), so z_h / w_c is 1 at z = -n and 0 at z = -f.
    let (hw, hh) = (w * 0.5, h * 0.5);
    let depth_scale = near / (far - near);
    let depth_offset = near * far / (far - near);
    Mat4::from_cols(
        Vec4::new(hw * focal / aspect, 0.0, 0.0, 0.0),
        Vec4::new(0.0, -hh * focal, 0.0, 0.0),
        Vec4::new(-hw, -hh, depth_scale, -1.0),
        Vec4::new(0.0, 0.0, depth_offset, 0.0),
    )
}

/// A matrix given row-major (as in the scene format and the argument block).
pub fn from_rows(rows: &[f32; 16]) -> Mat4 {
    Mat4::from_cols_array(rows).transpose()
}

/// Row-major components (the argument block's matrix layout).
pub fn to_rows(m: &Mat4) -> [f32; 16] {
    m.transpose().to_cols_array()
}
