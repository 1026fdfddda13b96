//! screen_triangle written by hand in Rust, in three forms: portable scalar code; SSE4.1
//! (4 pixels per step, the width of the JIT's f32x4 groups: per-row coverage spans, so
//! groups inside the triangle run without edge tests or blends); and AVX2 (8 pixels per
//! step, per-row hoisting, empty-group skipping, masked stores).
//!
//! All mirror `prims/screen_triangle.prim` operation for operation (same snapping, same
//! integer edge functions and top-left rule, same float expression order), so on the same
//! scene they produce the same buffers as the JIT kernel; the benchmark checks that before
//! it reports a time.
//!
//! Argument block (see `abi::ArgLayout`): word 0 n_seq; `T = P + L` plane indices (the P
//! perspective_linear components first, then the L linear ones); `screen_vertex` (12
//! floats); `interp_data[3]` (3 * T floats). `P` and `L` are const generics so the
//! component loops unroll.

use crate::abi::{TileCtx, MODE_BOUND};

/// Everything the per-pixel code needs, computed once per triangle exactly as the prim does.
pub(crate) struct Setup<const T: usize> {
    /// G-buffer plane of each component (the argument block's plane table).
    pub planes: [u32; T],
    pub exact: bool,
    pub ox16: i32,
    pub oy16: i32,
    pub ea: [i32; 3],
    pub eb: [i32; 3],
    pub ec: [i32; 3],
    pub fa: [f32; 3],
    pub fb: [f32; 3],
    pub fc: [f32; 3],
    /// Float edges: whether each is top-left (a tie `e == 0` keeps the pixel).
    pub ftl: [bool; 3],
    /// Over 1024 px with every vertex within 2^24 px: the edges in exact integers on the
    /// global 1/16 grid (the prim's two-limb `limb_sign`, here in i64): `wa * (16 x - gx) +
    /// wb * (16 y - gy) + wtl > 0`.
    pub wide: bool,
    pub wa: [i64; 3],
    pub wb: [i64; 3],
    pub wtl: [i64; 3],
    pub gx: [i64; 3],
    pub gy: [i64; 3],
    pub z: [f32; 3],
    /// Planes of the linear parameters (a, b, c per component).
    pub la: [f32; T],
    pub lb: [f32; T],
    pub lc: [f32; T],
    /// Planes of f/w per component and of 1/w.
    pub ga: [f32; T],
    pub gb: [f32; T],
    pub gc: [f32; T],
    pub q: [f32; 3],
}

/// Read word `i` of the argument block.
///
/// # Safety
/// `args` must point to at least `i + 1` words.
#[inline(always)]
unsafe fn word(args: *const u32, i: usize) -> u32 {
    unsafe { *args.add(i) }
}

#[inline(always)]
fn min3(a: f32, b: f32, c: f32) -> f32 {
    a.min(b).min(c)
}

#[inline(always)]
fn max3(a: f32, b: f32, c: f32) -> f32 {
    a.max(b).max(c)
}

/// The prim up to its `bound(...)`: the integer grid's origin and the vertices' largest
/// coordinates. `None` for a NaN or infinite vertex (nothing to draw).
#[derive(Clone, Copy)]
pub(crate) struct Extent {
    min_x: f32,
    min_y: f32,
    ox: f32,
    oy: f32,
    max_x: f32,
    max_y: f32,
}

impl Extent {
    /// # Safety
    /// `args` must hold the screen_triangle argument block for `T` components.
    #[inline(always)]
    pub(crate) unsafe fn of<const T: usize>(args: *const u32) -> Option<Extent> {
        let sv = |v: usize, c: usize| f32::from_bits(unsafe { word(args, 1 + T + v * 4 + c) });
        for i in 0..3 {
            if !(sv(i, 0).abs() < 1e30 && sv(i, 1).abs() < 1e30) {
                return None;
            }
        }
        let (min_x, min_y) = (min3(sv(0, 0), sv(1, 0), sv(2, 0)), min3(sv(0, 1), sv(1, 1), sv(2, 1)));
        Some(Extent {
            min_x,
            min_y,
            ox: min_x.floor(),
            oy: min_y.floor(),
            max_x: max3(sv(0, 0), sv(1, 0), sv(2, 0)),
            max_y: max3(sv(0, 1), sv(1, 1), sv(2, 1)),
        })
    }

    /// The bound the prim records: padded by a 1/16 grid step, since snapping can move a
    /// corner past the extreme coordinates.
    #[inline(always)]
    pub(crate) fn bound(&self) -> [f32; 4] {
        [
            self.min_x - 0.0625,
            self.min_y - 0.0625,
            self.max_x + 0.0625,
            self.max_y + 0.0625,
        ]
    }
}

/// The prim up to its `bound(...)`, and the tile's pixel rectangle it covers. A bound run
/// records the bound and ends here (`None`), as the prim's (and the JIT's) does, so the
/// rest of [`setup`] runs only when rendering.
///
/// # Safety
/// As [`Extent::of`].
#[inline(always)]
pub(crate) unsafe fn extent_in_tile<const T: usize>(ctx: &mut TileCtx, args: *const u32) -> Option<(Extent, [i32; 4])> {
    let e = unsafe { Extent::of::<T>(args) }?;
    bound_or_rect(ctx, e.bound()).map(|rect| (e, rect))
}

