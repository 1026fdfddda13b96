//! View clip codes, trivial accept / reject, and homogeneous polygon clipping.
//!
//! # Clip space (the convention every function here assumes)
//! A clip-space vertex is `(x, y, z, w)` = `clip_from_world * p_world`. The view volume is
//!
//! ```text
//! -w <= x <= w,   -w <= y <= w,   0 <= z <= w,   w > 0          (single pyramid)
//! ```
//!
//! with `z = w` on the near plane and `z = 0` on the far plane, so after the divide
//! `z / w` is 1 at the near plane and 0 at the far plane (larger = nearer, like the depth
//! buffer). Clip `y` points up; the device transform flips it (see
//! [`crate::pipeline::transform`]). In the *double pyramid* (seed 000, 9.6) the volume also
//! contains the mirror image with `w < 0`: `-|w| <= x, y <= |w|` and `0 <= z / w <= 1`.
//!
//! # Clip codes (seed 000, 4.2.4 and the appendix)
//! Seven bits, laid out as in the appendix: bit 0 is the W bit, bits 1-6 the planes.
//! Single pyramid: `CLIP_W` is `w <= 0` (the `w > 0` half-space, which the six planes alone
//! do not enforce at `w = 0`), `CLIP_X_POS` is `x > w`, `CLIP_X_NEG` is `x < -w`, likewise
//! for y, `CLIP_Z_NEAR` is `z > w`, `CLIP_Z_FAR` is `z < 0`. Every bit is the outside of a
//! *linear* half-space of 4D clip space, which is what makes the AND test sound for the
//! homogeneous convex hull of a primitive (the appendix's `|x| > w` form is not a half-space
//! when `w < 0`; ours agrees with it whenever `w > 0`).
//! Double pyramid: `CLIP_W` is the sign bit of `w`; `x` is compared with `|w|` exactly as in
//! the appendix, and `z` through `z' = 2z - w` (which maps `0 <= z/w <= 1` to
//! `|z'| <= |w|` for either sign of `w`): bit 5 is `z' > |w|`, bit 6 is `z' < -|w|` (for
//! `w > 0` these are near and far; for `w < 0` they swap — the bits name raw-coordinate
//! sides, as the appendix's x bits do). `x > |w|` and `x < -|w|` are intersections of two
//! half-spaces, so still convex.
//!
//! Non-finite input: a vertex with any NaN or infinite component gets *every* bit
//! (`CLIP_ALL`). It is outside everything, so a primitive made only of such vertices is
//! trivially rejected, one mixing them with finite vertices is sent to the clipper, and
//! the clipper refuses it ([`ClipError::NonFinite`]). A trivially accepted primitive
//! therefore never contains a NaN or an infinity. The double-pyramid code also gives
//! `CLIP_ALL` to the zero vector `(0,0,0,0)`, which is no point at all. `-0.0` compares equal
//! to `+0.0` everywhere (so `z = -0.0` is not beyond the far plane), except that in the
//! double pyramid the W bit is the raw sign bit, as in the appendix.
//!
//! [`clip_code_f32`] / [`clip_code_f64`] are branch-free: they work on the IEEE bit patterns
//! as integers (sign-magnitude to two's complement, then the sign of a difference), as the
//! appendix does; [`clip_code_reference`] is the same specification written with `if`s, and
//! the tests check that the two agree on millions of vertices.
//!
//! # Accumulation (seed 002)
//! [`ClipAccumulator`] ANDs and ORs the codes of a primitive's vertices: AND of the plane bits
//! non-zero = trivially rejected (every vertex outside one same plane), OR zero = trivially
//! accepted, otherwise the OR names the planes the primitive crosses and only those are
//! clipped against. For the double pyramid the appendix's two OR flags are kept (accept
//! when all vertices are inside and of one sign of `w`); the W bit is left out of the AND,
//! since an all-negative-w primitive is visible in the back pyramid (the appendix's
//! listing ANDs it too, which would reject exactly those).
//!
//! # Clipping
//! [`clip_polygon`] is Sutherland-Hodgman in homogeneous clip space against only the planes
//! it is given (the OR code) plus model clip planes (`a*x + b*y + c*z + d*w >= 0` kept, in
//! the polygon's space; seed 000, 4.2.11). Before the view planes it clips against
//! `w = w_epsilon` (whenever the OR has the W bit or some vertex has `w < w_epsilon`), so
//! *every output vertex has `w >= w_epsilon > 0`*: nothing downstream divides by `w <= 0`.
//! Per-vertex attributes (any number of floats) are interpolated linearly in clip space,
//! which is perspective-correct. A new vertex is interpolated from the edge's endpoint nearer
//! the plane (smaller |distance|; ties to the lexicographically smaller position bits), so
//! its rounding is relative to that endpoint's distance from the plane, not to the edge's
//! length (a far endpoint 1e20 away would move it by 2^-53 of 1e20), and an edge shared by
//! two polygons yields bit-identical new vertices whichever polygon clips it and in which
//! direction (the choice depends on the two endpoints only).
//! A new vertex on a view plane is snapped exactly onto it (`x = w` etc.), so it is inside
//! by its own code. Positions whose magnitude nears overflow are first scaled by a common
//! power of two (the projective points, the projection and the attributes do not change).
//! In the double pyramid the polygon is clipped twice, once as given and once negated (the
//! same projective points, with `w > 0`), giving up to two pieces.

