//! The NURB surface written by hand in Rust: validation, homogeneous de Boor evaluation,
//! tolerance-driven tessellation with crack-free edges and hither clipping in scalar code,
//! each triangle rendered by the hand-written screen_triangle kernel (scalar or AVX2).
//!
//! It mirrors `prims/nurb_surface.prim` (and the `polygon` it calls) operation for
//! operation: the same step counts from the same derivative bounds, the same parameter
//! triples in the same order, the same float expression order in every de Boor step, and
//! min/max with the JIT's semantics (NaN in, NaN out; -0 below +0). The triangles reach
//! `screen_triangle` in the argument block the JIT's call builds (word 0 = 1, the plane
//! table, the 12 screen-vertex floats, 3 x T interpolation floats), so on the same scene
//! it produces the same buffers as the JIT kernel, bit for bit. Bound mode runs the same
//! code, as the JIT does: the hull bound and every triangle's bound are unioned.
//!
//! Both flavours evaluate every tessellation point once and reuse it, as the prim does;
//! "scalar" draws with the scalar screen_triangle, "SIMD" with the AVX2 one.
//!
//! In `MODE_EXPAND` the triangles are recorded through `abi::call_primitive` instead of
//! drawn: the JIT's kernel records screen_triangle calls, and `polygon` calls for triangles
//! it clips, which the runtime expands in turn into the same screen_triangle calls, so both
//! yield the same triangle instances in the same order (a clipped one from the hand-written
//! kernel one call level shallower, which screen_triangle never reads).
//!
//! A rejected surface draws nothing, as in the prim, but records no W0801 run-time
//! warning (the prim reports its reason through an out-of-range index at a source site;
//! the hand-written kernel has no site to name).
//!
//! Keys served: bindings of kind `implicit` (at most one, 3 components, first) and
//! `perspective_linear`, then `linear` ones — the components screen_triangle treats as
//! perspective-correct (P) first, the linear ones (L) last — for the (P, L) shapes in
//! [`entry`]. Argument block (see `abi::ArgLayout`): word 0 n_seq; T plane indices; the six
//! space matrices; u_count, v_count, u_order, v_order; u_knots[16]; v_knots[16]; tolerance;
//! object_x, object_y, object_z (3 floats each, in lighting coordinates: the implicit
//! normal's object-to-lighting cofactor matrix is built from them, as in the prim); then
//! per sequence point vertex (4 floats), weight, interp_data (T floats).

// `!(a < b)` is the prims' NaN-rejecting test, kept as written (a NaN fails it).
#![allow(clippy::neg_cmp_op_on_partial_ord)]
use super::screen_triangle;
use super::sphere::{apply_point, cross3, dot3, space_matrix};
use crate::abi::{call_primitive, ArgLayout, BindingKind, KernelFn, ParamSlot, TileCtx, VariantKey, MODE_BOUND};

/// Word offset of the first fixed parameter (`u_count`) for `t` plane-table entries.
pub(crate) const fn params_at(t: usize) -> usize {
    1 + t + 96
}

/// Words before the per-sequence-point part.
pub(crate) const fn fixed_words(t: usize) -> usize {
    params_at(t) + 4 + 16 + 16 + 1 + 9
}

/// Largest T the kernel's fixed-size buffers hold.
const MAX_T: usize = 16;
/// The screen_triangle argument block: n_seq, plane table, screen_vertex, interp_data[3].
const TRI_WORDS: usize = 1 + MAX_T + 12 + 3 * MAX_T;

const LIMIT: f32 = 1e30f64 as f32;
const WEIGHT_FLOOR: f32 = 1e-6f64 as f32;
/// The prim's largest control point coordinate.
const POINT_LIMIT: f32 = 1e15f64 as f32;

/// Cranelift's `fmin`: NaN if either operand is NaN, and -0 below +0.
#[inline(always)]
fn jit_min(a: f32, b: f32) -> f32 {
    if a.is_nan() || b.is_nan() {
        f32::NAN
    } else if a == b {
        if a.is_sign_negative() {
            a
        } else {
            b
        }
    } else if a < b {
        a
    } else {
        b
    }
}

/// Cranelift's `fmax`: NaN if either operand is NaN, and +0 above -0.
#[inline(always)]
fn jit_max(a: f32, b: f32) -> f32 {
    if a.is_nan() || b.is_nan() {
        f32::NAN
    } else if a == b {
        if a.is_sign_positive() {
            a
        } else {
            b
        }
    } else if a > b {
        a
    } else {
        b
    }
}

/// The prim's `nurb_span`: k with knots[k] <= t < knots[k + 1], the end of the domain in
/// the last non-empty span.
fn span(knots: &[f32; 16], count: usize, order: usize, t: f32) -> usize {
    let mut k = order - 1;
    for i in order - 1..count {
        if knots[i] <= t && knots[i] < knots[i + 1] {
            k = i;
        }
    }
    k
}

/// The prim's `nurb_alphas`: de Boor's weights at t in knot span k for degree p (step
/// `level` mixes points j - 1 and j with `alpha[level][j]`), shared by every curve
/// evaluated at t.
fn alphas(knots: &[f32; 16], k: usize, p: usize, t: f32) -> [[f32; 4]; 4] {
    let mut alpha = [[0f32; 4]; 4];
    for level in 1..=p {
        for j in (level..=p).rev() {
            let i = k - p + j;
            alpha[level][j] = (t - knots[i]) / (knots[i + p + 1 - level] - knots[i]);
        }
    }
    alpha
}