/// The rest of the prim's uniform part, after its `bound(...)`. `None` when the triangle
/// draws nothing.
///
/// One function because it mirrors `prims/screen_triangle.prim`'s setup operation for
/// operation (see the module doc): kept in the prim's order, it reads side by side with it.
///
/// Inlined into each kernel so the SIMD ones round with their own instructions (SSE4.1's
/// `roundss`) rather than baseline x86-64's libm calls (`floorf`, `rintf`): on the small
/// triangles workload the AVX2 kernel retires 29 % fewer instructions so.
///
/// # Safety
/// `args` must hold the screen_triangle argument block for `T` components.
#[inline(always)]
pub(crate) unsafe fn setup<const T: usize>(args: *const u32, e: Extent) -> Option<Setup<T>> {
    let sv_at = 1 + T;
    let data_at = sv_at + 12;
    let sv = |v: usize, c: usize| f32::from_bits(unsafe { word(args, sv_at + v * 4 + c) });
    let data = |v: usize, c: usize| f32::from_bits(unsafe { word(args, data_at + v * T + c) });
    let Extent {
        ox,
        oy,
        max_x,
        max_y,
        min_x,
        min_y,
    } = e;
    let exact = max_x - ox < 1024.0 && max_y - oy < 1024.0;
    const WIDE_LIMIT: f32 = 16777216.0;
    let wide = !exact && min_x > -WIDE_LIMIT && max_x < WIDE_LIMIT && min_y > -WIDE_LIMIT && max_y < WIDE_LIMIT;
    let mut vx = [0i32; 3];
    let mut vy = [0i32; 3];
    let mut px = [0f32; 3];
    let mut py = [0f32; 3];
    for i in 0..3 {
        vx[i] = ((sv(i, 0) - ox) * 16.0).round_ties_even() as i32;
        vy[i] = ((sv(i, 1) - oy) * 16.0).round_ties_even() as i32;
        px[i] = ox + vx[i] as f32 / 16.0;
        py[i] = oy + vy[i] as f32 / 16.0;
    }
    // The wide path's vertices on the global 1/16 grid (the prim splits them into limbs;
    // i64 holds them whole).
    let (mut gx, mut gy) = ([0i64; 3], [0i64; 3]);
    if wide {
        for i in 0..3 {
            let (fx, fy) = ((sv(i, 0) * 16.0).round_ties_even(), (sv(i, 1) * 16.0).round_ties_even());
            gx[i] = fx as i64;
            gy[i] = fy as i64;
            px[i] = fx / 16.0;
            py[i] = fy / 16.0;
        }
    } else if !exact {
        for i in 0..3 {
            px[i] = sv(i, 0);
            py[i] = sv(i, 1);
        }
    }
    let (dx1, dy1) = (px[1] - px[0], py[1] - py[0]);
    let (dx2, dy2) = (px[2] - px[0], py[2] - py[0]);
    let det = dx1 * dy2 - dx2 * dy1;
    let mut orient: i32 = if det > 0.0 { 1 } else { -1 };
    if wide {
        let exact_det = (gx[1] - gx[0]) * (gy[2] - gy[0]) - (gx[2] - gx[0]) * (gy[1] - gy[0]);
        orient = exact_det.signum() as i32;
        if orient == 0 {
            return None;
        }
    } else if det == 0.0 || !(det.abs() < 1e30) {
        return None;
    }
    let (mut ea, mut eb, mut ec) = ([0i32; 3], [0i32; 3], [0i32; 3]);
    let (mut fa, mut fb, mut fc) = ([0f32; 3], [0f32; 3], [0f32; 3]);
    let (mut wa, mut wb, mut wtl) = ([0i64; 3], [0i64; 3], [0i64; 3]);
    let mut ftl = [false; 3];
    for i in 0..3 {
        let j = (i + 1) % 3;
        ea[i] = (-orient).wrapping_mul(vy[j].wrapping_sub(vy[i]));
        eb[i] = orient.wrapping_mul(vx[j].wrapping_sub(vx[i]));
        let top_left = if ea[i] > 0 || (ea[i] == 0 && eb[i] < 0) { 1 } else { 0 };
        ec[i] = top_left - (ea[i].wrapping_mul(vx[i]).wrapping_add(eb[i].wrapping_mul(vy[i])));
        if wide {
            wa[i] = -i64::from(orient) * (gy[j] - gy[i]);
            wb[i] = i64::from(orient) * (gx[j] - gx[i]);
            wtl[i] = i64::from(wa[i] > 0 || (wa[i] == 0 && wb[i] < 0));
        }
        // The float edge from its endpoints in canonical order, then oriented (as the prim).
        let (lo, hi) = if px[j] < px[i] || (px[j] == px[i] && py[j] < py[i]) {
            (j, i)
        } else {
            (i, j)
        };
        let a = -(py[hi] - py[lo]);
        let b = px[hi] - px[lo];
        let c = -(a * px[lo] + b * py[lo]);
        let sign = if lo == i { orient } else { -orient } as f32;
        fa[i] = sign * a;
        fb[i] = sign * b;
        fc[i] = sign * c;
        ftl[i] = fa[i] > 0.0 || (fa[i] == 0.0 && fb[i] < 0.0);
    }
    // The planes go through the vertices as given, not as snapped (as in
    // prims/screen_triangle.prim): the values belong to those positions. Degenerate as
    // given but not as snapped: the snapped corners give the planes.
    let (mut ux, mut uy) = ([sv(0, 0), sv(1, 0), sv(2, 0)], [sv(0, 1), sv(1, 1), sv(2, 1)]);
    let (mut ux1, mut uy1) = (ux[1] - ux[0], uy[1] - uy[0]);
    let (mut ux2, mut uy2) = (ux[2] - ux[0], uy[2] - uy[0]);
    let mut plane_det = ux1 * uy2 - ux2 * uy1;
    if plane_det == 0.0 || !(plane_det.abs() < 1e30) {
        ux = px;
        uy = py;
        (ux1, uy1, ux2, uy2) = (dx1, dy1, dx2, dy2);
        plane_det = det;
    }
    let inv_det = 1.0 / plane_det;
    let z1 = sv(1, 2) - sv(0, 2);
    let z2 = sv(2, 2) - sv(0, 2);
    let za = (z1 * uy2 - z2 * uy1) * inv_det;
    let zb = (z2 * ux1 - z1 * ux2) * inv_det;
    let zc = sv(0, 2) - za * ux[0] - zb * uy[0];

    let q0 = 1.0 / sv(0, 3);
    let q1 = 1.0 / sv(1, 3);
    let q2 = 1.0 / sv(2, 3);
    let mut planes = [0u32; T];
    for (c, p) in planes.iter_mut().enumerate() {
        // SAFETY: the plane table has T words after word 0.
        *p = unsafe { word(args, 1 + c) };
    }
    let mut s = Setup::<T> {
        planes,
        exact,
        ox16: (ox * 16.0) as i32,
        oy16: (oy * 16.0) as i32,
        ea,
        eb,
        ec,
        fa,
        fb,
        fc,
        ftl,
        wide,
        wa,
        wb,
        wtl,
        gx,
        gy,
        z: [za, zb, zc],
        la: [0.0; T],
        lb: [0.0; T],
        lc: [0.0; T],
        ga: [0.0; T],
        gb: [0.0; T],
        gc: [0.0; T],
        q: [0.0; 3],
    };
    for c in 0..T {
        let (d0, d1, d2) = (data(0, c), data(1, c), data(2, c));
        let (l1, l2) = (d1 - d0, d2 - d0);
        s.la[c] = (l1 * uy2 - l2 * uy1) * inv_det;
        s.lb[c] = (l2 * ux1 - l1 * ux2) * inv_det;
        s.lc[c] = d0 - s.la[c] * ux[0] - s.lb[c] * uy[0];
        let g1 = d1 * q1 - d0 * q0;
        let g2 = d2 * q2 - d0 * q0;
        s.ga[c] = (g1 * uy2 - g2 * uy1) * inv_det;
        s.gb[c] = (g2 * ux1 - g1 * ux2) * inv_det;
        s.gc[c] = d0 * q0 - s.ga[c] * ux[0] - s.gb[c] * uy[0];
    }
    let qa = ((q1 - q0) * uy2 - (q2 - q0) * uy1) * inv_det;
    let qb = ((q2 - q0) * ux1 - (q1 - q0) * ux2) * inv_det;
    let qc = q0 - qa * ux[0] - qb * uy[0];
    s.q = [qa, qb, qc];
    Some(s)
}