use super::real::Real;

/// Bit 0: single pyramid, `w <= 0`; double pyramid, the sign bit of `w`.
pub const CLIP_W: u32 = 1 << 0;
/// `x > w` (double pyramid: `x > |w|`).
pub const CLIP_X_POS: u32 = 1 << 1;
/// `x < -w` (double pyramid: `x < -|w|`).
pub const CLIP_X_NEG: u32 = 1 << 2;
/// `y > w` (double pyramid: `y > |w|`).
pub const CLIP_Y_POS: u32 = 1 << 3;
/// `y < -w` (double pyramid: `y < -|w|`).
pub const CLIP_Y_NEG: u32 = 1 << 4;
/// In front of the near plane: `z > w` (double pyramid: `2z - w > |w|`).
pub const CLIP_Z_NEAR: u32 = 1 << 5;
/// Beyond the far plane: `z < 0` (double pyramid: `2z - w < -|w|`).
pub const CLIP_Z_FAR: u32 = 1 << 6;
/// The six plane bits.
pub const CLIP_PLANES: u32 = 0x7e;
/// Every bit: what a non-finite vertex gets.
pub const CLIP_ALL: u32 = 0x7f;

/// Which view volume the clip codes and the clipper use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PyramidMode {
    /// Only `w > 0` is visible (the well-behaved case, seed 000 4.2.2 item 4).
    Single,
    /// Both `w > 0` and its mirror `w < 0` are visible (seed 000 9.6, seed 001 4.3).
    Double,
}

// ---------------------------------------------------------------------------------------
// Branch-free clip codes.
//
// An IEEE float is sign-magnitude; `key` turns its bits into a two's-complement integer with
// the same order (and +0 == -0): `mag` if positive, `-mag` if negative, computed as
// `(mag ^ m) - m` with `m` the sign smeared over the word. `a > b` is then the sign bit of
// `key(b) - key(a)`, computed in a wider integer so the difference cannot overflow.
// ---------------------------------------------------------------------------------------

