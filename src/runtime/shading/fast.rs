//! The fast shading kernels: one fused pass per row of the G-buffer over vectors of
//! [`LANES`] contiguous pixels ([`super::lanes`]). Per vector: the position in f64 (the
//! device-to-lighting product, its row terms hoisted); the facing from a filtered f64 sign
//! test (the exact f64 path near grazing); normal and eye vector normalised in f32; every
//! light, fog and the final colour in f32 lanes; one interleaving store.
//!
//! The kernels are generic over the lanes' instruction set and built three times: AVX-512
//! and AVX2 (each inside a `#[target_feature]` function, chosen at run time by what the CPU
//! has) and portable loops. The three are bit-identical and agree with the f64 reference
//! within the bound stated in the parent module. The pass is latency-bound (one vector is a
//! chain of ~40 dependent operations through two divisions, two square roots and the
//! power), so 32 pixels per vector, two or four independent registers per value, run
//! faster than 8 or 16 (measured: 8 -> 32 lanes on AVX2 2.6 -> 1.8 ms, AVX-512 1.1 -> 0.9
//! ms for the bench's lit sphere frame).

use super::lanes::{lane_index, load, map3, xyz, F32s, F64s, Isa, Mask, Portable, LANES};
use super::lanes::{Avx2, Avx512};
use super::{Fog, LightingSpaceChoice, Shader, ShadingKernel};
use crate::pipeline::lighting::{Eye, LightKind, LightingSetup, Material};
use crate::pipeline::real::normalize3;
use glam::DVec3;

/// Largest shininess the fast kernels take. The power itself is good to 1e-5 up to 16384, but
/// R.V comes from f32 vectors (a few ulps, ~3e-7 relative) and `x^s` multiplies that relative
/// error by `s`: at 16384 a highlight's peak can be off by ~1e-3, over the 1/4096 bound, while
/// at 1024 it stays below ~3e-4 in theory (3.4e-5 measured at 1000). Larger, non-finite or
/// below 1 (where the highlight jumps at R.V = 0) runs the f64 reference instead.
const FAST_MAX_SHININESS: f64 = 1024.0;
/// Largest light colour, material coefficient or ambient component the fast kernels take.
const FAST_MAX_COEFFICIENT: f64 = 1.0e6;