/// The prim's `nurb_de_boor`: the homogeneous point and its derivative from the p + 1
/// points of a knot span (`points[j]` is the curve's point k - p + j), with the span's
/// weights and width `knots[k + 1] - knots[k]`.
#[allow(clippy::needless_range_loop)] // the loops are the prim's, index for index
fn de_boor(alpha: &[[f32; 4]; 4], p: usize, points: &[[f32; 4]; 4], width: f32) -> ([f32; 4], [f32; 4]) {
    let mut d = *points;
    let (mut before_last, mut last) = ([0f32; 4], [0f32; 4]);
    for level in 1..=p {
        if level == p {
            before_last = d[p - 1];
            last = d[p];
        }
        for j in (level..=p).rev() {
            let a = alpha[level][j];
            d[j] = std::array::from_fn(|c| (1.0 - a) * d[j - 1][c] + a * d[j][c]);
        }
    }
    let derivative = std::array::from_fn(|c| p as f32 * (last[c] - before_last[c]) / width);
    (d[p], derivative)
}

/// The prim's `nurb_knots_valid`.
fn knots_valid(knots: &[f32; 16], count: usize, order: usize) -> bool {
    let mut ok = true;
    for i in 0..count + order - 1 {
        if !(knots[i] <= knots[i + 1]) || !(knots[i].abs() < LIMIT) {
            ok = false;
        }
    }
    for i in 0..order {
        if knots[i] != knots[0] || knots[count + i] != knots[count + order - 1] {
            ok = false;
        }
    }
    ok && knots[order - 1] < knots[count]
}

/// The prim's `nurb_interior_multiplicity`.
fn interior_multiplicity(knots: &[f32; 16], count: usize, order: usize) -> usize {
    if count > order && (knots[order] == knots[order - 1] || knots[count - 1] == knots[count]) {
        return order;
    }
    let (mut most, mut run) = (0, 0);
    for i in order..count {
        run = if knots[i] == knots[i - 1] && i > order {
            run + 1
        } else {
            1
        };
        most = most.max(run);
    }
    most
}

/// The prim's `nurb_second_derivative_bound`: the largest second-derivative control point
/// of Q = W (p - c) plus `radius` times that of W.
#[allow(clippy::too_many_arguments)]
fn second_derivative_bound(
    knots: &[f32; 16],
    count: usize,
    order: usize,
    x: &[f32; 12],
    y: &[f32; 12],
    w: &[f32; 12],
    (cx, cy, radius): (f32, f32, f32),
) -> f32 {
    let p = order - 1;
    if p < 2 {
        return 0.0;
    }
    let (mut dx, mut dy, mut dw) = ([0f32; 12], [0f32; 12], [0f32; 12]);
    for i in 0..count - 1 {
        let span = knots[i + p + 1] - knots[i + 1];
        if span > 0.0 {
            dx[i] = p as f32 * (w[i + 1] * (x[i + 1] - cx) - w[i] * (x[i] - cx)) / span;
            dy[i] = p as f32 * (w[i + 1] * (y[i + 1] - cy) - w[i] * (y[i] - cy)) / span;
            dw[i] = p as f32 * (w[i + 1] - w[i]) / span;
        }
    }
    let (mut most_q, mut most_w) = (0f32, 0f32);
    for i in 0..count.saturating_sub(2) {
        let span = knots[i + p + 1] - knots[i + 2];
        if span > 0.0 {
            let qx = (p - 1) as f32 * (dx[i + 1] - dx[i]) / span;
            let qy = (p - 1) as f32 * (dy[i + 1] - dy[i]) / span;
            most_q = jit_max(most_q, (qx * qx + qy * qy).sqrt());
            most_w = jit_max(most_w, ((p - 1) as f32 * (dw[i + 1] - dw[i]) / span).abs());
        }
    }
    most_q + radius * most_w
}

/// The prim's `nurb_edge_bound`: a boundary curve's bound from its own points only.
fn edge_bound(knots: &[f32; 16], count: usize, order: usize, x: &[f32; 12], y: &[f32; 12], w: &[f32; 12]) -> f32 {
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi, mut w_min) = (x[0], x[0], y[0], y[0], w[0]);
    for i in 1..count {
        x_lo = jit_min(x_lo, x[i]);
        x_hi = jit_max(x_hi, x[i]);
        y_lo = jit_min(y_lo, y[i]);
        y_hi = jit_max(y_hi, y[i]);
        w_min = jit_min(w_min, w[i]);
    }
    let (cx, cy) = (0.5 * (x_lo + x_hi), 0.5 * (y_lo + y_hi));
    let mut radius = 0f32;
    for i in 0..count {
        radius = jit_max(radius, ((x[i] - cx) * (x[i] - cx) + (y[i] - cy) * (y[i] - cy)).sqrt());
    }
    second_derivative_bound(knots, count, order, x, y, w, (cx, cy, radius)) / w_min
}