macro_rules! branch_free_code {
    ($name:ident, $f:ty, $u:ty, $i:ty, $wide:ty, $sign:expr, $inf:expr) => {
        /// The branch-free clip code of one clip-space vertex (see the module doc for the
        /// bits). Agrees with [`clip_code_reference`] on every input.
        #[inline]
        pub fn $name(v: [$f; 4], mode: PyramidMode) -> u32 {
            const MAG: $u = !$sign;
            const INF: $wide = $inf;
            const SHIFT: u32 = <$wide>::BITS - 1;
            #[inline(always)]
            fn key(b: $u) -> $wide {
                let m = ((b as $i) >> (<$i>::BITS - 1)) as $wide;
                (((b & MAG) as $wide) ^ m) - m
            }
            // 1 if a > b (keys), else 0.
            #[inline(always)]
            fn gt(a: $wide, b: $wide) -> u32 {
                ((b - a) >> SHIFT) as u32 & 1
            }
            // 1 if the magnitude is NaN or infinite.
            #[inline(always)]
            fn non_finite(b: $u) -> u32 {
                (((INF - 1) - (b & MAG) as $wide) >> SHIFT) as u32 & 1
            }
            let bx = v[0].to_bits();
            let by = v[1].to_bits();
            let bz = v[2].to_bits();
            let bw = v[3].to_bits();
            let bad = non_finite(bx) | non_finite(by) | non_finite(bz) | non_finite(bw);
            let code = match mode {
                PyramidMode::Single => {
                    let (kx, ky, kz, kw) = (key(bx), key(by), key(bz), key(bw));
                    (1 - gt(kw, 0))
                        | gt(kx, kw) << 1
                        | gt(-kw, kx) << 2
                        | gt(ky, kw) << 3
                        | gt(-kw, ky) << 4
                        | gt(kz, kw) << 5
                        | gt(0, kz) << 6
                }
                PyramidMode::Double => {
                    // z' = 2z - w maps 0 <= z/w <= 1 onto |z'| <= |w| for either sign of w.
                    let bzc = (v[2] + v[2] - v[3]).to_bits();
                    let aw = (bw & MAG) as $wide;
                    let (kx, ky, kzc) = (key(bx), key(by), key(bzc));
                    let zero = ((((bx | by | bz | bw) & MAG) as $wide - 1) >> SHIFT) as u32 & 1;
                    ((bw >> (<$u>::BITS - 1)) as u32)
                        | gt(kx, aw) << 1
                        | gt(-aw, kx) << 2
                        | gt(ky, aw) << 3
                        | gt(-aw, ky) << 4
                        | gt(kzc, aw) << 5
                        | gt(-aw, kzc) << 6
                        | zero.wrapping_neg() & CLIP_ALL
                }
            };
            code | (bad.wrapping_neg() & CLIP_ALL)
        }
    };
}

branch_free_code!(clip_code_f32, f32, u32, i32, i64, 0x8000_0000u32, 0x7f80_0000i64);
branch_free_code!(
    clip_code_f64,
    f64,
    u64,
    i64,
    i128,
    0x8000_0000_0000_0000u64,
    0x7ff0_0000_0000_0000i128
);

/// A [`Real`] with branch-free clip codes in its own precision: what [`classify`] and
/// [`clip_polygon_to_view`] compute the codes with.
pub trait ClipCode: Real {
    /// The branch-free clip code of a clip-space vertex ([`clip_code_f32`],
    /// [`clip_code_f64`]).
    fn clip_code(v: [Self; 4], mode: PyramidMode) -> u32;
}

impl ClipCode for f32 {
    #[inline]
    fn clip_code(v: [f32; 4], mode: PyramidMode) -> u32 {
        clip_code_f32(v, mode)
    }
}

impl ClipCode for f64 {
    #[inline]
    fn clip_code(v: [f64; 4], mode: PyramidMode) -> u32 {
        clip_code_f64(v, mode)
    }
}