/// One row of the G-buffer as the fast kernels read it: the frame's planes sliced to the row
/// (every slice exactly `depth.len()` long), so a chunk of pixels is one contiguous load per
/// plane. Unwritten pixels (depth 0) are shaded along with their chunk and masked out.
#[derive(Clone, Copy)]
pub struct RowInputs<'a> {
    pub y: u32,
    /// Raw depth (`fixed<32,32>`, larger nearer, 0 = nothing written).
    pub depth: &'a [u32],
    /// `Cs` as three planes (a gray `Cs` repeats its plane); `None`: white.
    pub cs: Option<[&'a [f32]; 3]>,
    /// The 3-component normal parameter, when the frame has one and is lit.
    pub normal: Option<[&'a [f32]; 3]>,
    /// The recorded facing (negative = back), when the frame records it and is lit.
    pub facing: Option<&'a [f32]>,
    /// The texture coordinates (first two components), when textured.
    pub st: Option<[&'a [f32]; 2]>,
}

/// One light's constants for the lane loop, per facing (index 0 front, 1 back).
#[derive(Clone, Copy)]
struct LaneLight {
    positional: bool,
    /// Directional: unit vector towards the light (zero when degenerate).
    towards: [f32; 3],
    position: [f64; 3],
    attenuation: [f64; 3],
    diffuse: [[f32; 3]; 2],
    specular: [[f32; 3]; 2],
}

/// The fast kernels' per-frame constants, derived once from the shader's setup.
pub(super) struct FastSetup {
    lights: Vec<LaneLight>,
    shininess: [f32; 2],
    /// Some material has a specular term (otherwise the highlight code is left out).
    with_specular: bool,
    /// Both sides share one small integer shininess n: the highlight is `x^n` by repeated
    /// squaring (exact to a few ulp) instead of the polynomial `2^(s log2 x)`; with the
    /// smallest base that keeps every step normal.
    integer_power: Option<(u32, f32)>,
    /// Ambient material times ambient light, per facing.
    ambient: [[f32; 3]; 2],
    /// The lighting eye: a point, or a unit direction.
    lit_eye_point: Option<[f64; 3]>,
    lit_eye_direction: Option<[f64; 3]>,
    /// The fog eye: a point, or a unit direction from the near point.
    fog_eye_point: Option<[f64; 3]>,
    fog_direction: Option<[f64; 3]>,
    fog_colour: [f32; 3],
}

/// The filtered facing test's margin on the cosine: a facing is decided from the f32
/// `t . d` when `|t . d| > FACING_MARGIN |t| |d|`. Its error against the reference's
/// (exact f64 normal, f64 eye offset) is below 2.5e-7 |t| |d|: the offset's rounding to f32
/// (2^-24 relative per component) and three products and two sums in f32 (3 * 2^-24 of
/// `sum |t_i d_i|`); the margin is 40 times that.
const FACING_MARGIN: f32 = 1.0e-5;

/// Largest integer shininess taken by repeated squaring: at most 2 log2(n) = 14 f32
/// multiplications, relative error below 1e-5 (tests/runtime/shading_fast_maths.rs sweeps
/// it).
#[doc(hidden)]
pub const MAX_INTEGER_SHININESS: u32 = 128;

impl FastSetup {
    pub(super) fn new(setup: &LightingSetup<f64>, eye: Eye<f64>, fog: Option<&Fog>) -> FastSetup {
        let materials = [&setup.front, &setup.back];
        let with_specular = materials.iter().any(|m| m.specular != [0.0; 3]);
        let lights = setup
            .lights
            .iter()
            .filter_map(|light| {
                let per_side = |f: fn(&Material<f64>) -> [f64; 3]| {
                    materials.map(|m| [0, 1, 2].map(|k| (f(m)[k] * light.colour[k]) as f32))
                };
                let mut lane_light = LaneLight {
                    positional: false,
                    towards: [0.0; 3],
                    position: [0.0; 3],
                    attenuation: [0.0; 3],
                    diffuse: per_side(|m| m.diffuse),
                    specular: per_side(|m| m.specular),
                };
                match light.kind {
                    LightKind::Directional { towards_light } => {
                        // A degenerate direction lights nothing (the reference skips it).
                        lane_light.towards = normalize3(towards_light)?.map(|c| c as f32);
                    }
                    LightKind::Positional { position, attenuation } => {
                        lane_light.positional = true;
                        lane_light.position = position;
                        lane_light.attenuation = attenuation;
                    }
                }
                Some(lane_light)
            })
            .collect();
        // The exponent only matters on sides with a specular term.
        let specular_shininess: Vec<f64> = materials
            .iter()
            .filter(|m| m.specular != [0.0; 3])
            .map(|m| m.shininess)
            .collect();
        let integer_power = match specular_shininess.as_slice() {
            [s, rest @ ..]
                if rest.iter().all(|r| r == s)
                    && s.fract() == 0.0
                    && *s >= 1.0
                    && *s <= f64::from(MAX_INTEGER_SHININESS) =>
            {
                Some((*s as u32, integer_power_floor(*s as u32)))
            }
            _ => None,
        };
        let (lit_eye_point, lit_eye_direction) = match setup.eye {
            Eye::Point(e) => (Some(e), None),
            Eye::Direction(d) => (None, normalize3(d)),
        };
        let (fog_eye_point, fog_direction) = match eye {
            Eye::Point(e) => (Some(e), None),
            Eye::Direction(d) => (
                None,
                normalize3(d).map(|d| DVec3::from_array(d).normalize_or_zero().to_array()),
            ),
        };
        FastSetup {
            lights,
            shininess: materials.map(|m| m.shininess as f32),
            with_specular,
            integer_power,
            ambient: materials.map(|m| [0, 1, 2].map(|k| (m.ambient[k] * setup.ambient_light[k]) as f32)),
            lit_eye_point,
            lit_eye_direction,
            fog_eye_point,
            fog_direction,
            fog_colour: fog.map(|f| f.colour.map(|c| c as f32)).unwrap_or([0.0; 3]),
        }
    }
}

/// One vector's per-pixel geometry for the light loop: the normal (flipped for back faces),
/// the eye vector (zero without a normal), and which pixels are back-facing.
#[doc(hidden)]
pub struct ChunkGeometry<I: Isa> {
    pub n: [F32s<I>; 3],
    pub v: [F32s<I>; 3],
    pub back: Mask<I>,
}

impl Shader {
    /// Whether every material, light and fog value lies where the fast kernels' accuracy
    /// bound is stated (finite, shininess in [1, 1024], coefficients <= 1e6).
    pub(super) fn fast_domain(&self) -> bool {
        let ok = |v: f64| v.is_finite() && v.abs() <= FAST_MAX_COEFFICIENT;
        let ok3 = |v: [f64; 3]| v.into_iter().all(ok);
        let material_ok = |m: &Material<f64>| {
            ok3(m.ambient)
                && ok3(m.diffuse)
                && ok3(m.specular)
                && (m.specular == [0.0; 3] || (m.shininess >= 1.0 && m.shininess <= FAST_MAX_SHININESS))
        };
        let lights_ok = self.setup.lights.iter().all(|l| {
            ok3(l.colour)
                && match l.kind {
                    LightKind::Directional { towards_light } => towards_light.iter().all(|v| v.is_finite()),
                    LightKind::Positional { position, attenuation } => {
                        position.iter().chain(attenuation.iter()).all(|v| v.is_finite())
                    }
                }
        });
        let fog_ok = self
            .fog
            .is_none_or(|f| f.colour.into_iter().all(ok) && f.start.is_finite() && f.end.is_finite());
        material_ok(&self.setup.front)
            && material_ok(&self.setup.back)
            && ok3(self.setup.ambient_light)
            && lights_ok
            && fog_ok
    }

    /// Shade one row with the fast kernel, writing `out[x]` for every x of the row: the
    /// colour where depth was written, zero elsewhere. Monomorphised per effect set like
    /// the reference, and built for AVX-512 and AVX2 (the widest the CPU has runs, or AVX2
    /// when the kernel is [`ShadingKernel::Avx2`]) and for any target.
    pub fn shade_row(&self, row: &RowInputs<'_>, out: &mut [[f32; 3]]) {
        match (self.effects.lit, self.effects.fog, self.effects.texture) {
            (false, false, false) => self.shade_row_for::<false, false, false>(row, out),
            (false, false, true) => self.shade_row_for::<false, false, true>(row, out),
            (false, true, false) => self.shade_row_for::<false, true, false>(row, out),
            (false, true, true) => self.shade_row_for::<false, true, true>(row, out),
            (true, false, false) => self.shade_row_for::<true, false, false>(row, out),
            (true, false, true) => self.shade_row_for::<true, false, true>(row, out),
            (true, true, false) => self.shade_row_for::<true, true, false>(row, out),
            (true, true, true) => self.shade_row_for::<true, true, true>(row, out),
        }
    }

    fn shade_row_for<const LIT: bool, const FOG: bool, const TEXTURE: bool>(
        &self,
        row: &RowInputs<'_>,
        out: &mut [[f32; 3]],
    ) {
        #[cfg(target_arch = "x86_64")]
        match (self.kernel, simd_level()) {
            // SAFETY: the CPU has AVX-512 F and DQ (detected at run time).
            (ShadingKernel::Simd, SimdLevel::Avx512) => {
                return unsafe { self.shade_row_avx512::<LIT, FOG, TEXTURE>(row, out) }
            }
            // SAFETY: the CPU has AVX2 and FMA (detected at run time; `Avx512` implies them).
            (ShadingKernel::Simd | ShadingKernel::Avx2, SimdLevel::Avx512 | SimdLevel::Avx2) => {
                return unsafe { self.shade_row_avx2::<LIT, FOG, TEXTURE>(row, out) }
            }
            _ => {}
        }
        self.shade_row_body::<Portable, LIT, FOG, TEXTURE>(row, out);
    }

    /// The kernel on AVX-512 registers: the one place [`Avx512`] lanes are instantiated.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512dq")]
    unsafe fn shade_row_avx512<const LIT: bool, const FOG: bool, const TEXTURE: bool>(
        &self,
        row: &RowInputs<'_>,
        out: &mut [[f32; 3]],
    ) {
        self.shade_row_body::<Avx512, LIT, FOG, TEXTURE>(row, out);
    }

    /// The kernel on AVX2 registers: the one place [`Avx2`] lanes are instantiated, so
    /// their instructions only ever run after the CPU was found to have them.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn shade_row_avx2<const LIT: bool, const FOG: bool, const TEXTURE: bool>(
        &self,
        row: &RowInputs<'_>,
        out: &mut [[f32; 3]],
    ) {
        self.shade_row_body::<Avx2, LIT, FOG, TEXTURE>(row, out);
    }

    /// The body of [`Self::shade_row_for`], inlined into each build: one fused pass over the
    /// row in vectors of [`LANES`] pixels. Each vector loads its planes contiguously,
    /// computes geometry, every light, fog and the final colour in registers and stores the
    /// colours once; a vector with no written pixel is stored as zeros unshaded.
    #[inline(always)]
    fn shade_row_body<I: Isa, const LIT: bool, const FOG: bool, const TEXTURE: bool>(
        &self,
        row: &RowInputs<'_>,
        out: &mut [[f32; 3]],
    ) {
        let width = row.depth.len().min(out.len());
        let mut x0 = 0;
        while x0 < width {
            let tail;
            let depth: &[u32; LANES] = match row.depth.get(x0..x0 + LANES).map(<&[u32; LANES]>::try_from) {
                Some(Ok(whole)) => whole,
                _ => {
                    tail = load(row.depth, x0, 0);
                    &tail
                }
            };
            let written = Mask::<I>::nonzero(depth);
            if !written.any() {
                // Nothing drawn here: black, without the shading.
                out[x0..width.min(x0 + LANES)].fill([0.0; 3]);
            } else {
                let colour = self.shade_chunk::<I, LIT, FOG, TEXTURE>(row, x0, depth, written);
                // Unwritten pixels are zero.
                let [r, g, b] = map3!(colour, c => written.select(c, F32s::splat(0.0)));
                match out[..width]
                    .get_mut(x0..x0 + LANES)
                    .map(<&mut [[f32; 3]; LANES]>::try_from)
                {
                    // Whole vectors (all but a row's tail): one interleaving store.
                    Some(Ok(whole)) => F32s::store_rgb(r, g, b, whole),
                    _ => {
                        let (r, g, b) = (r.lanes(), g.lanes(), b.lanes());
                        for (j, dst) in out[x0..width].iter_mut().enumerate() {
                            *dst = [r[j], g[j], b[j]];
                        }
                    }
                }
            }
            x0 += LANES;
        }
    }

    /// The colours of the pixels `x0 ..= x0 + LANES - 1` of `row` (lanes past the row's end
    /// or unwritten are computed from placeholder inputs and discarded).
    #[inline(always)]
    fn shade_chunk<I: Isa, const LIT: bool, const FOG: bool, const TEXTURE: bool>(
        &self,
        row: &RowInputs<'_>,
        x0: usize,
        depth: &[u32; LANES],
        written: Mask<I>,
    ) -> [F32s<I>; 3] {
        let fast = &self.fast;
        let zero = F32s::splat(0.0);
        let cs = match row.cs {
            Some(planes) => map3!(planes, p => F32s::load(p, x0)),
            None => [F32s::splat(1.0); 3],
        };
        let p = if LIT || FOG {
            self.chunk_position(row.y, x0, depth)
        } else {
            [F64s::splat(0.0); 3]
        };

        // The base colour: `Cs`, scaled by the checker's `dark` on odd cells (cell parity
        // in f64 with the reference's operations, so no cell edge flips).
        let mut base = cs;
        if TEXTURE {
            if let (Some(t), Some(st)) = (&self.texture, row.st) {
                let (s, tt) = (
                    F64s::from_f32(F32s::load(st[0], x0)),
                    F64s::from_f32(F32s::load(st[1], x0)),
                );
                let cell = (s * t.scale).floor() + (tt * t.scale).floor();
                // cell.rem_euclid(2.0) == 1.0 without the fmod call (exact for every
                // finite cell).
                let odd = cell.finite() & (cell - 2.0 * (cell * 0.5).floor()).equals(F64s::splat(1.0));
                base = map3!(cs, c => odd.select(F32s::from_f64(F64s::from_f32(c) * t.dark), c));
            }
        }

        let mut colour = base;
        if LIT {
            let g = self.chunk_geometry(row, x0, &p, written);
            let mut diffuse = [zero; 3];
            let mut specular = [zero; 3];
            for light in &fast.lights {
                match (light.positional, fast.with_specular) {
                    (false, false) => light_chunk::<I, false, false>(light, fast, &g, &p, &mut diffuse, &mut specular),
                    (false, true) => light_chunk::<I, false, true>(light, fast, &g, &p, &mut diffuse, &mut specular),
                    (true, false) => light_chunk::<I, true, false>(light, fast, &g, &p, &mut diffuse, &mut specular),
                    (true, true) => light_chunk::<I, true, true>(light, fast, &g, &p, &mut diffuse, &mut specular),
                }
            }
            // Ambient and diffuse take the base colour; the highlight does not.
            for k in 0..3 {
                let ambient = by_side(g.back, fast.ambient, k);
                colour[k] = (ambient + diffuse[k]) * colour[k] + specular[k];
            }
        }

        if FOG {
            if let Some(fog) = &self.fog {
                let distance = match (fast.fog_eye_point, fast.fog_direction) {
                    (Some(e), _) => {
                        let d = xyz!(k => p[k] - e[k]);
                        F64s::dot(&d, &d).sqrt()
                    }
                    (None, Some(d)) => {
                        let q = self.near_point;
                        let along = (q.x - p[0]) * d[0] + (q.y - p[1]) * d[1] + (q.z - p[2]) * d[2];
                        along.gt(F64s::splat(0.0)).select(along, F64s::splat(0.0))
                    }
                    (None, None) => F64s::splat(0.0),
                };
                let span = fog.end - fog.start;
                let f = if span > 0.0 {
                    let t = (fog.end - distance) / span;
                    let t = t.lt(F64s::splat(0.0)).select(F64s::splat(0.0), t);
                    F32s::from_f64(t.gt(F64s::splat(1.0)).select(F64s::splat(1.0), t))
                } else {
                    distance.lt(F64s::splat(fog.end)).select(F32s::splat(1.0), zero)
                };
                for (c, fog_colour) in colour.iter_mut().zip(fast.fog_colour) {
                    *c = f * *c + (1.0 - f) * fog_colour;
                }
            }
        }

        // Non-finite colours are black, as in the reference.
        map3!(colour, c => F32s::or_zero_if_not_finite(c))
    }

    /// The position of each pixel in the space lit in: device (x + 1/2, y + 1/2, depth, 1)
    /// through `space_from_device` in f64, the row's terms of the product hoisted; zero where
    /// the product is not finite or w is zero.
    // `q - q` is zero only for finite q: one test for all four components.
    #[allow(clippy::eq_op)]
    #[inline(always)]
    fn chunk_position<I: Isa>(&self, y: u32, x0: usize, depth: &[u32; LANES]) -> [F64s<I>; 3] {
        let z = F64s::from_u32(depth) / 4294967296.0;
        let x = F64s::from_u32(&lane_index()) + (x0 as f64 + 0.5);
        let y = f64::from(y) + 0.5;
        if self.space == LightingSpaceChoice::Device {
            return [x, F64s::splat(y), z];
        }
        let m = self.space_from_device;
        let (mx, mz) = (m.x_axis.to_array(), m.z_axis.to_array());
        let row_terms = (m.y_axis * y + m.w_axis).to_array();
        let [q0, q1, q2] = xyz!(i => mx[i] * x + row_terms[i] + mz[i] * z);
        let q = [q0, q1, q2, mx[3] * x + row_terms[3] + mz[3] * z];
        // Finite and w != 0.
        let ok = q[3].not_equal(F64s::splat(0.0))
            & ((q[0] - q[0]) + (q[1] - q[1]) + (q[2] - q[2]) + (q[3] - q[3])).equals(F64s::splat(0.0));
        let inv_w = 1.0 / ok.select(q[3], F64s::splat(1.0));
        xyz!(k => ok.select(q[k] * inv_w, F64s::splat(0.0)))
    }

    /// The vector's geometry for the light loop: [`Self::chunk_geometry_filtered`] when
    /// every written pixel's facing is clear, otherwise [`Self::chunk_geometry_exact`].
    #[inline(always)]
    fn chunk_geometry<I: Isa>(
        &self,
        row: &RowInputs<'_>,
        x0: usize,
        p: &[F64s<I>; 3],
        written: Mask<I>,
    ) -> ChunkGeometry<I> {
        match self.chunk_geometry_filtered(row, x0, p, written) {
            Some(g) => g,
            None => self.chunk_geometry_exact(row, x0, p),
        }
    }

    /// The common case, in f32 but for the eye offset: the normal `t = M g` (in f64 unless
    /// M is the identity) and the eye offset `d` (eye - position in f64, or the eye
    /// direction), both rounded to f32; the facing from the sign of the *unnormalised*
    /// `t . d` in f32, then `t` and `d` normalised. The sign is the reference's whenever
    /// `|t . d| > 1e-5 |t| |d|` ([`FACING_MARGIN`]). `None` when a written pixel's facing is
    /// closer to grazing than that, its normal or eye offset is zero, non-finite or outside
    /// [1e-15, 1e15] in length, or the frame has no normal: the vector then runs the exact
    /// path.
    #[inline(always)]
    #[doc(hidden)]
    pub fn chunk_geometry_filtered<I: Isa>(
        &self,
        row: &RowInputs<'_>,
        x0: usize,
        p: &[F64s<I>; 3],
        written: Mask<I>,
    ) -> Option<ChunkGeometry<I>> {
        let normal = row.normal?;
        let fast = &self.fast;
        let nm = self.normals_from_lighting.matrix;
        let (na, nb, nc) = (nm.x_axis.to_array(), nm.y_axis.to_array(), nm.z_axis.to_array());
        let g = map3!(normal, plane => F32s::load(plane, x0));
        // Lighting in LC (the default) leaves normals as they are.
        let tf = if nm == glam::DMat3::IDENTITY {
            g
        } else {
            let g = map3!(g, c => F64s::from_f32(c));
            xyz!(i => F32s::from_f64(na[i] * g[0] + nb[i] * g[1] + nc[i] * g[2]))
        };
        let df = match (fast.lit_eye_point, fast.lit_eye_direction) {
            (Some(e), _) => xyz!(k => F32s::from_f64(e[k] - p[k])),
            (None, Some(direction)) => map3!(direction, c => F32s::splat(c as f32)),
            (None, None) => return None,
        };
        let (tt, dd, td) = (F32s::dot(&tf, &tf), F32s::dot(&df, &df), F32s::dot(&tf, &df));
        #[inline(always)]
        fn within<I: Isa>(v: F32s<I>) -> Mask<I> {
            v.gt(F32s::splat(1.0e-30)) & v.lt(F32s::splat(1.0e30))
        }
        let usable = within(tt) & within(dd);
        let (t_len, d_len) = (tt.sqrt(), dd.sqrt());
        // |t . d| beyond the margin; t_len d_len is at least 1e-30 on usable lanes, so the
        // margin never underflows.
        let margin = FACING_MARGIN * t_len * d_len;
        let clear = td.gt(margin) | (-td).gt(margin);
        let zero = F32s::splat(0.0);
        let (back, given) = match row.facing {
            Some(plane) => (F32s::load(plane, x0).lt(zero), Mask::all()),
            None => (td.lt(zero), Mask::none()),
        };
        if (written & !(usable & (given | clear))).any() {
            return None;
        }
        // Unusable lanes are unwritten (discarded): zero keeps them quiet.
        let t_scale = usable.select(back.select(F32s::splat(-1.0), F32s::splat(1.0)) / t_len, zero);
        let d_scale = usable.select(1.0 / d_len, zero);
        Some(ChunkGeometry {
            n: map3!(tf, c => c * t_scale),
            v: map3!(df, c => c * d_scale),
            back,
        })
    }

    /// Per-pixel geometry in f64 with the reference's operations (the decisions: facing,
    /// which lanes have a normal and an eye vector), rounded to f32 for the light loop.
    #[inline(always)]
    #[doc(hidden)]
    pub fn chunk_geometry_exact<I: Isa>(&self, row: &RowInputs<'_>, x0: usize, p: &[F64s<I>; 3]) -> ChunkGeometry<I> {
        let fast = &self.fast;
        let nm = self.normals_from_lighting.matrix;
        let (na, nb, nc) = (nm.x_axis.to_array(), nm.y_axis.to_array(), nm.z_axis.to_array());
        let (zero, one) = (F64s::splat(0.0), F64s::splat(1.0));
        #[inline(always)]
        fn positive_finite<I: Isa>(v: F64s<I>) -> Mask<I> {
            v.gt(F64s::splat(0.0)) & v.lt(F64s::splat(f64::INFINITY))
        }
        let mut n = [zero; 3];
        let mut has_n = Mask::none();
        if let Some(normal) = row.normal {
            let g = map3!(normal, plane => F64s::from_f32(F32s::load(plane, x0)));
            // NormalMatrix::transform: to the space lit in, unit; a degenerate one stays zero
            // (ambient light only, as the reference); then normalize3 as the lighting does.
            let t = xyz!(i => na[i] * g[0] + nb[i] * g[1] + nc[i] * g[2]);
            let len = F64s::dot(&t, &t).sqrt();
            let ok = positive_finite(len);
            let safe_len = ok.select(len, one);
            let t = [
                ok.select(t[0] / safe_len, zero),
                ok.select(t[1] / safe_len, zero),
                ok.select(t[2] / safe_len, zero),
            ];
            let len2 = F64s::dot(&t, &t).sqrt();
            has_n = positive_finite(len2);
            let inv = has_n.select(1.0 / has_n.select(len2, one), zero);
            n = map3!(t, c => c * inv);
        }
        let mut v = [zero; 3];
        let mut has_v = Mask::none();
        match (fast.lit_eye_point, fast.lit_eye_direction) {
            (Some(e), _) => {
                let d = xyz!(k => e[k] - p[k]);
                let len = F64s::dot(&d, &d).sqrt();
                has_v = positive_finite(len);
                let inv = has_v.select(1.0 / has_v.select(len, one), zero);
                v = map3!(d, c => c * inv);
            }
            (None, Some(d)) => {
                has_v = Mask::all();
                v = map3!(d, c => F64s::splat(c));
            }
            (None, None) => {}
        }
        let back = match row.facing {
            Some(plane) => F32s::load(plane, x0).lt(F32s::splat(0.0)),
            None => has_v & has_n & F64s::dot(&n, &v).lt(zero),
        };
        ChunkGeometry {
            n: map3!(n, c => F32s::from_f64(back.select(-c, c))),
            // No normal: no eye vector either (the reference skips the lights).
            v: map3!(v, c => has_n.select(F32s::from_f64(c), F32s::splat(0.0))),
            back,
        }
    }
}

/// Which build of the fast kernels `ShadingKernel::Simd` runs on this CPU, for reports.
pub fn simd_build() -> String {
    #[cfg(target_arch = "x86_64")]
    let name = match simd_level() {
        SimdLevel::Avx512 => "AVX-512",
        SimdLevel::Avx2 => "AVX2",
        SimdLevel::None => "portable loops",
    };
    #[cfg(not(target_arch = "x86_64"))]
    let name = "portable loops";
    format!("{name}, {LANES} pixels per vector")
}

/// The widest vector instructions the CPU has that the kernels are built for.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, PartialEq, Eq)]
enum SimdLevel {
    Avx512,
    Avx2,
    None,
}

/// Detected once per process.
#[cfg(target_arch = "x86_64")]
fn simd_level() -> SimdLevel {
    use std::sync::OnceLock;
    static LEVEL: OnceLock<SimdLevel> = OnceLock::new();
    *LEVEL.get_or_init(|| {
        let avx2 = is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
        if avx2 && is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("avx512dq") {
            SimdLevel::Avx512
        } else if avx2 {
            SimdLevel::Avx2
        } else {
            SimdLevel::None
        }
    })
}

/// One light's contribution to a vector of pixels, specialised for its kind and for whether
/// any material has a specular term, accumulated into `diffuse` and `specular` (light by
/// light, in the scene's order). Positional lights take the vector to the light, its length
/// and the attenuation in f64 (so huge distances and lights close to a far surface keep
/// their precision), the rest is f32.
#[inline(always)]
fn light_chunk<I: Isa, const POSITIONAL: bool, const SPECULAR: bool>(
    light: &LaneLight,
    fast: &FastSetup,
    g: &ChunkGeometry<I>,
    p: &[F64s<I>; 3],
    diffuse: &mut [F32s<I>; 3],
    specular: &mut [F32s<I>; 3],
) {
    let zero = F32s::splat(0.0);
    let (l, att) = if POSITIONAL {
        let [c0, c1, c2] = light.attenuation;
        let to_light = xyz!(k => light.position[k] - p[k]);
        let d = F64s::dot(&to_light, &to_light).sqrt();
        let usable = d.gt(F64s::splat(0.0)) & d.lt(F64s::splat(f64::INFINITY));
        let inv = usable.select(1.0 / d, F64s::splat(0.0));
        let denom = c0 + c1 * d + c2 * d * d;
        let attenuates = denom.gt(F64s::splat(0.0)) & denom.lt(F64s::splat(f64::INFINITY));
        let a = attenuates.select(1.0 / denom, F64s::splat(1.0));
        (map3!(to_light, c => F32s::from_f64(c * inv)), F32s::from_f64(a))
    } else {
        (map3!(light.towards, c => F32s::splat(c)), F32s::splat(1.0))
    };
    let n_dot_l = F32s::dot(&g.n, &l);
    let lit = n_dot_l.gt(zero);
    let weight = lit.select(n_dot_l * att, zero);
    for (k, sum) in diffuse.iter_mut().enumerate() {
        *sum = *sum + weight * by_side(g.back, light.diffuse, k);
    }
    if SPECULAR {
        let two_ndl = 2.0 * n_dot_l;
        let r = xyz!(k => two_ndl * g.n[k] - l[k]);
        let r_dot_v = F32s::dot(&r, &g.v);
        let tiny = F32s::splat(1.0e-30);
        let base = r_dot_v.gt(tiny).select(r_dot_v, tiny);
        let power = match fast.integer_power {
            Some((exponent, floor)) => pow_integer(base, exponent, floor),
            None => {
                let shine = g
                    .back
                    .select(F32s::splat(fast.shininess[1]), F32s::splat(fast.shininess[0]));
                base.zip(shine, pow_positive)
            }
        };
        let highlight = (lit & r_dot_v.gt(zero)).select(power * att, zero);
        for (k, sum) in specular.iter_mut().enumerate() {
            *sum = *sum + highlight * by_side(g.back, light.specular, k);
        }
    }
}

/// Component `k` of a per-side constant (index 0 front, 1 back), chosen per lane.
#[inline(always)]
fn by_side<I: Isa>(back: Mask<I>, per_side: [[f32; 3]; 2], k: usize) -> F32s<I> {
    back.select(F32s::splat(per_side[1][k]), F32s::splat(per_side[0][k]))
}

/// The smallest base [`pow_integer`] takes for exponent `n`: `2^(-120/n)`, so `floor^n`
/// is about 2^-120, well inside f32's normal range.
#[doc(hidden)]
pub fn integer_power_floor(n: u32) -> f32 {
    (-120.0 / n.max(1) as f32).exp2()
}

/// `x^n` for positive `x` and an integer `n` in [1, 128] by repeated squaring over a whole
/// vector (the exponent is the same for every lane, so the loop is uniform). Bases below
/// `floor` ([`integer_power_floor`]) are raised to it first, so no intermediate power is
/// subnormal (subnormal products are slow on x86); the result there is ~2^-120 instead of
/// smaller, an absolute error below 1e-36. Relative error elsewhere <= 2 log2(n) + 1
/// roundings (< 1e-5).
#[inline(always)]
#[doc(hidden)]
pub fn pow_integer<I: Isa>(x: F32s<I>, n: u32, floor: f32) -> F32s<I> {
    let floor = F32s::splat(floor);
    let mut square = x.gt(floor).select(x, floor);
    let mut result = F32s::splat(1.0);
    let mut rest = n;
    while rest > 0 {
        if rest & 1 != 0 {
            result = result * square;
        }
        rest >>= 1;
        if rest > 0 {
            square = square * square;
        }
    }
    result
}

/// `x^s` for normal positive `x` and `s` in [1, 16384], as `2^(s log2 x)` with polynomial
/// log2 and exp2 (branch-free, so it vectorises). Relative error <= 1e-5 (dominated by the
/// f32 rounding of `s log2 x`; tests/runtime/shading_fast_maths.rs sweeps it against f64
/// `powf`); results below 2^-126 are flushed to (near) zero.
#[inline(always)]
#[doc(hidden)]
pub fn pow_positive(x: f32, s: f32) -> f32 {
    // log2 x = e + log2 m with m in [sqrt(1/2), sqrt(2)): ln m = 2 atanh(t), t = (m-1)/(m+1),
    // |t| <= 0.172, five terms of the series leave < 4e-10.
    let bits = x.to_bits();
    let mut e = ((bits >> 23) & 0xff) as i32 - 127;
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    let big = m > std::f32::consts::SQRT_2;
    m = if big { m * 0.5 } else { m };
    e += big as i32;
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let series = 1.0 + t2 * (1.0 / 3.0 + t2 * (1.0 / 5.0 + t2 * (1.0 / 7.0 + t2 * (1.0 / 9.0))));
    let log2 = e as f32 + 2.0 * std::f32::consts::LOG2_E * t * series;
    // exp2 y = 2^k * e^(f ln 2), k = round(y), |f| <= 1/2: Taylor to degree 7 (< 6e-9).
    let y = s * log2;
    let y = if y < -126.0 { -126.0 } else { y };
    let y = if y > 126.0 { 126.0 } else { y };
    let k = (y + 12_582_912.0) - 12_582_912.0;
    let z = (y - k) * std::f32::consts::LN_2;
    let p = 1.0
        + z * (1.0
            + z * (1.0 / 2.0
                + z * (1.0 / 6.0 + z * (1.0 / 24.0 + z * (1.0 / 120.0 + z * (1.0 / 720.0 + z * (1.0 / 5040.0)))))));
    p * f32::from_bits(((k as i32 + 127) as u32) << 23)
}