/// The prim's `nurb_steps`: steps so that step^2 * m <= limit, between 1 and `finest` + 1.
fn steps(range: f32, m: f32, limit: f32, finest: i32) -> i32 {
    if !(m > 0.0) {
        return 1;
    }
    let steps = (range * (m / limit).sqrt()).ceil();
    // `int(...)` saturates, NaN to 0, as Rust's `as` does.
    jit_min(jit_max(steps, 1.0), (finest + 1) as f32) as i32
}

/// The parts of the argument block the tessellation reads, after validation.
struct Surface<const T: usize> {
    args: *const u32,
    u_count: usize,
    v_count: usize,
    u_order: usize,
    v_order: usize,
    u_knots: [f32; 16],
    v_knots: [f32; 16],
    /// Homogeneous control points: weight * device point.
    h: [[f32; 4]; 144],
    weights: [f32; 144],
    object_from_device: [f32; 16],
    /// Columns of the object-to-lighting normal matrix (cofactors of lighting_from_object,
    /// times the handedness).
    normal_columns: [[f32; 3]; 3],
    /// Offset of interpolation data element 0.
    data_at: usize,
}

impl<const T: usize> Surface<T> {
    /// Control point `at`'s interpolation data.
    fn data(&self, at: usize) -> [f32; T] {
        // SAFETY: `at` < n_seq, and the layout holds T words per sequence point there.
        std::array::from_fn(|c| f32::from_bits(unsafe { *self.args.add(self.data_at + at * T + c) }))
    }

    /// Position (homogeneous device point) and interpolation data of the surface at (u, v),
    /// as the prim's corner loop computes them.
    #[allow(clippy::needless_range_loop)] // the loops are the prim's, index for index
    fn corner<const NORMAL: bool>(&self, u: f32, v: f32) -> ([f32; 4], [f32; T]) {
        let ku = span(&self.u_knots, self.u_count, self.u_order, u);
        let kv = span(&self.v_knots, self.v_count, self.v_order, v);
        let (pu, pv) = (self.u_order - 1, self.v_order - 1);
        // Each direction's de Boor weights once, for every curve evaluated in it.
        let alpha_u = alphas(&self.u_knots, ku, pu, u);
        let alpha_v = alphas(&self.v_knots, kv, pv, v);
        let width_u = self.u_knots[ku + 1] - self.u_knots[ku];
        let width_v = self.v_knots[kv + 1] - self.v_knots[kv];
        let mut column = [[0f32; 4]; 4];
        let mut column_du = [[0f32; 4]; 4];
        let mut weight_rows = [0f32; 4];
        for r in 0..=pv {
            let row = kv - pv + r;
            let mut window = [[0f32; 4]; 4];
            let first = row * self.u_count + ku - pu;
            window[..=pu].copy_from_slice(&self.h[first..=first + pu]);
            let (value, du) = de_boor(&alpha_u, pu, &window, width_u);
            column[r] = value;
            column_du[r] = du;
            // The weight by the same scheme (the patch's denominator).
            let mut w = [0f32; 4];
            w[..=pu].copy_from_slice(&self.weights[first..=first + pu]);
            for level in 1..=pu {
                for j in (level..=pu).rev() {
                    let a = alpha_u[level][j];
                    w[j] = (1.0 - a) * w[j - 1] + a * w[j];
                }
            }
            weight_rows[r] = w[pu];
        }
        let (surface, dv) = de_boor(&alpha_v, pv, &column, width_v);
        let (du_surface, _) = de_boor(&alpha_v, pv, &column_du, width_v);
        for level in 1..=pv {
            for j in (level..=pv).rev() {
                let a = alpha_v[level][j];
                weight_rows[j] = (1.0 - a) * weight_rows[j - 1] + a * weight_rows[j];
            }
        }
        // The shading data (weight * data by the same scheme, over the weight), as the prim's
        // `default:` arm: only when some component is not the normal's.
        let mut data_rows = [[0f32; T]; 4];
        if T > if NORMAL { 3 } else { 0 } {
            for (r, data_row) in data_rows.iter_mut().enumerate().take(pv + 1) {
                let row = kv - pv + r;
                let mut d = [[0f32; T]; 4];
                for (j, dj) in d.iter_mut().enumerate().take(pu + 1) {
                    let at = row * self.u_count + ku - pu + j;
                    let data = self.data(at);
                    *dj = std::array::from_fn(|c| self.weights[at] * data[c]);
                }
                for level in 1..=pu {
                    for j in (level..=pu).rev() {
                        let a = alpha_u[level][j];
                        d[j] = std::array::from_fn(|c| (1.0 - a) * d[j - 1][c] + a * d[j][c]);
                    }
                }
                *data_row = d[pu];
            }
            for level in 1..=pv {
                for j in (level..=pv).rev() {
                    let a = alpha_v[level][j];
                    data_rows[j] = std::array::from_fn(|c| (1.0 - a) * data_rows[j - 1][c] + a * data_rows[j][c]);
                }
            }
        }
        let mut vertex_data: [f32; T] = std::array::from_fn(|c| data_rows[pv][c] / weight_rows[pv]);
        if NORMAL {
            // Derivatives of the homogeneous point in object space, then of the divided point.
            let o = apply_point(&self.object_from_device, surface);
            let o_u = apply_point(&self.object_from_device, du_surface);
            let o_v = apply_point(&self.object_from_device, dv);
            let tangent_u: [f32; 3] = std::array::from_fn(|c| o_u[c] * o[3] - o[c] * o_u[3]);
            let tangent_v: [f32; 3] = std::array::from_fn(|c| o_v[c] * o[3] - o[c] * o_v[3]);
            let mut normal = [
                tangent_u[1] * tangent_v[2] - tangent_u[2] * tangent_v[1],
                tangent_u[2] * tangent_v[0] - tangent_u[0] * tangent_v[2],
                tangent_u[0] * tangent_v[1] - tangent_u[1] * tangent_v[0],
            ];
            let length = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
            if length > 0.0 {
                normal = normal.map(|n| n / length);
            }
            // To lighting coordinates, and unit length again (a zero normal stays zero).
            let [nx, ny, nz] = self.normal_columns;
            let mut lit: [f32; 3] = std::array::from_fn(|c| normal[0] * nx[c] + normal[1] * ny[c] + normal[2] * nz[c]);
            let lit_length = (lit[0] * lit[0] + lit[1] * lit[1] + lit[2] * lit[2]).sqrt();
            if lit_length > 0.0 {
                lit = lit.map(|n| n / lit_length);
            }
            vertex_data[..3].copy_from_slice(&lit);
        }
        // The prim hands `polygon` the point divided by the patch's denominator.
        let denominator = weight_rows[pv];
        (surface.map(|c| c / denominator), vertex_data)
    }
}

