//! polygon written by hand in Rust: `prims/polygon.prim`'s homogeneous hither clip and fan,
//! calling a hand-written screen_triangle kernel (scalar, SSE4.1 or AVX2) for each fan
//! triangle, as the JIT's polygon kernel calls the JIT's screen_triangle.
//!
//! Operation for operation the same as the prim (the same divisions, the clip parameter
//! `t = d_current / (d_current - d_next)`, `v + t * (w - v)` for positions and
//! `(1 - t) * a + t * b` for interpolation data, the same emission order), and the argument
//! block handed to screen_triangle is the one the JIT's call builds (`abi::ArgLayout` of
//! screen_triangle under the same key), so the triangles and hence the buffers are the same
//! bit for bit.
//!
//! Argument block of a polygon instance with `n` sequence points and `T` interpolation
//! components (all bindings `Kind`, as `Handwritten` checks): word 0 n; the plane table
//! (`T` words); then, from `fixed = 1 + T`, `vertex` (4 words per point) and
//! `interp_data` (`T` words per point) at `fixed + max(n, 1) * seq_offset`.
//!
//! Each fan triangle goes through `abi::call_primitive`, as the JIT's call does: run in bound
//! and render mode, recorded for the runtime in `MODE_EXPAND` (so an expanded polygon yields
//! the same triangle instances from either kernel).
//!
//! The variant key's `trivial_accept` makes the prim's `clipping()` false (only the plain
//! fan is compiled); the kernels take it as the const generic `CLIP` (= `clipping()`).

use crate::abi::{call_primitive, KernelFn, TileCtx};

/// Most interpolation components a hand-written polygon handles (the size of the argument
/// block it builds for screen_triangle on its stack).
pub const MAX_COMPONENTS: usize = 32;

/// Words of screen_triangle's argument block for `MAX_COMPONENTS` components: n_seq, plane
/// table, screen_vertex[3][4], interp_data[3].
const TRIANGLE_WORDS: usize = 1 + MAX_COMPONENTS + 12 + 3 * MAX_COMPONENTS;

/// The polygon kernel for `T` components whose fan triangles are drawn by `TRIANGLE`'s
/// hand-written screen_triangle (picked by the caller for the same key).
///
/// # Safety
/// Called by the runtime with a valid `ctx` and the argument block of a polygon instance
/// under a key of `T <= MAX_COMPONENTS` Kind components; `triangle` must be a
/// screen_triangle kernel for the same key.
pub(crate) unsafe fn polygon(ctx: *mut TileCtx, args: *const u32, t: usize, clipping: bool, triangle: KernelFn) {
    // SAFETY (all reads below): the block holds word 0, the plane table and, for
    // max(n, 1) sequence points, 4 + t words each; every index read is below n.
    let word = |i: usize| unsafe { *args.add(i) };
    let n = word(0) as i32;
    if n < 3 || t > MAX_COMPONENTS {
        return;
    }
    let n = n as usize;
    let fixed = 1 + t;
    let vertex = |i: usize| -> [f32; 4] { std::array::from_fn(|k| f32::from_bits(word(fixed + 4 * i + k))) };
    let data_at = fixed + 4 * n;
    let interp = |i: usize, c: usize| f32::from_bits(word(data_at + t * i + c));

    let mut fan = Fan {
        block: [0; TRIANGLE_WORDS],
        t,
        count: 0,
        ctx,
        triangle,
    };
    // n_seq of the call (screen_triangle has no per-sequence-point parameter) and the
    // plane table, which the JIT copies from the caller's block (same key, same prefix).
    fan.block[0] = 1;
    for w in 1..fixed {
        fan.block[w] = word(w);
    }
    let mut data = [0f32; MAX_COMPONENTS];

    if !clipping {
        for i in 0..n {
            let v = vertex(i);
            for (c, d) in data[..t].iter_mut().enumerate() {
                *d = interp(i, c);
            }
            // SAFETY: as this function's contract.
            unsafe { fan.push([v[0] / v[3], v[1] / v[3], v[2] / v[3], v[3]], &data) };
        }
        return;
    }

    for current in 0..n {
        let next = (current + 1) % n;
        let (vc, vn) = (vertex(current), vertex(next));
        // Signed distance inside the hither plane, in homogeneous units.
        let d_current = vc[3] - vc[2];
        let d_next = vn[3] - vn[2];
        for k in 0..2 {
            let mut emit = false;
            let mut h = [0f32; 4];
            if k == 0 && d_current >= 0.0 {
                emit = true;
                h = vc;
                for (c, d) in data[..t].iter_mut().enumerate() {
                    *d = interp(current, c);
                }
            }
            if k == 1 && (d_current >= 0.0) != (d_next >= 0.0) {
                let tc = d_current / (d_current - d_next);
                emit = true;
                h = std::array::from_fn(|m| vc[m] + tc * (vn[m] - vc[m]));
                for (c, d) in data[..t].iter_mut().enumerate() {
                    *d = (1.0 - tc) * interp(current, c) + tc * interp(next, c);
                }
            }
            if emit && h[3] > 0.0 {
                // SAFETY: as this function's contract.
                unsafe { fan.push([h[0] / h[3], h[1] / h[3], h[2] / h[3], h[3]], &data) };
            }
        }
    }
}