/// The clip code written the obvious way, with comparisons and branches: the specification
/// [`clip_code_f32`] and [`clip_code_f64`] are tested against.
pub fn clip_code_reference<T: Real>(v: [T; 4], mode: PyramidMode) -> u32 {
    let [x, y, z, w] = v;
    if !(x.is_finite() && y.is_finite() && z.is_finite() && w.is_finite()) {
        return CLIP_ALL;
    }
    let mut code = 0;
    match mode {
        PyramidMode::Single => {
            if w <= T::ZERO {
                code |= CLIP_W;
            }
            if x > w {
                code |= CLIP_X_POS;
            }
            if x < -w {
                code |= CLIP_X_NEG;
            }
            if y > w {
                code |= CLIP_Y_POS;
            }
            if y < -w {
                code |= CLIP_Y_NEG;
            }
            if z > w {
                code |= CLIP_Z_NEAR;
            }
            if z < T::ZERO {
                code |= CLIP_Z_FAR;
            }
        }
        PyramidMode::Double => {
            if x == T::ZERO && y == T::ZERO && z == T::ZERO && w == T::ZERO {
                return CLIP_ALL;
            }
            // The raw sign bit, as the appendix: -0.0 counts as negative.
            if w.to_f64().is_sign_negative() {
                code |= CLIP_W;
            }
            let aw = w.abs();
            let zc = z + z - w;
            if x > aw {
                code |= CLIP_X_POS;
            }
            if x < -aw {
                code |= CLIP_X_NEG;
            }
            if y > aw {
                code |= CLIP_Y_POS;
            }
            if y < -aw {
                code |= CLIP_Y_NEG;
            }
            if zc > aw {
                code |= CLIP_Z_NEAR;
            }
            if zc < -aw {
                code |= CLIP_Z_FAR;
            }
        }
    }
    code
}

/// What the clip codes of a whole primitive say.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClipVerdict {
    /// Every vertex is outside one same plane: draw nothing.
    Reject,
    /// Every vertex is inside (and, double pyramid, of one sign of w): draw unclipped.
    Accept,
    /// Clip against the planes in this OR code (it may include `CLIP_W`).
    Clip(u32),
}

/// AND / OR accumulation of the clip codes of one primitive's vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClipAccumulator {
    and: u32,
    or_pos: u32,
    or_neg: u32,
    count: u32,
}

impl Default for ClipAccumulator {
    fn default() -> Self {
        ClipAccumulator::new()
    }
}

impl ClipAccumulator {
    pub fn new() -> ClipAccumulator {
        ClipAccumulator {
            and: CLIP_ALL,
            or_pos: 0,
            or_neg: 0,
            count: 0,
        }
    }
    #[inline]
    pub fn add(&mut self, code: u32) {
        self.and &= code;
        self.or_pos |= code;
        // The double pyramid's second OR: a vertex counts as "outside" the back pyramid
        // when its W bit is clear.
        self.or_neg |= code ^ CLIP_W;
        self.count += 1;
    }
    /// The OR of all codes added so far.
    pub fn or(&self) -> u32 {
        self.or_pos
    }
    /// The AND of all codes added so far (`CLIP_ALL` for none).
    pub fn and(&self) -> u32 {
        self.and
    }
    /// Reject / accept / clip. A primitive with no vertices is rejected.
    pub fn verdict(&self, mode: PyramidMode) -> ClipVerdict {
        if self.count == 0 {
            return ClipVerdict::Reject;
        }
        match mode {
            PyramidMode::Single => {
                if self.and != 0 {
                    ClipVerdict::Reject
                } else if self.or_pos == 0 {
                    ClipVerdict::Accept
                } else {
                    ClipVerdict::Clip(self.or_pos)
                }
            }
            PyramidMode::Double => {
                if self.and & CLIP_PLANES != 0 {
                    ClipVerdict::Reject
                } else if self.or_pos == 0 || self.or_neg == 0 {
                    ClipVerdict::Accept
                } else {
                    ClipVerdict::Clip(self.or_pos)
                }
            }
        }
    }
}

/// The clip codes of `vertices` accumulated (branch-free codes of `T`'s precision).
pub fn classify<T: ClipCode>(vertices: impl IntoIterator<Item = [T; 4]>, mode: PyramidMode) -> ClipVerdict {
    let mut acc = ClipAccumulator::new();
    for v in vertices {
        acc.add(T::clip_code(v, mode));
    }
    acc.verdict(mode)
}

// ---------------------------------------------------------------------------------------
// Polygons and the clipper.
// ---------------------------------------------------------------------------------------

