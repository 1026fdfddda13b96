//! Factoring the view matrix into a Euclidean part and a sparse part (seed 001):
//! lighting coordinates (LC) and the adapted W-clip.
//!
//! `V = clip_from_world` (see [`crate::pipeline::clip`] for clip space). For a view in
//! *canonical form* (the near and far faces of the view volume are rectangles in world
//! space) we find
//!
//! ```text
//! perspective:  V = G Q E      parallel:  V = S H E
//! E = [R | t]   Euclidean (R a rotation, det +1): lighting_from_world
//! Q = I, Q[3][2] = qz          shear in w: w = qz z + 1 (LC z = 0 on the far plane)
//! G = diag(sx, sy, sz, l) + tx, ty in column 3     (no z translation)
//! H = I, H[0][2] = hx, H[1][2] = hy                shear of x, y by z (oblique views)
//! S = diag(sx, sy, sz, l) + tx, ty, tz in column 3
//! ```
//!
//! `l` is V's homogeneous scale (the paper normalises it to 1; we keep it so that the
//! product reproduces V exactly, sign of w included). LC = E * WC: angles and distances are
//! those of world space, so lighting there equals lighting in WC, while `GQ` (one multiply-add
//! for w, then a scale/translate) takes LC to clip space cheaply.
//!
//! The canonical-form test is seed 001 section 3.2: with `V^-1`'s columns
//! `A, B, P, O` (the images of clip space's x and y directions, of its z point at infinity —
//! the eye — and of its origin, here the centre of the far face) and `D = A + B + P + O`,
//! V is canonical iff V is non-singular, `A` and `B` are ideal (`w = 0`), orthogonal, and
//! (perspective) `P`, `O`, `D` are not ideal. E then rotates the far face onto LC's z = 0
//! plane with x along `A`, z towards the eye, and puts the eye on LC's z axis. The
//! resulting `V E^-1` is checked against the sparse form too; anything else is
//! [`NotFactorizable`], and the caller lights in world coordinates instead (seed 000 9.5:
//! E = I, GQ = V) with a warning.
//!
//! Tolerances are relative: a quantity that must vanish must be below `tolerance` times the
//! magnitude of what it is computed from (default [`DEFAULT_TOLERANCE`]).

use glam::{DMat4, DVec3, DVec4};

use super::clip::{clip_polygon, ClipError, ClipOptions, ClipPolygon, PyramidMode};
use super::real::Real;

/// Default relative tolerance of the canonical-form test.
pub const DEFAULT_TOLERANCE: f64 = 1e-9;

/// Why a view matrix has no G Q E / S H E factorisation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NotFactorizable {
    /// A component is NaN or infinite.
    NonFinite,
    /// V is singular (or numerically so).
    Singular,
    /// The images of clip x / y directions are not directions (`A_w` or `B_w` != 0): the
    /// near and far faces are not parallelograms.
    SidesNotParallel,
    /// The images of clip x and y directions are not orthogonal: the faces are not
    /// rectangles.
    NotRectangular,
    /// The eye, the far-face centre or a near corner is at infinity in a perspective view.
    PointAtInfinity,
    /// `V E^-1` did not come out sparse (a numerically borderline view).
    NotSparse,
}

impl std::fmt::Display for NotFactorizable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let why = match self {
            NotFactorizable::NonFinite => "it has a NaN or infinite entry",
            NotFactorizable::Singular => "it is singular",
            NotFactorizable::SidesNotParallel => "the near and far faces of its view volume are not parallelograms",
            NotFactorizable::NotRectangular => "the near and far faces of its view volume are not rectangles",
            NotFactorizable::PointAtInfinity => "its eye point or far face is at infinity",
            NotFactorizable::NotSparse => "the remaining factor is not a shear plus scale/translate",
        };
        write!(f, "view matrix is not in canonical form: {why}")
    }
}

impl std::error::Error for NotFactorizable {}

/// `V = G Q E` for a perspective view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PerspectiveFactors {
    pub g: DMat4,
    pub q: DMat4,
    /// lighting_from_world.
    pub e: DMat4,
    /// `Q[3][2]`: `w = qz * z_lc + 1`; the eye is at LC `(0, 0, -1/qz)`.
    pub qz: f64,
}