/// Record the bound (bound mode) or return the pixel rectangle [x0, x1) x [y0, y1) of the
/// tile whose centres lie in it (render mode), as the JIT does. Inlined, as [`setup`].
#[inline(always)]
pub(crate) fn bound_or_rect(ctx: &mut TileCtx, b: [f32; 4]) -> Option<[i32; 4]> {
    if ctx.mode == MODE_BOUND {
        if b.iter().any(|v| v.is_nan()) {
            return None;
        }
        if ctx.bound_set == 0 {
            ctx.bound = b;
            ctx.bound_set = 1;
        } else {
            ctx.bound = [
                ctx.bound[0].min(b[0]),
                ctx.bound[1].min(b[1]),
                ctx.bound[2].max(b[2]),
                ctx.bound[3].max(b[3]),
            ];
        }
        return None;
    }
    if b.iter().any(|v| v.is_nan()) {
        return None;
    }
    let clampf = |v: f32, lo: i32, hi: i32| v.clamp(lo as f32, hi as f32) as i32;
    let x0 = clampf((b[0] - 0.5).ceil(), ctx.x0, ctx.x1);
    let x1 = clampf((b[2] - 0.5).floor() + 1.0, ctx.x0, ctx.x1);
    let y0 = clampf((b[1] - 0.5).ceil(), ctx.y0, ctx.y1);
    let y1 = clampf((b[3] - 0.5).floor() + 1.0, ctx.y0, ctx.y1);
    (x0 < x1 && y0 < y1).then_some([x0, y0, x1, y1])
}

/// float -> fixed<32,32> raw, as the JIT converts (nearest, saturating, NaN -> 0).
#[inline(always)]
pub(crate) fn depth_raw(z: f32) -> u32 {
    (z * 4294967296.0).round_ties_even() as u32
}