/// A polygon in homogeneous coordinates with `n_attrs` float attributes per vertex, stored
/// flat: `x y z w a0 .. a(n-1)` per vertex.
#[derive(Clone, Debug, PartialEq)]
pub struct ClipPolygon<T> {
    n_attrs: usize,
    data: Vec<T>,
}

/// Why a polygon could not be built or clipped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClipError {
    /// A vertex was given a different number of attributes than the polygon carries.
    AttributeCount { expected: usize, got: usize },
    /// A vertex position has a NaN or infinite component: the polygon is dropped.
    NonFinite,
}

impl std::fmt::Display for ClipError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ClipError::AttributeCount { expected, got } => {
                write!(f, "vertex has {got} attributes, the polygon carries {expected}")
            }
            ClipError::NonFinite => write!(f, "vertex position is NaN or infinite; primitive dropped"),
        }
    }
}

impl std::error::Error for ClipError {}

impl<T: Real> ClipPolygon<T> {
    pub fn new(n_attrs: usize) -> ClipPolygon<T> {
        ClipPolygon { n_attrs, data: vec![] }
    }
    /// A polygon from positions only.
    pub fn from_positions(positions: &[[T; 4]]) -> ClipPolygon<T> {
        let mut p = ClipPolygon::new(0);
        for &v in positions {
            p.data.extend_from_slice(&v);
        }
        p
    }
    /// Appends a vertex; `attrs` must have `n_attrs` entries.
    pub fn push(&mut self, position: [T; 4], attrs: &[T]) -> Result<(), ClipError> {
        if attrs.len() != self.n_attrs {
            return Err(ClipError::AttributeCount {
                expected: self.n_attrs,
                got: attrs.len(),
            });
        }
        self.data.extend_from_slice(&position);
        self.data.extend_from_slice(attrs);
        Ok(())
    }
    pub fn n_attrs(&self) -> usize {
        self.n_attrs
    }
    fn stride(&self) -> usize {
        4 + self.n_attrs
    }
    pub fn len(&self) -> usize {
        self.data.len() / self.stride()
    }
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
    /// Vertex `i`'s position and attributes (`x y z w a0 ..`).
    pub fn vertex(&self, i: usize) -> &[T] {
        &self.data[i * self.stride()..(i + 1) * self.stride()]
    }
    pub fn position(&self, i: usize) -> [T; 4] {
        let v = self.vertex(i);
        [v[0], v[1], v[2], v[3]]
    }
    pub fn attrs(&self, i: usize) -> &[T] {
        &self.vertex(i)[4..]
    }
    pub fn positions(&self) -> impl Iterator<Item = [T; 4]> + '_ {
        (0..self.len()).map(|i| self.position(i))
    }
    /// The same projective points with every position negated (attributes unchanged).
    pub fn negated(&self) -> ClipPolygon<T> {
        let mut out = self.clone();
        let stride = self.stride();
        for v in out.data.chunks_mut(stride) {
            for c in &mut v[..4] {
                *c = -*c;
            }
        }
        out
    }
}

/// Magnitude (2^900) above which the clipper rescales positions so that plane distances
/// such as `w - x` cannot overflow f64.
const RESCALE_ABOVE: f64 = 8.452712498170644e270;

/// Options of the clipper.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClipOptions {
    /// The `w = w_epsilon` plane every output vertex is on or beyond. Any positive normal
    /// number works: after clipping `|x|, |y|, z <= w`, so the divide stays bounded.
    pub w_epsilon: f64,
}

/// The default `w` floor: tiny, yet a normal number in f32 as well as f64.
pub const DEFAULT_W_EPSILON: f64 = 1e-20;

impl Default for ClipOptions {
    fn default() -> Self {
        ClipOptions {
            w_epsilon: DEFAULT_W_EPSILON,
        }
    }
}

/// One plane the clipper cuts with; the kept side is `distance >= 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Plane<T> {
    /// `w - eps >= 0`.
    W(T),
    /// A view plane, by its clip-code bit.
    View(u32),
    /// `a x + b y + c z + d w >= 0`.
    General([T; 4]),
}