/// The fan being built: the prim's `screen_vertex` / `screen_data` live directly in the
/// argument block of the next screen_triangle call.
struct Fan {
    block: [u32; TRIANGLE_WORDS],
    t: usize,
    /// Vertices emitted so far (the prim's `screen_vertex_count`, not capped).
    count: usize,
    ctx: *mut TileCtx,
    triangle: KernelFn,
}

impl Fan {
    fn set(&mut self, slot: usize, s: [f32; 4], data: &[f32; MAX_COMPONENTS]) {
        let sv_at = 1 + self.t;
        let data_at = sv_at + 12;
        for (k, v) in s.iter().enumerate() {
            self.block[sv_at + 4 * slot + k] = v.to_bits();
        }
        for c in 0..self.t {
            self.block[data_at + self.t * slot + c] = data[c].to_bits();
        }
    }

    /// The prim's emission: the first two vertices fill slots 0 and 1; each later one is
    /// slot 2, draws the triangle, and becomes slot 1.
    ///
    /// # Safety
    /// `ctx` and `triangle` as [`polygon`]'s contract.
    unsafe fn push(&mut self, s: [f32; 4], data: &[f32; MAX_COMPONENTS]) {
        if self.count < 2 {
            self.set(self.count, s, data);
            self.count += 1;
            return;
        }
        self.set(2, s, data);
        let words = 1 + self.t + 12 + 3 * self.t;
        // SAFETY: the block's first `words` words are screen_triangle's argument block for
        // this key (n_seq, the caller's plane table, screen_vertex, interp_data), and the
        // caller vouches for `ctx` and `triangle`. In MODE_EXPAND the call is recorded, as
        // the JIT's polygon records it.
        unsafe { call_primitive(self.ctx, self.triangle, &self.block[..words]) };
        self.set(1, s, data);
    }
}

/// The exported kernel: [`polygon`] for the key's shape, fanning into the hand-written
/// screen_triangle of form `ISA` (a `handwritten::isa` constant) for the same key; `CLIP`
/// is the prim's `clipping()`.
///
/// # Safety
/// As [`polygon`].
pub unsafe extern "C" fn kernel<
    const P: usize,
    const L: usize,
    const T: usize,
    const COUNT: bool,
    const ISA: u8,
    const CLIP: bool,
>(
    ctx: *mut TileCtx,
    args: *const u32,
) {
    let triangle = super::screen_triangle_kernel::<P, L, T>(COUNT, ISA);
    // SAFETY: as this function's contract; `triangle` is screen_triangle for the same key.
    unsafe { polygon(ctx, args, T, CLIP, triangle) }
}