/// `V = S H E` for a parallel view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParallelFactors {
    pub s: DMat4,
    pub h: DMat4,
    /// lighting_from_world.
    pub e: DMat4,
}

/// The factorisation of a canonical view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ViewFactors {
    Perspective(PerspectiveFactors),
    Parallel(ParallelFactors),
}

impl ViewFactors {
    /// E: lighting_from_world.
    pub fn lighting_from_world(&self) -> DMat4 {
        match self {
            ViewFactors::Perspective(p) => p.e,
            ViewFactors::Parallel(p) => p.e,
        }
    }
    /// G Q or S H: clip_from_lighting.
    pub fn clip_from_lighting(&self) -> DMat4 {
        match self {
            ViewFactors::Perspective(p) => p.g * p.q,
            ViewFactors::Parallel(p) => p.s * p.h,
        }
    }
    /// The product of the factors (= V up to rounding).
    pub fn product(&self) -> DMat4 {
        self.clip_from_lighting() * self.lighting_from_world()
    }
}

/// Row `r`, column `c` of a column-major glam matrix.
#[inline]
fn at(m: &DMat4, r: usize, c: usize) -> f64 {
    m.col(c)[r]
}

fn max_abs(m: &DMat4) -> f64 {
    m.to_cols_array().iter().fold(0.0f64, |a, &b| a.max(b.abs()))
}

/// Whether `v` is singular to working precision: `|det v|` at most 1e-12 of Hadamard's bound
/// on it, the product of the row lengths, *and* of the column lengths. Either bound alone
/// depends on where the world's origin is: a camera at (1e6, 1e6, 0) puts 1e6 translations in
/// two rows of V and makes the row bound 1e12 times |det v| for a perfectly regular view (the
/// same camera at (1e6, 0, 0) has one such row and passed). The column bound holds the
/// translation in one column, so the two together are only both small for a matrix that is
/// close to singular whichever way it is scaled.
pub fn is_numerically_singular(v: &DMat4) -> bool {
    let det = v.determinant().abs();
    let by_rows: f64 = (0..4).map(|r| v.row(r).length()).product();
    let by_cols: f64 = (0..4).map(|c| v.col(c).length()).product();
    // Written so that NaN counts as singular.
    !(det > 1e-12 * by_rows.min(by_cols))
}

/// Factors `clip_from_world` with the default tolerance.
pub fn factor_view(clip_from_world: &DMat4) -> Result<ViewFactors, NotFactorizable> {
    factor_view_with_tolerance(clip_from_world, DEFAULT_TOLERANCE)
}