/// Renders fan triangles through the hand-written screen_triangle, in the argument block
/// the JIT's `screen_triangle(...)` call builds.
struct TriangleSink<const T: usize> {
    ctx: *mut TileCtx,
    triangle: KernelFn,
    block: [u32; TRI_WORDS],
}

impl<const T: usize> TriangleSink<T> {
    fn draw(&mut self, screen_vertex: &[[f32; 4]; 3], screen_data: &[[f32; T]; 3]) {
        for (v, sv) in screen_vertex.iter().enumerate() {
            for (c, x) in sv.iter().enumerate() {
                self.block[1 + T + v * 4 + c] = x.to_bits();
            }
        }
        for (v, sd) in screen_data.iter().enumerate() {
            for (c, x) in sd.iter().enumerate() {
                self.block[1 + T + 12 + v * T + c] = x.to_bits();
            }
        }
        // SAFETY: `ctx` is the caller's valid context and the block's first `1 + T + 12 + 3T`
        // words a complete screen_triangle argument block for T components. In MODE_EXPAND
        // the triangle is recorded (the JIT records the polygon, whose expansion records
        // the same triangle).
        unsafe { call_primitive(self.ctx, self.triangle, &self.block[..1 + T + 12 + 3 * T]) };
    }

    /// The prim `polygon` on three vertices: the plain fan, or (`clip`) clipped against the
    /// hither plane z = w in homogeneous coordinates first.
    fn polygon(&mut self, clip: bool, vertex: &[[f32; 4]; 3], data: &[[f32; T]; 3]) {
        let screen = |h: &[f32; 4]| [h[0] / h[3], h[1] / h[3], h[2] / h[3], h[3]];
        let mut sv = [[0f32; 4]; 3];
        let mut sd = [[0f32; T]; 3];
        if !clip {
            for i in 0..3 {
                let s = screen(&vertex[i]);
                if i < 2 {
                    sv[i] = s;
                    sd[i] = data[i];
                } else {
                    sv[2] = s;
                    sd[2] = data[i];
                    self.draw(&sv, &sd);
                }
            }
            return;
        }
        let mut count = 0;
        for current in 0..3 {
            let next = (current + 1) % 3;
            let d_current = vertex[current][3] - vertex[current][2];
            let d_next = vertex[next][3] - vertex[next][2];
            for k in 0..2 {
                let mut emitted = None;
                if k == 0 && d_current >= 0.0 {
                    emitted = Some((vertex[current], data[current]));
                }
                if k == 1 && (d_current >= 0.0) != (d_next >= 0.0) {
                    let t = d_current / (d_current - d_next);
                    let h = std::array::from_fn(|c| vertex[current][c] + t * (vertex[next][c] - vertex[current][c]));
                    let d = std::array::from_fn(|c| (1.0 - t) * data[current][c] + t * data[next][c]);
                    emitted = Some((h, d));
                }
                let Some((h, d)) = emitted else { continue };
                if !(h[3] > 0.0) {
                    continue;
                }
                let s = screen(&h);
                if count < 2 {
                    sv[count] = s;
                    sd[count] = d;
                    count += 1;
                } else {
                    sv[2] = s;
                    sd[2] = d;
                    self.draw(&sv, &sd);
                    sv[1] = s;
                    sd[1] = d;
                }
            }
        }
    }
}

