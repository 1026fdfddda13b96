//! The sphere written by hand in Rust, in three forms: portable scalar code; SSE4.1 (4
//! pixels per group, the width of the JIT's f32x4 groups, legacy or VEX encoded: what the
//! JIT's sphere is measured against to separate the compiler from the vector width); and
//! AVX2 (8 pixels per step, masked stores). Every form computes the prim's row terms once
//! per row ([`SphereSetup::row_terms`]); the vector forms skip groups with no pixel left.
//!
//! All mirror `prims/sphere.prim` operation for operation: the same space matrices read
//! from the argument block and applied in the JIT's order (`transform` of a 4-component
//! point is `((m[i][3] w + m[i][0] x) + m[i][1] y) + m[i][2] z`, literal zeros included),
//! the same error-free `sphere_power`, the same cancellation-free discriminant evaluated as
//! the prim's polynomial in dx with per-row coefficients, the same root choice per pixel,
//! and no fused multiply-add anywhere. Every operation is an IEEE
//! add/sub/mul/div/sqrt (no libm call), so on the same scene they produce the same depth and
//! normal buffers as the JIT kernel, bit for bit; the benchmark and
//! `tests/prims/handwritten_shapes.rs` check that.
//!
//! Keys served: no bindings, or exactly one 3-component `implicit` binding (the normal, in
//! lighting coordinates). Argument block (see `abi::ArgLayout`): word 0 n_seq; `T` plane
//! indices; the six space matrices (96 floats); `center` (3); `radius`; `object_x`,
//! `object_y`, `object_z` (3 each, lighting coordinates). `Handwritten::kernel` checks the
//! layout against these offsets before handing a kernel out.

// `!(a < b)` is the prims' NaN-rejecting test, kept as written (a NaN fails it).
#![allow(clippy::neg_cmp_op_on_partial_ord)]
use super::isa;
use super::screen_triangle::{bound_or_rect, depth_raw};
#[cfg(target_arch = "x86_64")]
use super::screen_triangle::{depth_raw4, depth_raw8, depth_test8, tile_plane_bases};
use crate::abi::{ArgLayout, Binding, BindingKind, KernelFn, ParamSlot, TileCtx, VariantKey, MODE_BOUND};

/// Word offset of the space matrices for `t` plane-table entries.
pub(crate) const fn spaces_at(t: usize) -> usize {
    1 + t
}

/// Word offset of `center`; `radius` and `object_x/y/z` follow it.
pub(crate) const fn params_at(t: usize) -> usize {
    spaces_at(t) + 96
}

/// Float literals of the prim, converted as the front end converts them (parsed as f64,
/// then rounded to f32).
const LIMIT: f32 = 1e30f64 as f32;
const MARGIN: f32 = 1e-3f64 as f32;

/// Everything the per-pixel code needs, computed once per sphere as the prim does.
pub(crate) struct SphereSetup<const T: usize> {
    pub planes: [u32; T],
    /// The silhouette's bounding box, when the prim's `bound` statement ran.
    pub bound: Option<[f32; 4]>,
    pub sx: f32,
    pub sy: f32,
    pub zc: f32,
    pub g0: [f32; 3],
    pub g1: [f32; 3],
    pub gamma: [f32; 3],
    pub gamma_w: f32,
    /// `n0[3]` and `n1[3]`: the homogeneous w of a pixel step in x and y.
    pub n0w: f32,
    pub n1w: f32,
    pub inv_cw: f32,
    /// The reference point relative to the centre (zero unless the sphere reaches the eye
    /// plane, where the prim measures from device (0, 0, 0.5)).
    pub d0: [f32; 3],
    pub r2: f32,
    pub a: f32,
    pub normal_x: [f32; 3],
    pub normal_y: [f32; 3],
    pub normal_z: [f32; 3],
    pub handedness: f32,
    /// The dX coefficients of the discriminant's vectors, of disc, b and c', and of the
    /// normal's lighting-space image (the prim's `along_x` ... `lit_gamma`).
    pub along_x: [f32; 3],
    pub across_x: [f32; 3],
    pub disc_xx: f32,
    pub b_x: f32,
    pub c_xx: f32,
    pub lit_x: [f32; 3],
    pub lit_gamma: [f32; 3],
}

/// The prim's row terms: everything per pixel that reads Y but not X, for one row.
pub(crate) struct RowTerms {
    pub delta_w_row: f32,
    pub disc_row: f32,
    pub disc_x: f32,
    pub b_row: f32,
    pub c_row: f32,
    pub c_x: f32,
    pub lit_row: [f32; 3],
}