impl<T: Real> Plane<T> {
    /// The signed distance. For view planes it is the exact difference the clip codes
    /// compare (`w - x` etc.), so "inside" here agrees with the code bit being clear.
    #[inline]
    fn distance(&self, v: &[T]) -> T {
        let (x, y, z, w) = (v[0], v[1], v[2], v[3]);
        match *self {
            Plane::W(eps) => w - eps,
            Plane::View(CLIP_X_POS) => w - x,
            Plane::View(CLIP_X_NEG) => w + x,
            Plane::View(CLIP_Y_POS) => w - y,
            Plane::View(CLIP_Y_NEG) => w + y,
            Plane::View(CLIP_Z_NEAR) => w - z,
            Plane::View(_) => z,
            Plane::General([a, b, c, d]) => a * x + b * y + c * z + d * w,
        }
    }
    /// Puts a new vertex exactly on a view plane (and keeps `w >= eps`).
    #[inline]
    fn snap(&self, v: &mut [T], eps: T) {
        if v[3] < eps {
            v[3] = eps;
        }
        let w = v[3];
        match *self {
            Plane::View(CLIP_X_POS) => v[0] = w,
            Plane::View(CLIP_X_NEG) => v[0] = -w,
            Plane::View(CLIP_Y_POS) => v[1] = w,
            Plane::View(CLIP_Y_NEG) => v[1] = -w,
            Plane::View(CLIP_Z_NEAR) => v[2] = w,
            Plane::View(CLIP_Z_FAR) => v[2] = T::ZERO,
            _ => {}
        }
    }
}

/// Lexicographic order of two positions on their bit patterns: the canonical endpoint order.
fn position_less<T: Real>(a: &[T], b: &[T]) -> bool {
    for i in 0..4 {
        match a[i].total_cmp(&b[i]) {
            std::cmp::Ordering::Less => return true,
            std::cmp::Ordering::Greater => return false,
            std::cmp::Ordering::Equal => {}
        }
    }
    false
}

/// One Sutherland-Hodgman pass: keeps the part of `input` with `plane.distance >= 0`.
fn clip_against<T: Real>(input: &[T], stride: usize, plane: Plane<T>, eps: T, out: &mut Vec<T>) {
    out.clear();
    let n = input.len() / stride;
    if n == 0 {
        return;
    }
    let mut prev = &input[(n - 1) * stride..n * stride];
    let mut d_prev = plane.distance(prev);
    for i in 0..n {
        let cur = &input[i * stride..(i + 1) * stride];
        let d_cur = plane.distance(cur);
        let prev_in = d_prev >= T::ZERO;
        let cur_in = d_cur >= T::ZERO;
        if prev_in != cur_in {
            // The parameter is measured from the endpoint nearer the plane (smaller |d|):
            // `a + t (b - a)` then moves `a` by about its own small distance, so the
            // rounding is relative to that and not to the edge's length (from a far
            // endpoint 1e20 away, 2^-53 of the length is 1e4 units of drift). Ties go to the
            // bit-order-smaller endpoint. The choice depends only on the two endpoints, so
            // both polygons sharing this edge compute the same bits whichever way they run it.
            let prev_first = match d_prev.abs().total_cmp(&d_cur.abs()) {
                std::cmp::Ordering::Less => true,
                std::cmp::Ordering::Greater => false,
                std::cmp::Ordering::Equal => position_less(prev, cur),
            };
            let (a, b, da, db) = if prev_first {
                (prev, cur, d_prev, d_cur)
            } else {
                (cur, prev, d_cur, d_prev)
            };
            // da and db have opposite signs (one >= 0, one < 0): da - db != 0 and t in [0, 1].
            let t = da / (da - db);
            let start = out.len();
            for k in 0..stride {
                out.push(a[k] + t * (b[k] - a[k]));
            }
            plane.snap(&mut out[start..start + 4], eps);
        }
        if cur_in {
            out.extend_from_slice(cur);
        }
        prev = cur;
        d_prev = d_cur;
    }
}