/// Factors `clip_from_world`; `tolerance` is the relative tolerance of the canonical-form
/// test.
pub fn factor_view_with_tolerance(v: &DMat4, tolerance: f64) -> Result<ViewFactors, NotFactorizable> {
    if !v.is_finite() {
        return Err(NotFactorizable::NonFinite);
    }
    let rows = [v.row(0), v.row(1), v.row(2), v.row(3)];
    if is_numerically_singular(v) {
        return Err(NotFactorizable::Singular);
    }
    let inv = v.inverse();
    let (a, b, p, o) = (inv.col(0), inv.col(1), inv.col(2), inv.col(3));
    let ideal = |x: DVec4| x.w.abs() <= tolerance * x.length();
    if !ideal(a) || !ideal(b) {
        return Err(NotFactorizable::SidesNotParallel);
    }
    let (a3, b3) = (a.truncate(), b.truncate());
    if a3.dot(b3).abs() > tolerance * a3.length() * b3.length() {
        return Err(NotFactorizable::NotRectangular);
    }
    let x_axis = a3.normalize();
    let far_normal = a3.cross(b3).normalize();
    let row3 = rows[3];
    let parallel = row3.truncate().length() <= tolerance * row3.length();
    if parallel {
        // O is the far-face centre; the near-face centre is O + P (P ideal), so P / O_w
        // points from the far face towards the near face.
        let towards_near = p.truncate() / o.w;
        let side = towards_near.dot(far_normal);
        if side == 0.0 || !side.is_finite() {
            return Err(NotFactorizable::Singular);
        }
        let z_axis = far_normal * side.signum();
        let origin = o.truncate() / o.w;
        let e = euclidean(x_axis, z_axis, origin);
        let sh = *v * euclidean_inverse(&e);
        let scale = max_abs(&sh);
        for (r, c) in [(0, 1), (1, 0), (2, 0), (2, 1), (3, 0), (3, 1), (3, 2)] {
            if at(&sh, r, c).abs() > tolerance * scale {
                return Err(NotFactorizable::NotSparse);
            }
        }
        let (sx, sy, sz, l) = (at(&sh, 0, 0), at(&sh, 1, 1), at(&sh, 2, 2), at(&sh, 3, 3));
        let s = DMat4::from_cols(
            DVec4::new(sx, 0.0, 0.0, 0.0),
            DVec4::new(0.0, sy, 0.0, 0.0),
            DVec4::new(0.0, 0.0, sz, 0.0),
            DVec4::new(at(&sh, 0, 3), at(&sh, 1, 3), at(&sh, 2, 3), l),
        );
        let mut h = DMat4::IDENTITY;
        h.col_mut(2)[0] = at(&sh, 0, 2) / sx;
        h.col_mut(2)[1] = at(&sh, 1, 2) / sy;
        return Ok(ViewFactors::Parallel(ParallelFactors { s, h, e }));
    }
    let d = a + b + p + o;
    let finite_point = |x: DVec4| x.w.abs() > tolerance * x.length();
    if !finite_point(p) || !finite_point(o) || !finite_point(d) {
        return Err(NotFactorizable::PointAtInfinity);
    }
    let eye = p.truncate() / p.w;
    let far_centre = o.truncate() / o.w;
    let height = (eye - far_centre).dot(far_normal);
    if height == 0.0 || !height.is_finite() {
        return Err(NotFactorizable::Singular);
    }
    // z points from the far face towards the eye; the LC origin is the eye's foot on the
    // far plane, so the eye sits on the LC z axis at z = |height|.
    let z_axis = far_normal * height.signum();
    let origin = eye - z_axis * height.abs();
    let e = euclidean(x_axis, z_axis, origin);
    let gq = *v * euclidean_inverse(&e);
    let l = at(&gq, 3, 3);
    if l == 0.0 {
        return Err(NotFactorizable::NotSparse);
    }
    let qz = at(&gq, 3, 2) / l;
    let scale = max_abs(&gq);
    for (r, c) in [(0, 1), (1, 0), (2, 0), (2, 1), (2, 3), (3, 0), (3, 1)] {
        if at(&gq, r, c).abs() > tolerance * scale {
            return Err(NotFactorizable::NotSparse);
        }
    }
    // Points on the LC z axis all project to one pixel: column 2 = qz * column 3 in x, y.
    for r in 0..2 {
        if (at(&gq, r, 2) - qz * at(&gq, r, 3)).abs() > tolerance * scale {
            return Err(NotFactorizable::NotSparse);
        }
    }
    let g = DMat4::from_cols(
        DVec4::new(at(&gq, 0, 0), 0.0, 0.0, 0.0),
        DVec4::new(0.0, at(&gq, 1, 1), 0.0, 0.0),
        DVec4::new(0.0, 0.0, at(&gq, 2, 2), 0.0),
        DVec4::new(at(&gq, 0, 3), at(&gq, 1, 3), 0.0, l),
    );
    let mut q = DMat4::IDENTITY;
    q.col_mut(2)[3] = qz;
    Ok(ViewFactors::Perspective(PerspectiveFactors { g, q, e, qz }))
}

/// The rigid map taking `origin` to 0 and the orthonormal frame (x, z x x, z) to the axes.
fn euclidean(x_axis: DVec3, z_axis: DVec3, origin: DVec3) -> DMat4 {
    // Re-orthogonalise x against z so the frame is orthonormal to rounding even when the
    // canonical test passed only within tolerance.
    let x = (x_axis - z_axis * x_axis.dot(z_axis)).normalize();
    let y = z_axis.cross(x);
    let r = [x, y, z_axis];
    DMat4::from_cols(
        DVec4::new(r[0].x, r[1].x, r[2].x, 0.0),
        DVec4::new(r[0].y, r[1].y, r[2].y, 0.0),
        DVec4::new(r[0].z, r[1].z, r[2].z, 0.0),
        DVec4::new(-r[0].dot(origin), -r[1].dot(origin), -r[2].dot(origin), 1.0),
    )
}