impl<const T: usize> SphereSetup<T> {
    /// The row terms for the row whose pixel centres are `dy` below the centre's
    /// projection, with the prim's operations (the JIT evaluates them once per row too).
    #[inline(always)]
    pub(crate) fn row_terms(&self, dy: f32) -> RowTerms {
        let delta_row: [f32; 3] = std::array::from_fn(|c| self.d0[c] + dy * self.g1[c]);
        let delta_w_row = self.inv_cw + dy * self.n1w;
        let along_row: [f32; 3] = std::array::from_fn(|c| delta_w_row * self.gamma[c] - self.gamma_w * delta_row[c]);
        let across_row = cross3(self.gamma, delta_row);
        RowTerms {
            delta_w_row,
            disc_row: self.r2 * dot3(along_row, along_row) - dot3(across_row, across_row),
            disc_x: 2.0 * (self.r2 * dot3(along_row, self.along_x) - dot3(across_row, self.across_x)),
            b_row: dot3(delta_row, self.gamma) - self.r2 * delta_w_row * self.gamma_w,
            c_row: dot3(delta_row, delta_row) - self.r2 * delta_w_row * delta_w_row,
            c_x: 2.0 * (dot3(delta_row, self.g0) - self.r2 * delta_w_row * self.n0w),
            lit_row: lighting_image(delta_row, [self.normal_x, self.normal_y, self.normal_z]),
        }
    }
}

/// `v[0] * normal_x + v[1] * normal_y + v[2] * normal_z`, in the prim's order.
#[inline(always)]
fn lighting_image(v: [f32; 3], normal: [[f32; 3]; 3]) -> [f32; 3] {
    std::array::from_fn(|k| v[0] * normal[0][k] + v[1] * normal[1][k] + v[2] * normal[2][k])
}