/// The whole prim for `T` components (`NORMAL`: components 0..3 are the implicit normal).
///
/// One function because it mirrors `prims/nurb_surface.prim` operation for operation (see
/// the module doc): kept in the prim's order, it reads side by side with the prim.
///
/// # Safety
/// `ctx` valid, `args` the nurb_surface argument block for T components, `triangle` a
/// screen_triangle kernel for the same components.
unsafe fn surface<const T: usize, const NORMAL: bool>(
    ctx: *mut TileCtx,
    args: *const u32,
    triangle: KernelFn,
    clip: bool,
) {
    let word = |i: usize| unsafe { *args.add(i) };
    let float = |i: usize| f32::from_bits(word(i));
    let f0 = params_at(T);
    let n_seq = word(0) as i32;
    let (u_count, v_count) = (word(f0) as i32, word(f0 + 1) as i32);
    let (u_order, v_order) = (word(f0 + 2) as i32, word(f0 + 3) as i32);
    let u_knots: [f32; 16] = std::array::from_fn(|i| float(f0 + 4 + i));
    let v_knots: [f32; 16] = std::array::from_fn(|i| float(f0 + 20 + i));
    let tolerance = float(f0 + 36);
    let object_x = [float(f0 + 37), float(f0 + 38), float(f0 + 39)];
    let object_y = [float(f0 + 40), float(f0 + 41), float(f0 + 42)];
    let object_z = [float(f0 + 43), float(f0 + 44), float(f0 + 45)];
    let fixed = fixed_words(T);
    let seq = (n_seq as u32).max(1) as usize;
    let vertex = |i: usize| -> [f32; 4] { std::array::from_fn(|c| float(fixed + i * 4 + c)) };
    let weight = |i: usize| float(fixed + seq * 4 + i);

    // ---- Validation (the prim's reasons, in its order).
    if !(2..=4).contains(&u_order) || !(2..=4).contains(&v_order) {
        return;
    }
    if u_count < u_order || u_count > 12 || v_count < v_order || v_count > 12 || n_seq != u_count * v_count {
        return;
    }
    let (u_count, v_count, u_order, v_order) = (u_count as usize, v_count as usize, u_order as usize, v_order as usize);
    if !(knots_valid(&u_knots, u_count, u_order) && knots_valid(&v_knots, v_count, v_order)) {
        return;
    }
    if interior_multiplicity(&u_knots, u_count, u_order) >= u_order
        || interior_multiplicity(&v_knots, v_count, v_order) >= v_order
    {
        return;
    }
    let n = u_count * v_count;
    let mut largest = 0f32;
    let mut weights_ok = true;
    let mut weights = [0f32; 144];
    for (i, w) in weights.iter_mut().enumerate().take(n) {
        *w = weight(i);
        if !(*w > 0.0 && *w <= f32::MAX) {
            weights_ok = false;
        }
        largest = jit_max(largest, *w);
    }
    for &w in &weights[..n] {
        if !(w >= WEIGHT_FLOOR * largest) {
            weights_ok = false;
        }
    }
    if !weights_ok {
        return;
    }
    if !(0..n).all(|i| vertex(i).iter().all(|c| c.abs() <= POINT_LIMIT)) {
        return;
    }
    if !(tolerance > 0.0) {
        return;
    }

    // ---- Homogeneous control points, the projected net and the bound.
    let mut h = [[0f32; 4]; 144];
    let (mut sx, mut sy) = ([0f32; 144], [0f32; 144]);
    let mut all_in_front = true;
    for i in 0..n {
        let p = vertex(i);
        weights[i] /= largest;
        h[i] = p.map(|c| weights[i] * c);
        if !(p[3] > 0.0 && p[0].abs() < LIMIT && p[1].abs() < LIMIT) {
            all_in_front = false;
        }
        sx[i] = p[0] / p[3];
        sy[i] = p[1] / p[3];
    }
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (sx[0], sx[0], sy[0], sy[0]);
    if all_in_front {
        for i in 1..n {
            x_lo = jit_min(x_lo, sx[i]);
            x_hi = jit_max(x_hi, sx[i]);
            y_lo = jit_min(y_lo, sy[i]);
            y_hi = jit_max(y_hi, sy[i]);
        }
        // SAFETY: the runtime's context is valid and exclusive for the call.
        let c = unsafe { &mut *ctx };
        if c.mode == MODE_BOUND {
            screen_triangle::bound_or_rect(c, [x_lo - 1.0, y_lo - 1.0, x_hi + 1.0, y_hi + 1.0]);
        }
    }
    // The prim's normal matrix: cofactor columns of lighting_from_object, times the
    // handedness (exactly +-1).
    let handedness: f32 = if dot3(object_x, cross3(object_y, object_z)) < 0.0 {
        -1.0
    } else {
        1.0
    };
    let normal_columns = [
        cross3(object_y, object_z).map(|c| handedness * c),
        cross3(object_z, object_x).map(|c| handedness * c),
        cross3(object_x, object_y).map(|c| handedness * c),
    ];
    let (unbounded, finest) = (32, 128);

    // ---- Step counts. Edges: from their own row / column only.
    let (u0, u1) = (u_knots[u_order - 1], u_knots[u_count]);
    let (v0, v1) = (v_knots[v_order - 1], v_knots[v_count]);
    let (mut e_bottom, mut e_top, mut e_left, mut e_right) = (unbounded, unbounded, unbounded, unbounded);
    let (mut inner_u, mut inner_v) = (unbounded, unbounded);
    if all_in_front {
        let (cx, cy) = (0.5 * (x_lo + x_hi), 0.5 * (y_lo + y_hi));
        let (mut radius, mut w_min) = (0f32, h[0][3]);
        for i in 0..n {
            radius = jit_max(
                radius,
                ((sx[i] - cx) * (sx[i] - cx) + (sy[i] - cy) * (sy[i] - cy)).sqrt(),
            );
            w_min = jit_min(w_min, h[i][3]);
        }
        let net = (cx, cy, radius);
        let (mut m_bottom, mut m_top, mut m_left, mut m_right) = (0f32, 0f32, 0f32, 0f32);
        let (mut m_uu, mut m_vv) = (0f32, 0f32);
        for j in 0..v_count {
            let (mut row_x, mut row_y, mut row_w) = ([0f32; 12], [0f32; 12], [0f32; 12]);
            for i in 0..u_count {
                row_x[i] = sx[j * u_count + i];
                row_y[i] = sy[j * u_count + i];
                row_w[i] = h[j * u_count + i][3];
            }
            m_uu = jit_max(
                m_uu,
                second_derivative_bound(&u_knots, u_count, u_order, &row_x, &row_y, &row_w, net),
            );
            if j == 0 {
                m_bottom = edge_bound(&u_knots, u_count, u_order, &row_x, &row_y, &row_w);
            }
            if j == v_count - 1 {
                m_top = edge_bound(&u_knots, u_count, u_order, &row_x, &row_y, &row_w);
            }
        }
        for i in 0..u_count {
            let (mut col_x, mut col_y, mut col_w) = ([0f32; 12], [0f32; 12], [0f32; 12]);
            for j in 0..v_count {
                col_x[j] = sx[j * u_count + i];
                col_y[j] = sy[j * u_count + i];
                col_w[j] = h[j * u_count + i][3];
            }
            m_vv = jit_max(
                m_vv,
                second_derivative_bound(&v_knots, v_count, v_order, &col_x, &col_y, &col_w, net),
            );
            if i == 0 {
                m_left = edge_bound(&v_knots, v_count, v_order, &col_x, &col_y, &col_w);
            }
            if i == u_count - 1 {
                m_right = edge_bound(&v_knots, v_count, v_order, &col_x, &col_y, &col_w);
            }
        }
        let (pu, pv) = (u_order - 1, v_order - 1);
        let (mut m_uv_q, mut m_uv_w) = (0f32, 0f32);
        for j in 0..v_count - 1 {
            let sv = v_knots[j + pv + 1] - v_knots[j + 1];
            for i in 0..u_count - 1 {
                let su = u_knots[i + pu + 1] - u_knots[i + 1];
                if su > 0.0 && sv > 0.0 {
                    let (a, b) = (j * u_count + i, (j + 1) * u_count + i);
                    let corners = [a, a + 1, b, b + 1];
                    let qx = corners.map(|at| h[at][3] * (sx[at] - cx));
                    let qy = corners.map(|at| h[at][3] * (sy[at] - cy));
                    let scale = (pu * pv) as f32 / (su * sv);
                    let dx = ((qx[3] - qx[2]) - (qx[1] - qx[0])) * scale;
                    let dy = ((qy[3] - qy[2]) - (qy[1] - qy[0])) * scale;
                    let dw = ((h[b + 1][3] - h[b][3]) - (h[a + 1][3] - h[a][3])) * scale;
                    m_uv_q = jit_max(m_uv_q, (dx * dx + dy * dy).sqrt());
                    m_uv_w = jit_max(m_uv_w, dw.abs());
                }
            }
        }
        m_uu /= w_min;
        m_vv /= w_min;
        let m_uv = (m_uv_q + radius * m_uv_w) / w_min;
        e_bottom = steps(u1 - u0, m_bottom, 2.0 * tolerance, finest);
        e_top = steps(u1 - u0, m_top, 2.0 * tolerance, finest);
        e_left = steps(v1 - v0, m_left, 2.0 * tolerance, finest);
        e_right = steps(v1 - v0, m_right, 2.0 * tolerance, finest);
        inner_u = steps(u1 - u0, m_uu + m_uv, 4.0 * tolerance, finest);
        inner_v = steps(v1 - v0, m_vv + m_uv, 4.0 * tolerance, finest);
        // The prim reports W0801 when the cap is reached; the hand-written kernel has no
        // site to name, and draws at the cap like the prim.
        e_bottom = e_bottom.min(finest);
        e_top = e_top.min(finest);
        e_left = e_left.min(finest);
        e_right = e_right.min(finest);
        inner_u = inner_u.min(finest);
        inner_v = inner_v.min(finest);
    }
    let nu = inner_u.max(3).max(e_bottom.max(e_top));
    let nv = inner_v.max(3).max(e_left.max(e_right));

    // ---- The ring: boundary points and the grid's outer loop, by perimeter position.
    let (mut outer_u, mut outer_v, mut outer_at) = ([0f32; 512], [0f32; 512], [0f32; 512]);
    let mut outer_n = 0;
    for side in 0..4 {
        let e = [e_bottom, e_right, e_top, e_left][side];
        for k in 0..e {
            let along = |lo: f32, hi: f32, k: i32| lo + k as f32 * (hi - lo) / e as f32;
            let ku = if k == 0 { u0 } else { along(u0, u1, k) };
            let kv = if k == 0 { v0 } else { along(v0, v1, k) };
            let back_u = if k == 0 { u1 } else { along(u0, u1, e - k) };
            let back_v = if k == 0 { v1 } else { along(v0, v1, e - k) };
            outer_u[outer_n] = [ku, u1, back_u, u0][side];
            outer_v[outer_n] = [v0, kv, v1, back_v][side];
            outer_at[outer_n] = side as f32 + k as f32 / e as f32;
            outer_n += 1;
        }
    }
    // Inner loop points are grid points: kept as (gi, gj), their parameters computed by
    // `point_uv` with the prim's formula.
    let (mut inner_grid, mut inner_at) = ([(0usize, 0usize); 512], [0f32; 512]);
    let mut inner_n = 0;
    for side in 0..4 {
        let steps = if side % 2 == 0 { nu - 2 } else { nv - 2 };
        for k in 0..steps {
            let gi = [1 + k, nu - 1, nu - 1 - k, 1][side];
            let gj = [1, 1 + k, nv - 1, nv - 1 - k][side];
            inner_grid[inner_n] = (gi as usize, gj as usize);
            inner_at[inner_n] = side as f32 + k as f32 / steps as f32;
            inner_n += 1;
        }
    }

    // SAFETY: the layout has the six matrices at 1 + T.
    let object_from_device = unsafe { space_matrix(args, 1 + T, 3) };
    let net = Surface::<T> {
        args,
        u_count,
        v_count,
        u_order,
        v_order,
        u_knots,
        v_knots,
        h,
        weights,
        object_from_device,
        normal_columns,
        data_at: fixed + seq * 5,
    };
    let mut sink = TriangleSink::<T> {
        ctx,
        triangle,
        block: [0; TRI_WORDS],
    };
    sink.block[0] = 1;
    for c in 0..T {
        sink.block[1 + c] = word(1 + c);
    }

    let ring = outer_n + inner_n;
    let (nu, nv) = (nu as usize, nv as usize);
    let cells = (nu - 2) * (nv - 2);
    // Points by id: the outer loop's first, then grid point (gi, gj) at
    // outer_n + gj * (nu + 1) + gi.
    let grid = |gi: usize, gj: usize| outer_n + gj * (nu + 1) + gi;
    let point_uv = |id: usize| -> (f32, f32) {
        if id < outer_n {
            (outer_u[id], outer_v[id])
        } else {
            let (gi, gj) = ((id - outer_n) % (nu + 1), (id - outer_n) / (nu + 1));
            (
                u0 + gi as f32 * (u1 - u0) / nu as f32,
                v0 + gj as f32 * (v1 - v0) / nv as f32,
            )
        }
    };
    // Every point is evaluated once (each is a corner of up to six triangles), as in the
    // prim; same inputs, same operations, so the same bits as evaluating afresh.
    let mut evaluated: Vec<Option<([f32; 4], [f32; T])>> = vec![None; outer_n + (nu + 1) * (nv + 1)];
    let (mut ia, mut ib) = (0usize, 0usize);
    for t in 0..ring + 2 * cells {
        let ids: [usize; 3];
        if t < ring {
            // Advance on the loop whose next segment's middle comes first around the
            // perimeter.
            let next_a = if ia + 1 < outer_n { outer_at[ia + 1] } else { 4.0 };
            let next_b = if ib + 1 < inner_n { inner_at[ib + 1] } else { 4.0 };
            let (a0, a1) = (ia % outer_n, (ia + 1) % outer_n);
            let take_a = ia < outer_n && (ib >= inner_n || outer_at[a0] + next_a <= inner_at[ib % inner_n] + next_b);
            let (b0, b1) = (inner_grid[ib % inner_n], inner_grid[(ib + 1) % inner_n]);
            ids = [a0, if take_a { a1 } else { grid(b1.0, b1.1) }, grid(b0.0, b0.1)];
            if take_a {
                ia += 1;
            } else {
                ib += 1;
            }
        } else {
            let (c, second) = ((t - ring) / 2, (t - ring) % 2);
            let (gi, gj) = (1 + c % (nu - 2), 1 + c / (nu - 2));
            ids = if second == 0 {
                [grid(gi, gj), grid(gi + 1, gj), grid(gi + 1, gj + 1)]
            } else {
                [grid(gi, gj), grid(gi + 1, gj + 1), grid(gi, gj + 1)]
            };
        }
        let mut corner = [[0f32; 4]; 3];
        let mut corner_data = [[0f32; T]; 3];
        for q in 0..3 {
            let eval = || {
                let (u, v) = point_uv(ids[q]);
                net.corner::<NORMAL>(u, v)
            };
            (corner[q], corner_data[q]) = match evaluated.get_mut(ids[q]) {
                Some(Some(done)) => *done,
                Some(slot) => *slot.insert(eval()),
                None => eval(), // not reached: every id is below the vector's length
            };
        }
        sink.polygon(clip, &corner, &corner_data);
    }
}