/// The inverse of a rigid map `[R | t]`: `[R^T | -R^T t]` (exact up to rounding, no
/// general inversion).
pub fn euclidean_inverse(e: &DMat4) -> DMat4 {
    let r = glam::DMat3::from_mat4(*e);
    let rt = r.transpose();
    let t = e.col(3).truncate();
    DMat4::from_mat3_translation(rt, -(rt * t))
}

/// Where the adapted W-clip (seed 001, 4.3) keeps geometry, in LC z.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WClipRegion {
    /// The viewport lies on one side of the eye plane: keep `z_min <= z <= z_max`. This one
    /// slab clip is the near clip, the far clip and the W-clip at once.
    Slab { z_min: f64, z_max: f64 },
    /// The viewport straddles the eye plane (double pyramid): the view volume wraps around
    /// infinity, so keep `z <= z_min` and `z >= z_max`, removing the slab that contains
    /// the eye plane (two pieces).
    OutsideSlab { z_min: f64, z_max: f64 },
}

/// The near/far clip done in LC before the perspective divide (seed 001, 4.3): in LC the
/// near and far planes are `z = const`, parallel to the eye plane `w = 0`, so clipping to
/// them in 3D (linear interpolation in LC) also removes everything that would divide by
/// `w <= 0`; x and y can then be clipped after the divide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptedWClip {
    /// LC z of the near plane (clip z = w).
    pub z_near: f64,
    /// LC z of the far plane (clip z = 0).
    pub z_far: f64,
    /// LC z of the eye plane (clip w = 0); infinite for parallel views.
    pub z_eye: f64,
    pub region: WClipRegion,
}

impl AdaptedWClip {
    pub fn new(factors: &ViewFactors) -> AdaptedWClip {
        let clip_from_lighting = factors.clip_from_lighting();
        // clip z = a z + b, clip w = c z + d along the LC z axis (x, y do not enter them).
        let (a, b) = (at(&clip_from_lighting, 2, 2), at(&clip_from_lighting, 2, 3));
        let (c, d) = (at(&clip_from_lighting, 3, 2), at(&clip_from_lighting, 3, 3));
        // near: a z + b = c z + d; far: a z + b = 0; eye: c z + d = 0.
        let z_near = (d - b) / (a - c);
        let z_far = -b / a;
        let z_eye = if c == 0.0 { f64::INFINITY } else { -d / c };
        let (z_min, z_max) = (z_near.min(z_far), z_near.max(z_far));
        let straddles = z_eye.is_finite() && z_min < z_eye && z_eye < z_max;
        let region = if straddles {
            WClipRegion::OutsideSlab { z_min, z_max }
        } else {
            WClipRegion::Slab { z_min, z_max }
        };
        AdaptedWClip {
            z_near,
            z_far,
            z_eye,
            region,
        }
    }

    /// Clips a polygon given in homogeneous LC (usually w = 1) to the kept region. The
    /// pieces can then go through `clip_from_lighting` and be divided by w safely.
    pub fn clip<T: Real>(&self, poly: &ClipPolygon<T>) -> Result<Vec<ClipPolygon<T>>, ClipError> {
        let opts = ClipOptions::default();
        let (zero, one) = (T::ZERO, T::ONE);
        // z - z0 w >= 0 keeps z >= z0; z0 w - z >= 0 keeps z <= z0.
        let above = |z0: f64| [zero, zero, one, -T::from_f64(z0)];
        let below = |z0: f64| [zero, zero, -one, T::from_f64(z0)];
        match self.region {
            WClipRegion::Slab { z_min, z_max } => {
                clip_polygon(poly, 0, &[above(z_min), below(z_max)], PyramidMode::Single, opts)
            }
            WClipRegion::OutsideSlab { z_min, z_max } => {
                let mut pieces = clip_polygon(poly, 0, &[below(z_min)], PyramidMode::Single, opts)?;
                pieces.extend(clip_polygon(poly, 0, &[above(z_max)], PyramidMode::Single, opts)?);
                Ok(pieces)
            }
        }
    }
}