/// The language's `dot` of two 3-vectors, in its order (the prims' bits).
#[inline(always)]
pub(crate) fn dot3(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The language's `cross`, in its order.
#[inline(always)]
pub(crate) fn cross3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `transform` of a 4-component point by a row-major matrix, in the JIT's order.
#[inline(always)]
pub(crate) fn apply_point(m: &[f32; 16], v: [f32; 4]) -> [f32; 4] {
    std::array::from_fn(|i| m[i * 4 + 3] * v[3] + m[i * 4] * v[0] + m[i * 4 + 1] * v[1] + m[i * 4 + 2] * v[2])
}

/// Space matrix `k` (0 device_from_object ... 3 object_from_device, see `abi::ArgLayout`).
///
/// # Safety
/// `args` must hold the space matrices at `at`.
#[inline(always)]
pub(crate) unsafe fn space_matrix(args: *const u32, at: usize, k: usize) -> [f32; 16] {
    // SAFETY: the caller guarantees the 96 words at `at`.
    std::array::from_fn(|i| f32::from_bits(unsafe { *args.add(at + 16 * k + i) }))
}

/// The rounding error of s = a + b (Knuth), as the prim's `exact_sum_error`.
fn exact_sum_error(a: f32, b: f32, s: f32) -> f32 {
    let bv = s - a;
    let av = s - bv;
    (a - av) + (b - bv)
}

/// The rounding error of p = a * b (Dekker), as the prim's `exact_product_error`.
fn exact_product_error(a: f32, b: f32, p: f32) -> f32 {
    let (ca, cb) = (4097.0 * a, 4097.0 * b);
    let (ah, bh) = (ca - (ca - a), cb - (cb - b));
    let (al, bl) = (a - ah, b - bh);
    ((ah * bh - p) + ah * bl + al * bh) + al * bl
}

/// |d|^2 - r^2 to nearly twice float precision, as the prim's `sphere_power`.
fn sphere_power(d: [f32; 3], r: f32) -> f32 {
    let (mut sum, mut err) = (0f32, 0f32);
    for di in d {
        let p = di * di;
        let s = sum + p;
        err += exact_sum_error(sum, p, s) + exact_product_error(di, di, p);
        sum = s;
    }
    let p = r * r;
    let s = sum - p;
    err += exact_sum_error(sum, -p, s) - exact_product_error(r, r, p);
    s + err
}

/// The uniform part of the prim. `None` when it returns before its `bound` statement (no
/// bound recorded, no pixel drawn).
///
/// # Safety
/// `args` must hold the sphere argument block for `T` plane-table entries.
pub(crate) unsafe fn setup<const T: usize>(args: *const u32) -> Option<SphereSetup<T>> {
    let word = |i: usize| unsafe { *args.add(i) };
    let float = |i: usize| f32::from_bits(word(i));
    let p = params_at(T);
    let center = [float(p), float(p + 1), float(p + 2)];
    let r = float(p + 3);
    let object_x = [float(p + 4), float(p + 5), float(p + 6)];
    let object_y = [float(p + 7), float(p + 8), float(p + 9)];
    let object_z = [float(p + 10), float(p + 11), float(p + 12)];
    if !(r > 0.0 && r < LIMIT) {
        return None;
    }
    if !center.iter().all(|c| c.abs() < LIMIT) {
        return None;
    }
    let normal_x = cross3(object_y, object_z);
    let normal_y = cross3(object_z, object_x);
    let normal_z = cross3(object_x, object_y);
    let handedness = if dot3(object_x, normal_x) < 0.0 { -1.0 } else { 1.0 };

    // SAFETY: the layout has the six matrices at spaces_at(T).
    let object_from_device = unsafe { space_matrix(args, spaces_at(T), 3) };
    let device_from_object = unsafe { space_matrix(args, spaces_at(T), 0) };
    let n0 = apply_point(&object_from_device, [1.0, 0.0, 0.0, 0.0]);
    let n1 = apply_point(&object_from_device, [0.0, 1.0, 0.0, 0.0]);
    let n2 = apply_point(&object_from_device, [0.0, 0.0, 1.0, 0.0]);
    let center_device = apply_point(&device_from_object, [center[0], center[1], center[2], 1.0]);
    let m0 = apply_point(&device_from_object, [1.0, 0.0, 0.0, 0.0]);
    let m1 = apply_point(&device_from_object, [0.0, 1.0, 0.0, 0.0]);
    let m2 = apply_point(&device_from_object, [0.0, 0.0, 1.0, 0.0]);
    let m3 = [m0[3], m1[3], m2[3]];
    let row0 = [m0[0], m1[0], m2[0]];
    let row1 = [m0[1], m1[1], m2[1]];

    let cw = center_device[3];
    let cw2 = cw * cw;
    let w_reach = r * dot3(m3, m3).sqrt();
    if cw <= -w_reach {
        return None;
    }
    // The reference point of pixel offsets and depths: the centre's projection while the
    // sphere is clear of the eye plane, device (0, 0, 0.5) once it reaches it (as the prim).
    let (sx, sy, zc, inv_cw, d0) = if cw > w_reach {
        (
            center_device[0] / cw,
            center_device[1] / cw,
            center_device[2] / cw,
            1.0 / cw,
            [0.0f32; 3],
        )
    } else {
        let p0 = apply_point(&object_from_device, [0.0, 0.0, 0.5, 1.0]);
        let d0: [f32; 3] = std::array::from_fn(|c| p0[c] - center[c] * p0[3]);
        (0.0, 0.0, 0.5, p0[3], d0)
    };

    let lead = cw2 - w_reach * w_reach;
    let mut bound = None;
    if lead > 0.0 && cw > 0.0 {
        let kx: [f32; 3] = std::array::from_fn(|c| row0[c] - sx * m3[c]);
        let ky: [f32; 3] = std::array::from_fn(|c| row1[c] - sy * m3[c]);
        let r2 = r * r;
        let (bx, by) = (r2 * dot3(kx, m3), r2 * dot3(ky, m3));
        let ex = (bx * bx + lead * r2 * dot3(kx, kx)).sqrt();
        let ey = (by * by + lead * r2 * dot3(ky, ky)).sqrt();
        let (x_lo, x_hi) = ((-bx - ex) / lead, (ex - bx) / lead);
        let (y_lo, y_hi) = ((-by - ey) / lead, (ey - by) / lead);
        let mx = 1.0 + MARGIN * (x_hi - x_lo);
        let my = 1.0 + MARGIN * (y_hi - y_lo);
        bound = Some([sx + x_lo - mx, sy + y_lo - my, sx + x_hi + mx, sy + y_hi + my]);
    }

    let g = |n: [f32; 4]| -> [f32; 3] { std::array::from_fn(|c| n[c] - center[c] * n[3]) };
    let (g0, g1, gamma) = (g(n0), g(n1), g(n2));
    let gamma_w = n2[3];
    let r2 = r * r;
    let mut a = dot3(gamma, gamma);
    if gamma_w != 0.0 {
        let eye_to_center: [f32; 3] = std::array::from_fn(|c| center[c] - n2[c] / gamma_w);
        a = gamma_w * gamma_w * sphere_power(eye_to_center, r);
    }
    let mut planes = [0u32; T];
    for (c, plane) in planes.iter_mut().enumerate() {
        *plane = word(1 + c);
    }
    let n0w = n0[3];
    let along_x: [f32; 3] = std::array::from_fn(|c| n0w * gamma[c] - gamma_w * g0[c]);
    let across_x = cross3(gamma, g0);
    let normal = [normal_x, normal_y, normal_z];
    Some(SphereSetup {
        planes,
        bound,
        sx,
        sy,
        zc,
        g0,
        g1,
        gamma,
        gamma_w,
        n0w,
        n1w: n1[3],
        inv_cw,
        d0,
        r2,
        a,
        normal_x,
        normal_y,
        normal_z,
        handedness,
        along_x,
        across_x,
        disc_xx: r2 * dot3(along_x, along_x) - dot3(across_x, across_x),
        b_x: dot3(g0, gamma) - r2 * n0w * gamma_w,
        c_xx: dot3(g0, g0) - r2 * n0w * n0w,
        lit_x: lighting_image(g0, normal),
        lit_gamma: lighting_image(gamma, normal),
    })
}

/// Bound mode: record the bound (the viewport when the prim ran no `bound`). Render mode:
/// the tile's pixel rectangle to evaluate, as the JIT's pass rectangle.
fn pass_rect<const T: usize>(ctx: &mut TileCtx, s: &SphereSetup<T>) -> Option<[i32; 4]> {
    match s.bound {
        Some(b) => bound_or_rect(ctx, b),
        None if ctx.mode == MODE_BOUND => {
            bound_or_rect(ctx, [0.0, 0.0, ctx.width as f32, ctx.height as f32]);
            None
        }
        None => bound_or_rect(
            ctx,
            [f32::NEG_INFINITY, f32::NEG_INFINITY, f32::INFINITY, f32::INFINITY],
        ),
    }
}

/// Portable scalar kernel.
///
/// # Safety
/// Called by the runtime with a valid `ctx` and the argument block of a sphere instance
/// whose key has `T` (0 or 3, one `implicit` binding) components.
pub unsafe extern "C" fn scalar<const T: usize, const COUNT: bool>(ctx: *mut TileCtx, args: *const u32) {
    // SAFETY: the runtime hands a valid, exclusive context for the duration of the call.
    let ctx = unsafe { &mut *ctx };
    let Some(s) = (unsafe { setup::<T>(args) }) else { return };
    let Some([rx0, ry0, rx1, ry1]) = pass_rect(ctx, &s) else {
        return;
    };
    for py in ry0..ry1 {
        let y = py as f32 + 0.5;
        let row = s.row_terms(y - s.sy);
        for px in rx0..rx1 {
            let x = px as f32 + 0.5;
            let dx = x - s.sx;
            let disc = (s.disc_xx * dx + row.disc_x) * dx + row.disc_row;
            if !(disc >= 0.0) {
                continue;
            }
            let b = s.b_x * dx + row.b_row;
            let c = (s.c_xx * dx + row.c_x) * dx + row.c_row;
            let root = disc.sqrt();
            let q = if b >= 0.0 { -(b + root) } else { root - b };
            if q == 0.0 {
                continue;
            }
            let t_finite = c / q;
            let z_finite = s.zc + t_finite;
            let q_over_a = q / s.a;
            let z_other = if s.a != 0.0 { s.zc + q_over_a } else { -1.0 };
            let finite_ok = (0.0..=1.0).contains(&z_finite);
            let other_ok = (0.0..=1.0).contains(&z_other);
            if !finite_ok && !other_ok {
                continue;
            }
            let mut t = t_finite;
            if other_ok && (!finite_ok || q_over_a > t_finite) {
                t = q_over_a;
            }
            let tz = depth_raw(s.zc + t);
            let idx = (py - ctx.y0) as usize * ctx.stride as usize + (px - ctx.x0) as usize;
            // SAFETY: (px, py) lies in the tile, so idx < stride * rows, the length of the
            // depth, G-buffer planes and write-count buffers; planes are checked below.
            unsafe {
                let zbuf = ctx.depth.add(idx);
                if tz < *zbuf {
                    continue;
                }
                *zbuf = tz;
                if COUNT {
                    *ctx.write_count.add(idx) += 1;
                }
                if T == 3 {
                    let w = (dx * s.n0w + row.delta_w_row) + t * s.gamma_w;
                    let lit: [f32; 3] =
                        std::array::from_fn(|k| (dx * s.lit_x[k] + row.lit_row[k]) + t * s.lit_gamma[k]);
                    let side = if w < 0.0 { -s.handedness } else { s.handedness };
                    let scale = side / dot3(lit, lit).sqrt();
                    for (&plane, lk) in s.planes.iter().zip(lit) {
                        if plane < ctx.num_planes {
                            *ctx.gbuf.add(plane as usize * ctx.plane_stride as usize + idx) = scale * lk;
                        }
                    }
                }
            }
        }
    }
}

/// AVX2 kernel: 8 pixels per step, row terms hoisted, empty groups skipped, masked stores.
///
/// # Safety
/// As [`scalar`], and the CPU must support AVX2 (the caller checks).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub unsafe extern "C" fn avx2<const T: usize, const COUNT: bool>(ctx: *mut TileCtx, args: *const u32) {
    use std::arch::x86_64::*;
    // SAFETY: as in `scalar`.
    let ctx = unsafe { &mut *ctx };
    let Some(s) = (unsafe { setup::<T>(args) }) else { return };
    let Some([rx0, ry0, rx1, ry1]) = pass_rect(ctx, &s) else {
        return;
    };
    let set1 = |v: f32| _mm256_set1_ps(v);
    let add = |a, b| _mm256_add_ps(a, b);
    let sub = |a, b| _mm256_sub_ps(a, b);
    let mul = |a, b| _mm256_mul_ps(a, b);
    let dot = |a: [__m256; 3], b: [__m256; 3]| add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]));
    let lane_offsets = _mm256_setr_ps(0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5, 7.5);
    let lane_index = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let sign = _mm256_set1_epi32(i32::MIN);
    let (zero, one) = (_mm256_setzero_ps(), set1(1.0));
    let (disc_xx, b_x, c_xx) = (set1(s.disc_xx), set1(s.b_x), set1(s.c_xx));
    let (lit_x, lit_gamma) = (s.lit_x.map(set1), s.lit_gamma.map(set1));
    let (gamma_w, zc) = (set1(s.gamma_w), set1(s.zc));
    let (n0w, sx) = (set1(s.n0w), set1(s.sx));
    let (a, a_nonzero) = (set1(s.a), s.a != 0.0);
    for py in ry0..ry1 {
        let terms = s.row_terms((py as f32 + 0.5) - s.sy);
        let row = (py - ctx.y0) as usize * ctx.stride as usize;
        let (disc_x, disc_row) = (set1(terms.disc_x), set1(terms.disc_row));
        let (b_row, c_x, c_row) = (set1(terms.b_row), set1(terms.c_x), set1(terms.c_row));
        let (delta_w_row, lit_row) = (set1(terms.delta_w_row), terms.lit_row.map(set1));
        let mut px = rx0;
        while px < rx1 {
            let n = (rx1 - px).min(8);
            let live = _mm256_cmpgt_epi32(_mm256_set1_epi32(n), lane_index);
            let x = add(set1(px as f32), lane_offsets);
            let dx = sub(x, sx);
            let disc = add(mul(add(mul(disc_xx, dx), disc_x), dx), disc_row);
            let mut mask = _mm256_and_si256(live, _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GE_OQ>(disc, zero)));
            if _mm256_testz_si256(mask, mask) != 0 {
                px += 8;
                continue;
            }
            let b = add(mul(b_x, dx), b_row);
            let c = add(mul(add(mul(c_xx, dx), c_x), dx), c_row);
            let root = _mm256_sqrt_ps(disc);
            let b_nonneg = _mm256_cmp_ps::<_CMP_GE_OQ>(b, zero);
            // -(b + root) by flipping the sign bit, as the JIT's fneg.
            let q = _mm256_blendv_ps(
                sub(root, b),
                _mm256_xor_ps(add(b, root), _mm256_castsi256_ps(sign)),
                b_nonneg,
            );
            mask = _mm256_andnot_si256(_mm256_castps_si256(_mm256_cmp_ps::<_CMP_EQ_OQ>(q, zero)), mask);
            let t_finite = _mm256_div_ps(c, q);
            let z_finite = add(zc, t_finite);
            let q_over_a = _mm256_div_ps(q, a);
            let z_other = if a_nonzero { add(zc, q_over_a) } else { set1(-1.0) };
            let in_range = |z| {
                _mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_GE_OQ>(z, zero),
                    _mm256_cmp_ps::<_CMP_LE_OQ>(z, one),
                )
            };
            let finite_ok = in_range(z_finite);
            let other_ok = in_range(z_other);
            mask = _mm256_and_si256(mask, _mm256_castps_si256(_mm256_or_ps(finite_ok, other_ok)));
            if _mm256_testz_si256(mask, mask) != 0 {
                px += 8;
                continue;
            }
            let take_other = _mm256_and_ps(
                other_ok,
                _mm256_or_ps(
                    _mm256_andnot_ps(finite_ok, _mm256_castsi256_ps(_mm256_set1_epi32(-1))),
                    _mm256_cmp_ps::<_CMP_GT_OQ>(q_over_a, t_finite),
                ),
            );
            let t = _mm256_blendv_ps(t_finite, q_over_a, take_other);
            let tz = depth_raw8(add(zc, t));
            let base = row + (px - ctx.x0) as usize;
            // SAFETY: lanes beyond `n` are masked off, and maskload/maskstore never touch
            // memory of masked-off lanes; the first `n` pixels of the row lie in the tile.
            unsafe {
                // The JIT's `sphere_z < Z` return.
                mask = depth_test8::<COUNT>(ctx, base, live, mask, tz);
                if _mm256_testz_si256(mask, mask) != 0 {
                    px += 8;
                    continue;
                }
                if T == 3 {
                    let w = add(add(mul(dx, n0w), delta_w_row), mul(t, gamma_w));
                    let lit: [__m256; 3] =
                        std::array::from_fn(|k| add(add(mul(dx, lit_x[k]), lit_row[k]), mul(t, lit_gamma[k])));
                    let handed = set1(s.handedness);
                    let behind = _mm256_cmp_ps::<_CMP_LT_OQ>(w, _mm256_setzero_ps());
                    let side = _mm256_blendv_ps(handed, set1(-s.handedness), behind);
                    let scale = _mm256_div_ps(side, _mm256_sqrt_ps(dot(lit, lit)));
                    for (&plane, lk) in s.planes.iter().zip(lit) {
                        if plane < ctx.num_planes {
                            let dst = ctx.gbuf.add(plane as usize * ctx.plane_stride as usize + base);
                            _mm256_maskstore_ps(dst, mask, mul(scale, lk));
                        }
                    }
                }
            }
            px += 8;
        }
    }
}