/// Each of `planes`' G-buffer plane in this tile, or null for a plane the frame lacks (the
/// SSE kernels skip its stores).
#[cfg(target_arch = "x86_64")]
pub(crate) fn tile_plane_bases<const T: usize>(ctx: &TileCtx, planes: &[u32; T]) -> [*mut f32; T] {
    std::array::from_fn(|c| {
        if planes[c] < ctx.num_planes {
            // SAFETY: plane `planes[c]` of `num_planes` starts inside gbuf.
            unsafe { ctx.gbuf.add(planes[c] as usize * ctx.plane_stride as usize) }
        } else {
            std::ptr::null_mut()
        }
    })
}

/// float -> fixed<32,32> raw for 4 depths in [0, 1], as [`depth_raw`] (nearest, saturating;
/// the SSE4.1 kernels' conversion, inlined into both encodings). Below 2^31 the signed
/// conversion rounds to nearest even (the MXCSR default) and is exact; from 2^31 on it gives
/// 0x8000_0000, and z * 2^32 - 2^31 (exact there, an integer) supplies the low bits; 2^32
/// itself (z == 1) converts to 0x8000_0000 in the second conversion, which the arithmetic
/// shift turns into all ones. Lanes outside [0, 1] are the caller's to mask off.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse4.1")]
#[inline]
pub(crate) fn depth_raw4(z: std::arch::x86_64::__m128) -> std::arch::x86_64::__m128i {
    use std::arch::x86_64::*;
    let scaled = _mm_mul_ps(z, _mm_set1_ps(4294967296.0));
    let low = _mm_cvtps_epi32(scaled);
    let above = _mm_max_ps(_mm_sub_ps(scaled, _mm_set1_ps(2147483648.0)), _mm_setzero_ps());
    let high = _mm_cvtps_epi32(above);
    let high = _mm_or_si128(high, _mm_srai_epi32::<31>(high));
    _mm_or_si128(low, high)
}

/// float -> fixed<32,32> raw for 8 depths in [0, 1], as [`depth_raw`] (nearest, saturating).
/// Values below 2^31 convert directly; values in [2^31, 2^32) are shifted down by 2^31
/// first (exact there) and the top bit set back; 2^32 itself (z == 1) saturates.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(crate) fn depth_raw8(z: std::arch::x86_64::__m256) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    let two32 = _mm256_set1_ps(4294967296.0);
    let two31 = _mm256_set1_ps(2147483648.0);
    let scaled = _mm256_round_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(_mm256_mul_ps(z, two32));
    let high = _mm256_cmp_ps::<_CMP_GE_OQ>(scaled, two31);
    let shifted = _mm256_blendv_ps(scaled, _mm256_sub_ps(scaled, two31), high);
    let tz = _mm256_cvtps_epi32(shifted);
    let tz = _mm256_or_si256(
        tz,
        _mm256_and_si256(_mm256_castps_si256(high), _mm256_set1_epi32(i32::MIN)),
    );
    _mm256_or_si256(tz, _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GE_OQ>(scaled, two32)))
}

/// The AVX2 kernels' Z test and write for the 8 pixels at `base` of the tile's rows: of the
/// lanes in `mask`, those whose depth `tz` is not farther than the buffer's (unsigned
/// `tz >= old`, the JIT's `Z` test) get `tz` stored and, with `COUNT`, their write count
/// bumped. Returns the lanes written (all zero when none).
///
/// # Safety
/// `live` holds the lanes whose pixels lie in the tile's row (a superset of `mask`): only
/// those are read, and only `mask`'s lanes written (maskload/maskstore touch no other lane).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(crate) unsafe fn depth_test8<const COUNT: bool>(
    ctx: &TileCtx,
    base: usize,
    live: std::arch::x86_64::__m256i,
    mask: std::arch::x86_64::__m256i,
    tz: std::arch::x86_64::__m256i,
) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    let sign = _mm256_set1_epi32(i32::MIN);
    let zptr = ctx.depth.add(base) as *mut i32;
    let old = _mm256_maskload_epi32(zptr, live);
    // Unsigned old > tz, by flipping the sign bits.
    let farther = _mm256_cmpgt_epi32(_mm256_xor_si256(old, sign), _mm256_xor_si256(tz, sign));
    let mask = _mm256_andnot_si256(farther, mask);
    if _mm256_testz_si256(mask, mask) == 0 {
        _mm256_maskstore_epi32(zptr, mask, tz);
        if COUNT {
            let cptr = ctx.write_count.add(base) as *mut i32;
            let counts = _mm256_maskload_epi32(cptr, mask);
            _mm256_maskstore_epi32(cptr, mask, _mm256_sub_epi32(counts, mask));
        }
    }
    mask
}

/// The wide path's edge tests at the pixel centre (x, y): exact, in i64 (|wa| <= 2^29 and
/// |16 x - gx| <= 2^29, so nothing overflows), as the prim's two-limb `limb_sign` is.
#[inline]
pub(crate) fn wide_inside<const T: usize>(s: &Setup<T>, x: f32, y: f32) -> bool {
    let (sx, sy) = ((x * 16.0) as i64, (y * 16.0) as i64);
    (0..3).all(|i| s.wa[i] * (sx - s.gx[i]) + s.wb[i] * (sy - s.gy[i]) + s.wtl[i] > 0)
}