/// Clips the `w > 0` part of `poly` against `w = eps`, the view planes in `crossed`, and
/// `model_planes`. Returns the (possibly empty) result.
fn clip_single<T: Real>(poly: &ClipPolygon<T>, crossed: u32, model_planes: &[[T; 4]], eps: T) -> ClipPolygon<T> {
    let stride = poly.stride();
    let mut cur = poly.data.clone();
    let mut next = Vec::with_capacity(cur.len() * 2);
    let needs_w = crossed & CLIP_W != 0 || poly.positions().any(|p| p[3] < eps);
    let mut planes: Vec<Plane<T>> = vec![];
    if needs_w {
        planes.push(Plane::W(eps));
    }
    for bit in [CLIP_X_POS, CLIP_X_NEG, CLIP_Y_POS, CLIP_Y_NEG, CLIP_Z_NEAR, CLIP_Z_FAR] {
        if crossed & bit != 0 {
            planes.push(Plane::View(bit));
        }
    }
    planes.extend(model_planes.iter().map(|&p| Plane::General(p)));
    for plane in planes {
        clip_against(&cur, stride, plane, eps, &mut next);
        std::mem::swap(&mut cur, &mut next);
        if cur.len() / stride < 3 {
            cur.clear();
            break;
        }
    }
    ClipPolygon {
        n_attrs: poly.n_attrs,
        data: cur,
    }
}

/// Clips a homogeneous polygon (clip space, or any space for model planes only).
///
/// `crossed` is the OR of the vertices' clip codes (only those planes are clipped against;
/// pass `CLIP_ALL` to clip against all; in the double pyramid each half works out its own
/// planes from single-pyramid codes and `crossed` is not used); `model_planes` are extra planes
/// `a x + b y + c z + d w >= 0` in the polygon's space. Returns the pieces with at least
/// three vertices each: at most one for [`PyramidMode::Single`], at most two (the `w > 0`
/// piece, then the back-pyramid piece, negated so its `w > 0` too) for
/// [`PyramidMode::Double`]. Every output vertex has `w >= opts.w_epsilon`.
pub fn clip_polygon<T: Real>(
    poly: &ClipPolygon<T>,
    crossed: u32,
    model_planes: &[[T; 4]],
    mode: PyramidMode,
    opts: ClipOptions,
) -> Result<Vec<ClipPolygon<T>>, ClipError> {
    if poly.positions().any(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(ClipError::NonFinite);
    }
    if model_planes.iter().any(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(ClipError::NonFinite);
    }
    if poly.len() < 3 {
        return Ok(vec![]);
    }
    // Work in f64 whatever T is: widening is exact, and an f32 polygon with coordinates of
    // 30000 w would otherwise lose about 3e4 * 6e-8 of screen position in the intersection
    // parameter. Each result is rounded to T once; snapped equalities (x = w) survive the
    // rounding, and so does bit-identity of shared edges (rounding is deterministic).
    let wide = ClipPolygon {
        n_attrs: poly.n_attrs,
        data: poly.data.iter().map(|c| c.to_f64()).collect(),
    };
    let wide_planes: Vec<[f64; 4]> = model_planes.iter().map(|p| p.map(|c| c.to_f64())).collect();
    let pieces = clip_polygon_f64(&wide, crossed, &wide_planes, mode, opts);
    Ok(pieces
        .into_iter()
        .map(|piece| ClipPolygon {
            n_attrs: piece.n_attrs,
            data: piece.data.into_iter().map(T::from_f64).collect(),
        })
        .collect())
}