/// The SSE4.1 kernel's body, stamped out twice by [`sse_kernel!`]: legacy encoding (any
/// x86_64 CPU with SSE4.1) and VEX encoding (three-operand forms) for CPUs with AVX, which
/// is what the JIT emits there. Both are 128-bit, 4 pixels per group: the JIT's width, so
/// the JIT and this kernel retire the same number of divides and square roots per pixel.
///
/// Per row: the prim's row terms, splatted. Per group: the prim's operations in the AVX2
/// kernel's order, groups with no pixel left skipped after the
/// silhouette, depth-range and Z tests; the Z buffer, write counts and normal planes are
/// stored whole when all four lanes pass and blended with what is there otherwise. Groups
/// start at tile-aligned x, like the JIT's, so a 4-lane load or store never leaves the row.
macro_rules! sse_kernel {
    ($(#[$doc:meta])* $name:ident, $features:literal) => {
        $(#[$doc])*
        ///
        /// # Safety
        /// As [`scalar`], and the CPU must support the enabled features (the caller checks).
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        pub unsafe extern "C" fn $name<const T: usize, const COUNT: bool>(ctx: *mut TileCtx, args: *const u32) {
            use std::arch::x86_64::*;

            /// The language's `dot` of two 3-vectors of lanes, in its order.
            #[inline]
            #[target_feature(enable = $features)]
            fn dot(a: [__m128; 3], b: [__m128; 3]) -> __m128 {
                _mm_add_ps(_mm_add_ps(_mm_mul_ps(a[0], b[0]), _mm_mul_ps(a[1], b[1])), _mm_mul_ps(a[2], b[2]))
            }

            /// `new` where `pass` is set, `old` elsewhere.
            #[inline]
            #[target_feature(enable = $features)]
            fn blend(old: __m128, new: __m128, pass: __m128) -> __m128 {
                _mm_blendv_ps(old, new, pass)
            }

            // SAFETY: as in `scalar`.
            let ctx = unsafe { &mut *ctx };
            let Some(s) = (unsafe { setup::<T>(args) }) else { return };
            let Some([rx0, ry0, rx1, ry1]) = pass_rect(ctx, &s) else {
                return;
            };
            let stride = ctx.stride as usize;
            let plane_base = tile_plane_bases(ctx, &s.planes);
            let set1 = |v: f32| _mm_set1_ps(v);
            let lane_offsets = _mm_setr_ps(0.5, 1.5, 2.5, 3.5);
            let lane_index = _mm_setr_epi32(0, 1, 2, 3);
            let all_lanes = _mm_set1_epi32(-1);
            let sign = _mm_castsi128_ps(_mm_set1_epi32(i32::MIN));
            let (zero, one) = (_mm_setzero_ps(), set1(1.0));
            let (disc_xx, b_x, c_xx) = (set1(s.disc_xx), set1(s.b_x), set1(s.c_xx));
            let (lit_x, lit_gamma) = (s.lit_x.map(set1), s.lit_gamma.map(set1));
            let (gamma_w, zc) = (set1(s.gamma_w), set1(s.zc));
            let (n0w, sx) = (set1(s.n0w), set1(s.sx));
            let (a, a_nonzero) = (set1(s.a), s.a != 0.0);
            let handed = set1(s.handedness);
            for py in ry0..ry1 {
                let terms = s.row_terms((py as f32 + 0.5) - s.sy);
                let row = (py - ctx.y0) as usize * stride;
                let (disc_x, disc_row) = (set1(terms.disc_x), set1(terms.disc_row));
                let (b_row, c_x, c_row) = (set1(terms.b_row), set1(terms.c_x), set1(terms.c_row));
                let (delta_w_row, lit_row) = (set1(terms.delta_w_row), terms.lit_row.map(set1));
                let mut gx = ctx.x0 + ((rx0 - ctx.x0) & !3);
                while gx < rx1 {
                    let live = if gx < rx0 || gx + 4 > rx1 {
                        let px = _mm_add_epi32(_mm_set1_epi32(gx), lane_index);
                        _mm_and_si128(
                            _mm_cmpgt_epi32(px, _mm_set1_epi32(rx0 - 1)),
                            _mm_cmplt_epi32(px, _mm_set1_epi32(rx1)),
                        )
                    } else {
                        all_lanes
                    };
                    let base = row + (gx - ctx.x0) as usize;
                    gx += 4;
                    let x = _mm_add_ps(set1((gx - 4) as f32), lane_offsets);
                    let dx = _mm_sub_ps(x, sx);
                    // (a dx + b) dx + c, as the prim's polynomials in dx.
                    let horner = |a, b, c| _mm_add_ps(_mm_mul_ps(_mm_add_ps(_mm_mul_ps(a, dx), b), dx), c);
                    let disc = horner(disc_xx, disc_x, disc_row);
                    let mut pass = _mm_and_ps(_mm_castsi128_ps(live), _mm_cmpge_ps(disc, zero));
                    if _mm_movemask_ps(pass) == 0 {
                        continue;
                    }
                    let b = _mm_add_ps(_mm_mul_ps(b_x, dx), b_row);
                    let c = horner(c_xx, c_x, c_row);
                    let root = _mm_sqrt_ps(disc);
                    // -(b + root) by flipping the sign bit, as the JIT's fneg.
                    let q = blend(_mm_sub_ps(root, b), _mm_xor_ps(_mm_add_ps(b, root), sign), _mm_cmpge_ps(b, zero));
                    pass = _mm_andnot_ps(_mm_cmpeq_ps(q, zero), pass);
                    let t_finite = _mm_div_ps(c, q);
                    let z_finite = _mm_add_ps(zc, t_finite);
                    let q_over_a = _mm_div_ps(q, a);
                    let z_other = if a_nonzero { _mm_add_ps(zc, q_over_a) } else { set1(-1.0) };
                    let finite_ok = _mm_and_ps(_mm_cmpge_ps(z_finite, zero), _mm_cmple_ps(z_finite, one));
                    let other_ok = _mm_and_ps(_mm_cmpge_ps(z_other, zero), _mm_cmple_ps(z_other, one));
                    pass = _mm_and_ps(pass, _mm_or_ps(finite_ok, other_ok));
                    if _mm_movemask_ps(pass) == 0 {
                        continue;
                    }
                    let take_other = _mm_and_ps(
                        other_ok,
                        _mm_or_ps(
                            _mm_andnot_ps(finite_ok, _mm_castsi128_ps(all_lanes)),
                            _mm_cmpgt_ps(q_over_a, t_finite),
                        ),
                    );
                    let t = blend(t_finite, q_over_a, take_other);
                    let tz = depth_raw4(_mm_add_ps(zc, t));
                    // SAFETY: the group lies in one row of the tile buffers (groups start at
                    // tile-aligned x and the stride is whole groups), so 4 elements from
                    // `base` are in every `stride * rows` buffer and plane.
                    unsafe {
                        let zptr = ctx.depth.add(base) as *mut __m128i;
                        let old = _mm_loadu_si128(zptr);
                        // The JIT's `sphere_z < Z` return: unsigned tz >= old passes.
                        let nearer = _mm_cmpeq_epi32(_mm_max_epu32(tz, old), tz);
                        pass = _mm_and_ps(pass, _mm_castsi128_ps(nearer));
                        let bits = _mm_movemask_ps(pass);
                        if bits == 0 {
                            continue;
                        }
                        let full = bits == 0b1111;
                        let new_z = if full {
                            tz
                        } else {
                            _mm_castps_si128(blend(_mm_castsi128_ps(old), _mm_castsi128_ps(tz), pass))
                        };
                        _mm_storeu_si128(zptr, new_z);
                        if COUNT {
                            let cptr = ctx.write_count.add(base) as *mut __m128i;
                            _mm_storeu_si128(cptr, _mm_sub_epi32(_mm_loadu_si128(cptr), _mm_castps_si128(pass)));
                        }
                        if T == 3 {
                            let w = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, n0w), delta_w_row), _mm_mul_ps(t, gamma_w));
                            let lit: [__m128; 3] = std::array::from_fn(|k| {
                                _mm_add_ps(
                                    _mm_add_ps(_mm_mul_ps(dx, lit_x[k]), lit_row[k]),
                                    _mm_mul_ps(t, lit_gamma[k]),
                                )
                            });
                            let behind = _mm_cmplt_ps(w, _mm_setzero_ps());
                            let side = blend(handed, set1(-s.handedness), behind);
                            let scale = _mm_div_ps(side, _mm_sqrt_ps(dot(lit, lit)));
                            for (&plane, lk) in plane_base.iter().zip(lit) {
                                if plane.is_null() {
                                    continue;
                                }
                                let dst = plane.add(base);
                                let mut n = _mm_mul_ps(scale, lk);
                                if !full {
                                    n = blend(_mm_loadu_ps(dst), n, pass);
                                }
                                _mm_storeu_ps(dst, n);
                            }
                        }
                    }
                }
            }
        }
    };
}