/// The float path's edge tests: outside, or on a non-top-left edge, fails (a NaN edge
/// value keeps the pixel, as the prim returns only on `e < 0 || (e == 0 && !top_left)`).
#[inline]
pub(crate) fn float_inside<const T: usize>(s: &Setup<T>, x: f32, y: f32) -> bool {
    (0..3).all(|i| {
        let e = s.fa[i] * x + s.fb[i] * y + s.fc[i];
        !(e < 0.0 || (e == 0.0 && !s.ftl[i]))
    })
}

/// Portable scalar kernel.
///
/// # Safety
/// Called by the runtime with a valid `ctx` and the argument block of a screen_triangle
/// instance whose key has `P` perspective_linear then `L` linear components.
pub unsafe extern "C" fn scalar<const P: usize, const L: usize, const T: usize, const COUNT: bool>(
    ctx: *mut TileCtx,
    args: *const u32,
) {
    // SAFETY: the runtime hands a valid, exclusive context for the duration of the call.
    let ctx = unsafe { &mut *ctx };
    let Some((e, [rx0, ry0, rx1, ry1])) = (unsafe { extent_in_tile::<T>(ctx, args) }) else {
        return;
    };
    let Some(s) = (unsafe { setup::<T>(args, e) }) else {
        return;
    };
    let planes = s.planes;
    for py in ry0..ry1 {
        let y = py as f32 + 0.5;
        for px in rx0..rx1 {
            let x = px as f32 + 0.5;
            let inside = if s.exact {
                let sx = ((x * 16.0) as i32).wrapping_sub(s.ox16);
                let sy = ((y * 16.0) as i32).wrapping_sub(s.oy16);
                (0..3).all(|i| {
                    s.ea[i]
                        .wrapping_mul(sx)
                        .wrapping_add(s.eb[i].wrapping_mul(sy))
                        .wrapping_add(s.ec[i])
                        > 0
                })
            } else if s.wide {
                wide_inside(&s, x, y)
            } else {
                float_inside(&s, x, y)
            };
            if !inside {
                continue;
            }
            let z = s.z[0] * x + s.z[1] * y + s.z[2];
            if !(z >= 0.0 && z <= 1.0) {
                continue;
            }
            let tz = depth_raw(z);
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
                let qw = s.q[0] * x + s.q[1] * y + s.q[2];
                for c in 0..T {
                    let v = if c < P {
                        (s.ga[c] * x + s.gb[c] * y + s.gc[c]) / qw
                    } else {
                        s.la[c] * x + s.lb[c] * y + s.lc[c]
                    };
                    if planes[c] < ctx.num_planes {
                        *ctx.gbuf.add(planes[c] as usize * ctx.plane_stride as usize + idx) = v;
                    }
                }
            }
        }
    }
}