/// One kernel entry: the surface with the scalar (`SIMD` false) or AVX2 screen_triangle for
/// P perspective-correct then L linear components, `CLIP` = the key's polygon clip path.
///
/// # Safety
/// Called by the runtime with a valid `ctx` and the argument block of a nurb_surface
/// instance whose key has these components; `SIMD` only when the CPU has AVX2.
unsafe extern "C" fn kernel<
    const P: usize,
    const L: usize,
    const T: usize,
    const NORMAL: bool,
    const COUNT: bool,
    const SIMD: bool,
    const CLIP: bool,
>(
    ctx: *mut TileCtx,
    args: *const u32,
) {
    #[cfg(target_arch = "x86_64")]
    let triangle: KernelFn = if SIMD {
        screen_triangle::avx2::<P, L, T, COUNT>
    } else {
        screen_triangle::scalar::<P, L, T, COUNT>
    };
    #[cfg(not(target_arch = "x86_64"))]
    let triangle: KernelFn = screen_triangle::scalar::<P, L, T, COUNT>;
    // SAFETY: as this function's contract.
    unsafe { surface::<T, NORMAL>(ctx, args, triangle, CLIP) }
}

macro_rules! nurb_table {
    ($(($p:literal, $l:literal, $normal:literal)),*) => {
        /// The kernel for P perspective-correct and L linear components (`normal`: the first
        /// three are an implicit normal), or `None` for a shape without one.
        pub(crate) fn entry(p: usize, l: usize, normal: bool, count: bool, simd: bool, clip: bool) -> Option<KernelFn> {
            macro_rules! pick {
                ($pp:literal, $ll:literal, $nn:literal) => {
                    match (count, simd, clip) {
                        (false, false, false) => Some(kernel::<$pp, $ll, { $pp + $ll }, $nn, false, false, false> as KernelFn),
                        (false, false, true) => Some(kernel::<$pp, $ll, { $pp + $ll }, $nn, false, false, true> as KernelFn),
                        (true, false, false) => Some(kernel::<$pp, $ll, { $pp + $ll }, $nn, true, false, false> as KernelFn),
                        (true, false, true) => Some(kernel::<$pp, $ll, { $pp + $ll }, $nn, true, false, true> as KernelFn),
                        (false, true, false) => Some(kernel::<$pp, $ll, { $pp + $ll }, $nn, false, true, false> as KernelFn),
                        (false, true, true) => Some(kernel::<$pp, $ll, { $pp + $ll }, $nn, false, true, true> as KernelFn),
                        (true, true, false) => Some(kernel::<$pp, $ll, { $pp + $ll }, $nn, true, true, false> as KernelFn),
                        (true, true, true) => Some(kernel::<$pp, $ll, { $pp + $ll }, $nn, true, true, true> as KernelFn),
                    }
                };
            }
            match (p, l, normal) {
                $(($p, $l, $normal) => pick!($p, $l, $normal),)*
                _ => None,
            }
        }
    };
}