sse_kernel!(
    /// SSE4.1 kernel, legacy (two-operand) encoding.
    sse41,
    "sse4.1"
);
sse_kernel!(
    /// SSE4.1 kernel, VEX (three-operand) encoding, for CPUs with AVX; still 128-bit.
    sse41_vex,
    "sse4.1,avx"
);

/// The kernel for `key` in form `isa` (an `isa::*` constant; a form not built for this
/// architecture is the scalar one), after checking that the key is one this file serves and
/// that the argument layout has the offsets the kernel reads.
pub fn entry_for(layout: &ArgLayout, key: &VariantKey, isa: u8) -> Result<KernelFn, String> {
    let t = match key.bindings.as_slice() {
        [] => 0,
        [Binding {
            kind: BindingKind::Kind(k),
            components: 3,
        }] if k == "implicit" => 3,
        _ => return Err("the hand-written sphere serves no bindings or one 3-component `implicit` binding".into()),
    };
    let p = params_at(t) as u32;
    let fixed = |offset: u32, words: u32| ParamSlot::Fixed { offset, words };
    let expected = [
        fixed(p, 3),
        fixed(p + 3, 1),
        fixed(p + 4, 3),
        fixed(p + 7, 3),
        fixed(p + 10, 3),
    ];
    if layout.spaces != Some(spaces_at(t) as u32) || layout.params.get(..5) != Some(&expected[..]) {
        return Err("sphere's parameters are not the ones the hand-written kernel reads".into());
    }
    macro_rules! forms {
        ($($isa:path => $kernel:ident),*) => {
            match (isa, t, key.count_writes) {
                $(
                    ($isa, 0, false) => $kernel::<0, false>,
                    ($isa, 0, true) => $kernel::<0, true>,
                    ($isa, _, false) => $kernel::<3, false>,
                    ($isa, _, true) => $kernel::<3, true>,
                )*
                (_, 0, false) => scalar::<0, false>,
                (_, 0, true) => scalar::<0, true>,
                (_, _, false) => scalar::<3, false>,
                (_, _, true) => scalar::<3, true>,
            }
        };
    }
    #[cfg(target_arch = "x86_64")]
    let kernel: KernelFn = forms!(isa::SSE41 => sse41, isa::SSE41_VEX => sse41_vex, isa::AVX2 => avx2);
    #[cfg(not(target_arch = "x86_64"))]
    let kernel: KernelFn = forms!();
    Ok(kernel)
}