/// AVX2 kernel: 8 pixels per step, row-hoisted edge and plane terms, groups with no live lane
/// skipped, masked stores (never touching memory outside the row's pixels).
///
/// # Safety
/// As [`scalar`], and the CPU must support AVX2 (the caller checks).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub unsafe extern "C" fn avx2<const P: usize, const L: usize, const T: usize, const COUNT: bool>(
    ctx: *mut TileCtx,
    args: *const u32,
) {
    use std::arch::x86_64::*;
    // SAFETY: as in `scalar`.
    let ctx = unsafe { &mut *ctx };
    let Some((e, [rx0, ry0, rx1, ry1])) = (unsafe { extent_in_tile::<T>(ctx, args) }) else {
        return;
    };
    let Some(s) = (unsafe { setup::<T>(args, e) }) else {
        return;
    };
    let planes = s.planes;
    let lane_offsets = _mm256_setr_ps(0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5, 7.5);
    let lane_index = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let zero_i = _mm256_setzero_si256();
    let (one, zero) = (_mm256_set1_ps(1.0), _mm256_setzero_ps());
    let sixteen = _mm256_set1_ps(16.0);
    for py in ry0..ry1 {
        let y = py as f32 + 0.5;
        let row = (py - ctx.y0) as usize * ctx.stride as usize;
        // Per-row terms: b*y + c of every plane and edge.
        let sy = ((y * 16.0) as i32).wrapping_sub(s.oy16);
        let erow: [__m256i; 3] =
            std::array::from_fn(|i| _mm256_set1_epi32(s.eb[i].wrapping_mul(sy).wrapping_add(s.ec[i])));
        let fby: [__m256; 3] = std::array::from_fn(|i| _mm256_set1_ps(s.fb[i] * y));
        let mut px = rx0;
        while px < rx1 {
            let n = (rx1 - px).min(8);
            let live_lanes = _mm256_cmpgt_epi32(_mm256_set1_epi32(n), lane_index);
            let x = _mm256_add_ps(_mm256_set1_ps(px as f32), lane_offsets);
            let mut mask = live_lanes;
            if s.exact {
                let sx = _mm256_sub_epi32(
                    _mm256_cvttps_epi32(_mm256_mul_ps(x, sixteen)),
                    _mm256_set1_epi32(s.ox16),
                );
                for i in 0..3 {
                    let e = _mm256_add_epi32(_mm256_mullo_epi32(_mm256_set1_epi32(s.ea[i]), sx), erow[i]);
                    mask = _mm256_and_si256(mask, _mm256_cmpgt_epi32(e, zero_i));
                }
            } else if s.wide {
                // Rare (triangles over 1024 px): the exact i64 test per lane.
                let lanes: [i32; 8] =
                    std::array::from_fn(|k| -i32::from(wide_inside(&s, (px + k as i32) as f32 + 0.5, y)));
                // SAFETY: an unaligned load of 8 i32 from a local array.
                let lanes = unsafe { _mm256_loadu_si256(lanes.as_ptr() as *const __m256i) };
                mask = _mm256_and_si256(mask, lanes);
            } else {
                for i in 0..3 {
                    // (a*x + b*y) + c, in the prim's order (not re-associated: bit-equal).
                    let e = _mm256_add_ps(
                        _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(s.fa[i]), x), fby[i]),
                        _mm256_set1_ps(s.fc[i]),
                    );
                    // As the prim returns: !(e < 0) on a top-left edge, !(e <= 0) on another
                    // (a NaN edge value keeps the pixel).
                    let keep = if s.ftl[i] {
                        _mm256_cmp_ps::<_CMP_NLT_UQ>(e, zero)
                    } else {
                        _mm256_cmp_ps::<_CMP_NLE_UQ>(e, zero)
                    };
                    mask = _mm256_and_si256(mask, _mm256_castps_si256(keep));
                }
            }
            if _mm256_testz_si256(mask, mask) != 0 {
                px += 8;
                continue;
            }
            // z = (za*x + zb*y) + zc, in the prim's order.
            let z = _mm256_add_ps(
                _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(s.z[0]), x), _mm256_set1_ps(s.z[1] * y)),
                _mm256_set1_ps(s.z[2]),
            );
            let in_range = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(z, zero),
                _mm256_cmp_ps::<_CMP_LE_OQ>(z, one),
            );
            mask = _mm256_and_si256(mask, _mm256_castps_si256(in_range));
            let tz = depth_raw8(z);
            let base = row + (px - ctx.x0) as usize;
            // SAFETY: lanes beyond `n` are masked off, and maskload/maskstore never touch
            // memory of masked-off lanes; the first `n` pixels of the row lie in the tile.
            unsafe {
                mask = depth_test8::<COUNT>(ctx, base, live_lanes, mask, tz);
                if _mm256_testz_si256(mask, mask) != 0 {
                    px += 8;
                    continue;
                }
                let qw = _mm256_add_ps(
                    _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(s.q[0]), x), _mm256_set1_ps(s.q[1] * y)),
                    _mm256_set1_ps(s.q[2]),
                );
                for c in 0..T {
                    if planes[c] >= ctx.num_planes {
                        continue;
                    }
                    let v = if c < P {
                        let g = _mm256_add_ps(
                            _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(s.ga[c]), x), _mm256_set1_ps(s.gb[c] * y)),
                            _mm256_set1_ps(s.gc[c]),
                        );
                        _mm256_div_ps(g, qw)
                    } else {
                        _mm256_add_ps(
                            _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(s.la[c]), x), _mm256_set1_ps(s.lb[c] * y)),
                            _mm256_set1_ps(s.lc[c]),
                        )
                    };
                    let dst = ctx.gbuf.add(planes[c] as usize * ctx.plane_stride as usize + base);
                    _mm256_maskstore_ps(dst, mask, v);
                }
            }
            px += 8;
        }
    }
}

/// Rows narrower than this many pixels test the edges per group instead of solving for the
/// row's span (up to three 64-bit divisions a row, which a few groups of tests beat).
const SPAN_MIN_WIDTH: i32 = 32;

/// The pixels `[a, b)` of row `py`, within `[rx0, rx1)`, whose centres pass the prim's three
/// integer edge tests (`ea * sx + eb * sy + ec > 0`); `a >= b` when none does.
///
/// The prim evaluates the edges in wrapping 32-bit arithmetic, which is the exact value
/// modulo 2^32. Along a row the exact value is linear in the pixel, so when it lies in the
/// i32 range at both ends of `[rx0, rx1)` it does at every pixel between, wrapping changes
/// nothing, and the inequality can be solved exactly in 64 bits. Otherwise `None`: the
/// caller tests the row's pixels one by one, as the prim does.
pub(crate) fn exact_span<const T: usize>(s: &Setup<T>, py: i32, rx0: i32, rx1: i32) -> Option<(i32, i32)> {
    let in_i32 = |v: i64| v >= i64::from(i32::MIN) && v <= i64::from(i32::MAX);
    // sx = int(X * 16) - int(ox * 16) with X = px + 0.5: X * 16 is exactly 16 px + 8 for
    // any pixel of a tile (|px| < 2^19), so int() of it is too.
    let sx = |px: i32| 16 * i64::from(px) + 8 - i64::from(s.ox16);
    let (first, last) = (rx0, rx1 - 1);
    if !(in_i32(sx(first)) && in_i32(sx(last))) {
        return None;
    }
    let sy = (((py as f32 + 0.5) * 16.0) as i32).wrapping_sub(s.oy16);
    let (mut lo, mut hi) = (i64::from(rx0), i64::from(rx1));
    for i in 0..3 {
        let a = i64::from(s.ea[i]);
        // Exact value of the row's constant part (|eb * sy| <= 2^62, |ec| < 2^31). The
        // products below fit too; the sums are checked (an overflow gives up on the row).
        let r = i64::from(s.eb[i]) * i64::from(sy) + i64::from(s.ec[i]);
        let e = |px: i32| (a * sx(px)).checked_add(r);
        if !(e(first).is_some_and(in_i32) && e(last).is_some_and(in_i32)) {
            return None;
        }
        // e(px) = 16 a px + c0.
        let c0 = (a * (8 - i64::from(s.ox16))).checked_add(r)?;
        let slope = 16 * a;
        if slope > 0 {
            // px > -c0 / slope  <=>  px >= floor(-c0 / slope) + 1.
            lo = lo.max(c0.checked_neg()?.div_euclid(slope) + 1);
        } else if slope < 0 {
            // (-slope) px < c0  <=>  px < ceil(c0 / -slope).
            hi = hi.min(-(c0.checked_neg()?.div_euclid(-slope)));
        } else if c0 <= 0 {
            return Some((rx0, rx0));
        }
    }
    // Both now lie in [rx0, rx1] or the span is empty: they fit an i32.
    let lo = lo.clamp(i64::from(rx0), i64::from(rx1)) as i32;
    let hi = hi.clamp(i64::from(rx0), i64::from(rx1)) as i32;
    Some((lo, hi))
}