nurb_table!(
    (0, 0, false),
    (1, 0, false),
    (0, 1, false),
    (3, 0, true),
    (4, 0, true),
    (3, 1, true),
    (1, 1, false)
);

/// The kernel for `key`, after checking that the key is one this file serves and that the
/// argument layout has the offsets the kernel reads.
pub(crate) fn entry_for(layout: &ArgLayout, key: &VariantKey, simd: bool) -> Result<KernelFn, String> {
    let (mut p, mut l, mut normal) = (0usize, 0usize, false);
    for (i, b) in key.bindings.iter().enumerate() {
        let c = b.components as usize;
        match &b.kind {
            BindingKind::Kind(k) if k == "implicit" && i == 0 && c == 3 => {
                normal = true;
                p += c;
            }
            BindingKind::Kind(k) if k == "perspective_linear" && l == 0 => p += c,
            BindingKind::Kind(k) if k == "linear" => l += c,
            _ => {
                return Err(
                    "the hand-written nurb_surface serves an optional first 3-component `implicit` binding, \
                     then perspective_linear, then linear bindings"
                        .into(),
                )
            }
        }
    }
    let t = p + l;
    if t > MAX_T {
        return Err(format!(
            "the hand-written nurb_surface serves at most {MAX_T} components"
        ));
    }
    let f0 = params_at(t) as u32;
    let fixed = |offset: u32, words: u32| ParamSlot::Fixed { offset, words };
    let seq = |seq_offset: u32, words: u32| ParamSlot::Seq { seq_offset, words };
    let expected = [
        seq(0, 4),
        seq(4, 1),
        fixed(f0, 1),
        fixed(f0 + 1, 1),
        fixed(f0 + 2, 1),
        fixed(f0 + 3, 1),
        fixed(f0 + 4, 16),
        fixed(f0 + 20, 16),
        fixed(f0 + 36, 1),
        fixed(f0 + 37, 3),
        fixed(f0 + 40, 3),
        fixed(f0 + 43, 3),
        seq(5, t as u32),
    ];
    if layout.spaces != Some(1 + t as u32)
        || layout.params.get(..13) != Some(&expected[..])
        || layout.fixed_words != fixed_words(t) as u32
    {
        return Err("nurb_surface's parameters are not the ones the hand-written kernel reads".into());
    }
    entry(p, l, normal, key.count_writes, simd, !key.trivial_accept)
        .ok_or_else(|| format!("no hand-written nurb_surface for {p} perspective-correct + {l} linear components"))
}