fn clip_polygon_f64(
    poly: &ClipPolygon<f64>,
    crossed: u32,
    model_planes: &[[f64; 4]],
    mode: PyramidMode,
    opts: ClipOptions,
) -> Vec<ClipPolygon<f64>> {
    let poly = rescaled(poly);
    let eps = opts.w_epsilon;
    let mut pieces = vec![];
    match mode {
        PyramidMode::Single => {
            let front = clip_single(&poly, crossed, model_planes, eps);
            if !front.is_empty() {
                pieces.push(front);
            }
        }
        PyramidMode::Double => {
            // The double-pyramid bits compare with |w| and are not half-spaces of either
            // half, so each half is clipped against the single-pyramid planes its own
            // vertices cross (a new vertex on w = eps is near infinity and usually outside).
            let back = poly.negated();
            for half in [&*poly, &back] {
                let crossed_half = half
                    .positions()
                    .fold(0, |acc, p| acc | clip_code_f64(p, PyramidMode::Single));
                let piece = clip_single(half, crossed_half, model_planes, eps);
                if !piece.is_empty() {
                    pieces.push(piece);
                }
            }
        }
    }
    pieces
}

/// `poly`, with its positions scaled by a power of two if their largest magnitude is so
/// large that plane distances (`w - x`) could overflow.
fn rescaled(poly: &ClipPolygon<f64>) -> std::borrow::Cow<'_, ClipPolygon<f64>> {
    let largest = poly
        .positions()
        .flat_map(|p| p.into_iter())
        .map(|c| c.to_f64().abs())
        .fold(0.0f64, f64::max);
    if largest <= RESCALE_ABOVE {
        return std::borrow::Cow::Borrowed(poly);
    }
    // A power of two is exact: the projective points only change by a common factor.
    let scale = 2f64.powi(-(largest.log2().ceil() as i32));
    let mut out = poly.clone();
    let stride = poly.stride();
    for v in out.data.chunks_mut(stride) {
        for c in &mut v[..4] {
            *c *= scale;
        }
    }
    std::borrow::Cow::Owned(out)
}

/// Classifies the polygon with the branch-free codes and clips only if needed: the usual
/// entry point. Rejected polygons give no pieces, accepted ones come back unchanged.
pub fn clip_polygon_to_view<T: ClipCode>(
    poly: &ClipPolygon<T>,
    model_planes: &[[T; 4]],
    mode: PyramidMode,
    opts: ClipOptions,
) -> Result<Vec<ClipPolygon<T>>, ClipError> {
    match classify(poly.positions(), mode) {
        ClipVerdict::Reject => {
            if poly.positions().any(|p| p.iter().any(|c| !c.is_finite())) {
                Err(ClipError::NonFinite)
            } else {
                Ok(vec![])
            }
        }
        // An accepted back-pyramid primitive comes back negated, so pieces always have w > 0.
        ClipVerdict::Accept if model_planes.is_empty() => match poly.positions().next() {
            Some(p) if p[3] < T::ZERO => Ok(vec![poly.negated()]),
            _ => Ok(vec![poly.clone()]),
        },
        ClipVerdict::Accept => clip_polygon(poly, 0, model_planes, mode, opts),
        ClipVerdict::Clip(crossed) => clip_polygon(poly, crossed, model_planes, mode, opts),
    }
}

/// The model clip plane through `point` with `normal` pointing into the kept half-space
/// (seed 000 3.0 step 7): coefficients `(n, -n.p)`, so `m . (x, y, z, 1) >= 0` is kept.
pub fn plane_from_point_normal(point: glam::DVec3, normal: glam::DVec3) -> glam::DVec4 {
    normal.extend(-normal.dot(point))
}

/// A plane moved to another space (seed 000 4.2.11): if `q' = dest_from_src * q`, the plane
/// becomes `m * dest_from_src^-1`. `None` when the matrix is singular (9.1: the caller skips
/// model clipping with [`crate::pipeline::Warning::SingularView`]). The kept side is preserved
/// for points whose w keeps its sign, which holds in the single pyramid after the W plane.
pub fn transform_plane(plane: glam::DVec4, dest_from_src: &glam::DMat4) -> Option<glam::DVec4> {
    let inv = dest_from_src.try_inverse()?;
    // Row vector times matrix = transpose(matrix) times column vector.
    let out = inv.transpose().mul_vec4(plane);
    out.is_finite().then_some(out)
}