/// The SSE4.1 kernel's body, stamped out twice by [`sse_kernel!`]: once with legacy SSE
/// encoding (any x86_64 CPU with SSE4.1) and once with VEX encoding (three-operand forms,
/// unaligned memory operands) for CPUs with AVX, which is what the JIT emits there. Both are
/// 128-bit, 4 pixels per step: the JIT's width.
///
/// Per row: the integer edges are solved for the span of covered pixels ([`exact_span`]), so
/// groups inside it run without edge tests, and the depth range test is dropped for the row
/// when both ends of the span pass it (z is monotone in x: each f32 operation of
/// `(za * x + zb * y) + zc` is). Per group: depth converted and tested, then every store is
/// a plain store when all four lanes pass and a load + blend + store otherwise. Groups start
/// at tile-aligned x, like the JIT's, so a 4-lane load or store never leaves the row.
/// Narrow rectangles, rows whose edge values could wrap, and triangles on the float edge
/// path test the edges per group.
macro_rules! sse_kernel {
    ($(#[$doc:meta])* $name:ident, $features:literal) => {
        $(#[$doc])*
        ///
        /// # Safety
        /// As [`scalar`], and the CPU must support the enabled features (the caller checks).
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        pub unsafe extern "C" fn $name<const P: usize, const L: usize, const T: usize, const COUNT: bool>(
            ctx: *mut TileCtx,
            args: *const u32,
        ) {
            use std::arch::x86_64::*;

            /// (a * x + by) + c, the prim's plane expression with b * y hoisted per row.
            #[inline]
            #[target_feature(enable = $features)]
            fn plane(a: __m128, x: __m128, by: __m128, c: __m128) -> __m128 {
                _mm_add_ps(_mm_add_ps(_mm_mul_ps(a, x), by), c)
            }

            // SAFETY: as in `scalar`.
            let ctx = unsafe { &mut *ctx };
            let Some((e, [rx0, ry0, rx1, ry1])) = (unsafe { extent_in_tile::<T>(ctx, args) }) else {
                return;
            };
            let Some(s) = (unsafe { setup::<T>(args, e) }) else { return };
            let stride = ctx.stride as usize;
            let plane_base = tile_plane_bases(ctx, &s.planes);
            let splat = |v: f32| _mm_set1_ps(v);
            let (za, zc) = (splat(s.z[0]), splat(s.z[2]));
            let (qa, qc) = (splat(s.q[0]), splat(s.q[2]));
            let a_of: [__m128; T] = std::array::from_fn(|c| splat(if c < P { s.ga[c] } else { s.la[c] }));
            let c_of: [__m128; T] = std::array::from_fn(|c| splat(if c < P { s.gc[c] } else { s.lc[c] }));
            let (zero, one) = (_mm_setzero_ps(), _mm_set1_ps(1.0));
            let all_lanes = _mm_set1_epi32(-1);
            let lane_offsets = _mm_setr_ps(0.5, 1.5, 2.5, 3.5);
            let lane_index = _mm_setr_epi32(0, 1, 2, 3);
            // Integer edge x step per group: sx grows by 16 per pixel.
            let edge_step: [__m128i; 3] = std::array::from_fn(|i| _mm_set1_epi32(s.ea[i].wrapping_mul(64)));
            let spans = s.exact && rx1 - rx0 >= SPAN_MIN_WIDTH;

            for py in ry0..ry1 {
                let y = py as f32 + 0.5;
                let row = (py - ctx.y0) as usize * stride;
                // The pixels to visit and whether the edges are already decided for them.
                let (cx0, cx1, edges_known) = match spans.then(|| exact_span(&s, py, rx0, rx1)).flatten() {
                    Some((a, b)) if a >= b => continue,
                    Some((a, b)) => (a, b, true),
                    None => (rx0, rx1, false),
                };
                let z_at = |px: i32| s.z[0] * (px as f32 + 0.5) + s.z[1] * y + s.z[2];
                let in_range = |z: f32| z >= 0.0 && z <= 1.0;
                let depth_known = edges_known && in_range(z_at(cx0)) && in_range(z_at(cx1 - 1));
                let (zby, qby) = (splat(s.z[1] * y), splat(s.q[1] * y));
                let by_of: [__m128; T] = std::array::from_fn(|c| splat(if c < P { s.gb[c] } else { s.lb[c] } * y));

                let mut gx = ctx.x0 + ((cx0 - ctx.x0) & !3);
                let mut x = _mm_add_ps(_mm_set1_ps(gx as f32), lane_offsets);
                // Per-group edge state for the rows that test edges per group.
                let sy = ((y * 16.0) as i32).wrapping_sub(s.oy16);
                let sx = _mm_add_epi32(
                    _mm_set1_epi32(gx.wrapping_mul(16).wrapping_add(8).wrapping_sub(s.ox16)),
                    _mm_setr_epi32(0, 16, 32, 48),
                );
                let mut edge: [__m128i; 3] = std::array::from_fn(|i| {
                    _mm_add_epi32(
                        _mm_mullo_epi32(_mm_set1_epi32(s.ea[i]), sx),
                        _mm_set1_epi32(s.eb[i].wrapping_mul(sy).wrapping_add(s.ec[i])),
                    )
                });
                let fby: [__m128; 3] = std::array::from_fn(|i| splat(s.fb[i] * y));

                while gx < cx1 {
                    let mut live = if gx < cx0 || gx + 4 > cx1 {
                        let px = _mm_add_epi32(_mm_set1_epi32(gx), lane_index);
                        _mm_and_si128(
                            _mm_cmpgt_epi32(px, _mm_set1_epi32(cx0 - 1)),
                            _mm_cmplt_epi32(px, _mm_set1_epi32(cx1)),
                        )
                    } else {
                        all_lanes
                    };
                    if !edges_known {
                        if s.exact {
                            for e in &edge {
                                live = _mm_and_si128(live, _mm_cmpgt_epi32(*e, _mm_setzero_si128()));
                            }
                        } else if s.wide {
                            // Rare (triangles over 1024 px): the exact i64 test per lane.
                            let lanes: [i32; 4] =
                                std::array::from_fn(|k| -i32::from(wide_inside(&s, (gx + k as i32) as f32 + 0.5, y)));
                            // SAFETY: an unaligned load of 4 i32 from a local array.
                            let lanes = unsafe { _mm_loadu_si128(lanes.as_ptr() as *const __m128i) };
                            live = _mm_and_si128(live, lanes);
                        } else {
                            for i in 0..3 {
                                let e = plane(splat(s.fa[i]), x, fby[i], splat(s.fc[i]));
                                // As the prim returns: !(e < 0) on a top-left edge, !(e <= 0)
                                // on another (NaN keeps the pixel).
                                let keep = if s.ftl[i] { _mm_cmpnlt_ps(e, zero) } else { _mm_cmpnle_ps(e, zero) };
                                live = _mm_and_si128(live, _mm_castps_si128(keep));
                            }
                        }
                    }
                    let z = plane(za, x, zby, zc);
                    if !depth_known {
                        let z_ok = _mm_and_ps(_mm_cmpge_ps(z, zero), _mm_cmple_ps(z, one));
                        live = _mm_and_si128(live, _mm_castps_si128(z_ok));
                    }
                    if _mm_testz_si128(live, live) == 0 {
                        let tz = depth_raw4(z);
                        let base = row + (gx - ctx.x0) as usize;
                        // SAFETY: the group lies in one row of the tile buffers (groups start
                        // at tile-aligned x and the stride is whole groups), so 4 elements
                        // from `base` are in every `stride * rows` buffer and plane.
                        unsafe {
                            let zptr = ctx.depth.add(base) as *mut __m128i;
                            let old = _mm_loadu_si128(zptr);
                            // Unsigned tz >= old.
                            let nearer = _mm_cmpeq_epi32(_mm_max_epu32(tz, old), tz);
                            let pass = _mm_and_si128(live, nearer);
                            let bits = _mm_movemask_ps(_mm_castsi128_ps(pass));
                            if bits != 0 {
                                let full = bits == 0b1111;
                                let pass_f = _mm_castsi128_ps(pass);
                                if full {
                                    _mm_storeu_si128(zptr, tz);
                                } else {
                                    _mm_storeu_si128(
                                        zptr,
                                        _mm_castps_si128(_mm_blendv_ps(
                                            _mm_castsi128_ps(old),
                                            _mm_castsi128_ps(tz),
                                            pass_f,
                                        )),
                                    );
                                }
                                if COUNT {
                                    let cptr = ctx.write_count.add(base) as *mut __m128i;
                                    _mm_storeu_si128(cptr, _mm_sub_epi32(_mm_loadu_si128(cptr), pass));
                                }
                                let qw = plane(qa, x, qby, qc);
                                for c in 0..T {
                                    if plane_base[c].is_null() {
                                        continue;
                                    }
                                    let mut v = plane(a_of[c], x, by_of[c], c_of[c]);
                                    if c < P {
                                        v = _mm_div_ps(v, qw);
                                    }
                                    let dst = plane_base[c].add(base);
                                    if !full {
                                        v = _mm_blendv_ps(_mm_loadu_ps(dst), v, pass_f);
                                    }
                                    _mm_storeu_ps(dst, v);
                                }
                            }
                        }
                    }
                    gx += 4;
                    x = _mm_add_ps(x, _mm_set1_ps(4.0));
                    if !edges_known && s.exact {
                        // Exact modulo 2^32, as the prim's wrapping products are.
                        for (e, step) in edge.iter_mut().zip(&edge_step) {
                            *e = _mm_add_epi32(*e, *step);
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
