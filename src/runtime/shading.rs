//! The deferred shading pass: after every tile is rendered, each *visible* pixel (depth
//! written) is shaded once from its G-buffer values.
//!
//! Inputs per pixel: the position, reconstructed from (X, Y, depth) through
//! `lighting_from_device` (the inverse of `device_from_lighting`, f64); the normal from the
//! `N` shading parameter (stored in lighting coordinates by the API); the base colour `Cs`
//! (white without one); the facing from the reserved `facing` parameter when the scene uses
//! `distinguish`, otherwise from the normal and the eye; texture coordinates from the
//! parameter the `texture` command names.
//!
//! Lighting is Phong ([`crate::pipeline::lighting`], f64) with the scene's directional and
//! positional lights (given in world coordinates, moved once per frame into the space lit
//! in), ambient light, front and back materials; then optional linear fog by distance from
//! the eye, and an optional procedural checker texture that scales the base colour.
//!
//! Specialisation: the pass is monomorphised Rust, one instance per effect set
//! (`shade_pixels::<LIT, FOG, TEXTURE>`, eight in all), chosen once per frame. A scene
//! without lights, fog or texture runs none of it: colours are `Cs` as before. The space
//! lit in is LC by default; WC and DC exist for the seed 001 figure 2 experiment
//! (`lighting_space`); DC lighting is wrong under perspective on purpose.
//!
//! Kernels ([`ShadingKernel`]): the pass above, scalar f64 per pixel ([`Shader::shade`]), is
//! the *reference*. The default kernel ([`Shader::shade_row`]) is one fused pass over a row
//! of the G-buffer in chunks of [`CHUNK`] pixels: each chunk loads its planes contiguously
//! ([`RowInputs`]; unwritten pixels ride along and are masked to zero), computes the
//! position in f64, decides the facing from the sign of the unnormalised f64 `N . (eye - P)`
//! when it is clear by a 1e-9 margin on the cosine (otherwise the chunk takes the exact path
//! with the reference's f64 operations), normalises normal and eye vector in f32, runs every
//! light (f32; positional light vectors and attenuation in f64), fog and the final colour in
//! registers, and stores the colours once. Compiled for AVX2 + FMA when the CPU has them
//! and for the baseline target otherwise — bit-identical results either way.
//! Stated bound (tests/shading_fast.rs, tests/shading_rows.rs): every channel within 1/4096
//! of the reference before quantisation, the 8-bit image equal or off by one on at most 2% of
//! covered pixels. Values outside the bound's domain (shininess outside [1, 1024],
//! coefficients above 1e6 or non-finite) run the reference instead.

use glam::{DMat4, DVec3, DVec4};

use crate::pipeline::face::Facing;
use crate::pipeline::lighting::{Eye, Light, LightKind, LightingSetup, Material, Sample};
use crate::pipeline::real::{add3, dot3, length3, normalize3, scale3, sub3};
use crate::pipeline::transform::NormalMatrix;

/// A light as the scene gives it, in world coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SceneLight {
    Directional {
        towards_light: [f64; 3],
        colour: [f64; 3],
    },
    Positional {
        position: [f64; 3],
        colour: [f64; 3],
        attenuation: [f64; 3],
    },
}

/// One side's reflectance: coefficients times the base colour (ambient, diffuse) or the
/// specular colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceMaterial {
    pub ka: f64,
    pub kd: f64,
    pub ks: f64,
    pub shininess: f64,
    pub specular_colour: [f64; 3],
}

impl Default for SurfaceMaterial {
    fn default() -> Self {
        SurfaceMaterial {
            ka: 1.0,
            kd: 1.0,
            ks: 0.0,
            shininess: 16.0,
            specular_colour: [1.0; 3],
        }
    }
}

/// Linear fog: full colour up to `start`, fog colour from `end` on (distance from the eye
/// in lighting units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fog {
    pub colour: [f64; 3],
    pub start: f64,
    pub end: f64,
}

/// A procedural checkerboard over two interpolated coordinates: the base colour is scaled
/// by `dark` on odd squares.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// The shading parameter with the coordinates (its first two components).
    pub param: String,
    /// Squares per coordinate unit.
    pub scale: f64,
    pub dark: f64,
}

/// The space the shading pass lights in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LightingSpaceChoice {
    /// Lighting coordinates (seed 001): correct, and cheap to reach from device space.
    #[default]
    Lighting,
    /// World coordinates: the reference.
    World,
    /// Device coordinates after the divide: wrong under perspective (seed 001 figure 2).
    Device,
}

/// Everything the scene says about shading.
#[derive(Clone, Debug, PartialEq)]
pub struct ShadingSetup {
    pub lights: Vec<SceneLight>,
    pub ambient_light: [f64; 3],
    pub front: SurfaceMaterial,
    /// `None`: the back side uses the front material.
    pub back: Option<SurfaceMaterial>,
    pub fog: Option<Fog>,
    pub texture: Option<Texture>,
    pub space: LightingSpaceChoice,
    /// Which implementation of the pass runs (the fast f32 lanes by default).
    pub kernel: ShadingKernel,
}

/// The implementation of the shading pass. The fast kernels agree with the f64 reference
/// within the bound stated in the module documentation; `Simd` and `Portable` give
/// bit-identical results (same IEEE operations in the same order, no fused multiply-add).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ShadingKernel {
    /// f32 lanes, the light loop compiled for AVX2 when the CPU has it (detected at run
    /// time), otherwise the portable loop.
    #[default]
    Simd,
    /// The same f32 lanes compiled for the baseline target (SSE2 on x86-64).
    Portable,
    /// Scalar f64 per pixel: the reference the fast kernels are measured against.
    ReferenceF64,
}

impl Default for ShadingSetup {
    fn default() -> Self {
        ShadingSetup {
            lights: vec![],
            ambient_light: [0.2; 3],
            front: SurfaceMaterial::default(),
            back: None,
            fog: None,
            texture: None,
            space: LightingSpaceChoice::Lighting,
            kernel: ShadingKernel::default(),
        }
    }
}

/// Which effects a frame's shading kernel contains.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Effects {
    pub lit: bool,
    pub fog: bool,
    pub texture: bool,
}

impl Effects {
    pub fn any(self) -> bool {
        self.lit || self.fog || self.texture
    }
}

impl std::fmt::Display for Effects {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut on = vec![];
        if self.lit {
            on.push("Phong lighting");
        }
        if self.fog {
            on.push("fog");
        }
        if self.texture {
            on.push("checker texture");
        }
        if on.is_empty() {
            write!(f, "none (colour = Cs)")
        } else {
            write!(f, "{}", on.join(", "))
        }
    }
}

impl ShadingSetup {
    /// The scene has lights: primitives need normals and the pass runs Phong.
    pub fn lit(&self) -> bool {
        !self.lights.is_empty()
    }
    pub fn effects(&self) -> Effects {
        Effects {
            lit: self.lit(),
            fog: self.fog.is_some(),
            texture: self.texture.is_some(),
        }
    }
}

/// The matrices the pass needs, taken from the geometry state at render time.
#[derive(Clone, Copy, Debug)]
pub struct ShadingSpaces {
    pub device_from_lighting: DMat4,
    pub lighting_from_world: DMat4,
    pub device_from_clip: DMat4,
}

/// What one pixel's shading reads from the G-buffer.
pub struct PixelInputs {
    pub x: u32,
    pub y: u32,
    /// Depth in [0, 1), larger nearer.
    pub depth: f64,
    pub cs: [f64; 3],
    /// Normal in lighting coordinates (may be unnormalised or absent).
    pub normal: Option<[f64; 3]>,
    pub facing: Option<Facing>,
    pub st: Option<[f64; 2]>,
}

/// A frame's shading kernel: the setup moved into the space lit in.
pub struct Shader {
    effects: Effects,
    space: LightingSpaceChoice,
    /// Where positions come from: device (x, y, z, 1) -> this space, homogeneous.
    space_from_device: DMat4,
    /// Normals from LC to this space.
    normals_from_lighting: NormalMatrix,
    setup: LightingSetup<f64>,
    /// The eye point (perspective) for fog distance, or a point on the near plane and the
    /// towards-viewer direction (parallel).
    eye: Eye<f64>,
    near_point: DVec3,
    fog: Option<Fog>,
    texture: Option<Texture>,
    kernel: ShadingKernel,
    /// The fast kernels' constants (lights in lane form, ambient, eyes), derived once.
    fast: FastSetup,
}

fn material(m: &SurfaceMaterial) -> Material<f64> {
    Material {
        ambient: [m.ka; 3],
        diffuse: [m.kd; 3],
        specular: m.specular_colour.map(|c| c * m.ks),
        shininess: m.shininess,
    }
}

fn project(m: &DMat4, p: DVec4) -> Option<DVec3> {
    let q = *m * p;
    (q.w != 0.0 && q.is_finite()).then(|| q.truncate() / q.w)
}

impl Shader {
    /// Build the kernel for `setup` under `spaces`. `None` when there is nothing to do or
    /// the device transform cannot be inverted (then colours stay `Cs`).
    pub fn new(setup: &ShadingSetup, spaces: &ShadingSpaces) -> Option<Shader> {
        let effects = setup.effects();
        if !effects.any() {
            return None;
        }
        let det = spaces.device_from_lighting.determinant();
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let lighting_from_device = spaces.device_from_lighting.inverse();
        let world_from_lighting = spaces.lighting_from_world.inverse();
        let (space_from_lighting, space_from_device) = match setup.space {
            LightingSpaceChoice::Lighting => (DMat4::IDENTITY, lighting_from_device),
            LightingSpaceChoice::World => (world_from_lighting, world_from_lighting * lighting_from_device),
            LightingSpaceChoice::Device => (spaces.device_from_lighting, DMat4::IDENTITY),
        };
        let space_from_world = space_from_lighting * spaces.lighting_from_world;
        // The eye: clip space's point at infinity along z, (0, 0, 1, 0), mapped back.
        let lighting_from_clip = lighting_from_device * spaces.device_from_clip;
        let near_centre = project(&lighting_from_clip, DVec4::new(0.0, 0.0, 1.0, 1.0)).unwrap_or(DVec3::ZERO);
        let far_centre = project(&lighting_from_clip, DVec4::new(0.0, 0.0, 0.0, 1.0)).unwrap_or(DVec3::NEG_Z);
        let eye_h = lighting_from_clip * DVec4::new(0.0, 0.0, 1.0, 0.0);
        let perspective = eye_h.w.abs() > 1e-12 * eye_h.truncate().length();
        let to_space = |p: DVec3| project(&space_from_lighting, p.extend(1.0)).unwrap_or(p);
        let eye = match setup.space {
            // Device lighting: the viewer looks down device -z (larger z is nearer).
            LightingSpaceChoice::Device => Eye::Direction([0.0, 0.0, 1.0]),
            _ if perspective => Eye::Point(to_space(eye_h.truncate() / eye_h.w).to_array()),
            _ => Eye::Direction((to_space(near_centre) - to_space(far_centre)).to_array()),
        };
        let lights = setup
            .lights
            .iter()
            .map(|l| match *l {
                SceneLight::Directional { towards_light, colour } => {
                    let d = space_from_world * DVec3::from_array(towards_light).extend(0.0);
                    Light {
                        kind: LightKind::Directional {
                            towards_light: d.truncate().to_array(),
                        },
                        colour,
                    }
                }
                SceneLight::Positional {
                    position,
                    colour,
                    attenuation,
                } => {
                    let p = project(&space_from_world, DVec3::from_array(position).extend(1.0))
                        .unwrap_or(DVec3::from_array(position));
                    Light {
                        kind: LightKind::Positional {
                            position: p.to_array(),
                            attenuation,
                        },
                        colour,
                    }
                }
            })
            .collect();
        let front = material(&setup.front);
        let back = setup.back.as_ref().map(material).unwrap_or(front);
        let lighting = LightingSetup {
            front,
            back,
            ambient_light: setup.ambient_light,
            lights,
            eye,
        };
        let fast = FastSetup::new(&lighting, eye, setup.fog.as_ref());
        Some(Shader {
            fast,
            effects,
            space: setup.space,
            space_from_device,
            normals_from_lighting: NormalMatrix::of(&space_from_lighting),
            setup: lighting,
            eye,
            near_point: to_space(near_centre),
            fog: setup.fog,
            texture: setup.texture.clone(),
            kernel: setup.kernel,
        })
    }

    pub fn effects(&self) -> Effects {
        self.effects
    }

    /// The implementation the frame runs: the fast kernels fall back to the f64 reference
    /// when a material or light lies outside the domain their accuracy bound covers.
    pub fn kernel(&self) -> ShadingKernel {
        if self.kernel != ShadingKernel::ReferenceF64 && !self.fast_domain() {
            return ShadingKernel::ReferenceF64;
        }
        self.kernel
    }

    /// The position of a pixel in the space lit in.
    pub fn position(&self, x: u32, y: u32, depth: f64) -> DVec3 {
        let d = DVec4::new(f64::from(x) + 0.5, f64::from(y) + 0.5, depth, 1.0);
        match self.space {
            LightingSpaceChoice::Device => d.truncate(),
            _ => project(&self.space_from_device, d).unwrap_or(DVec3::ZERO),
        }
    }

    /// Shade every pixel of `inputs`, writing colours; monomorphised per effect set.
    pub fn shade(&self, inputs: &[PixelInputs], out: &mut [[f32; 3]]) {
        match (self.effects.lit, self.effects.fog, self.effects.texture) {
            (false, false, false) => self.shade_pixels::<false, false, false>(inputs, out),
            (false, false, true) => self.shade_pixels::<false, false, true>(inputs, out),
            (false, true, false) => self.shade_pixels::<false, true, false>(inputs, out),
            (false, true, true) => self.shade_pixels::<false, true, true>(inputs, out),
            (true, false, false) => self.shade_pixels::<true, false, false>(inputs, out),
            (true, false, true) => self.shade_pixels::<true, false, true>(inputs, out),
            (true, true, false) => self.shade_pixels::<true, true, false>(inputs, out),
            (true, true, true) => self.shade_pixels::<true, true, true>(inputs, out),
        }
    }

    fn shade_pixels<const LIT: bool, const FOG: bool, const TEXTURE: bool>(
        &self,
        inputs: &[PixelInputs],
        out: &mut [[f32; 3]],
    ) {
        for (px, colour) in inputs.iter().zip(out.iter_mut()) {
            let mut base = px.cs;
            if TEXTURE {
                if let (Some(t), Some(st)) = (&self.texture, px.st) {
                    let cell = (st[0] * t.scale).floor() + (st[1] * t.scale).floor();
                    if cell.is_finite() && cell.rem_euclid(2.0) == 1.0 {
                        base = base.map(|c| c * t.dark);
                    }
                }
            }
            let needs_position = LIT || FOG;
            let position = if needs_position {
                self.position(px.x, px.y, px.depth)
            } else {
                DVec3::ZERO
            };
            let mut c = base;
            if LIT {
                let normal = px
                    .normal
                    .map(|n| self.normals_from_lighting.transform(DVec3::from_array(n)).0.to_array())
                    .unwrap_or([0.0; 3]);
                let sample = Sample {
                    point: position.to_array(),
                    normal,
                };
                let facing = px.facing.unwrap_or_else(|| self.setup.facing(&sample));
                // Ambient and diffuse take the base colour; the specular highlight does not.
                let (lit, unlit_spec) = phong_and_specular_share(&self.setup, &sample, facing);
                c = [0, 1, 2].map(|k| (lit[k] - unlit_spec[k]) * base[k] + unlit_spec[k]);
            }
            if FOG {
                if let Some(fog) = &self.fog {
                    let distance = match self.eye {
                        Eye::Point(e) => (position - DVec3::from_array(e)).length(),
                        Eye::Direction(d) => {
                            let d = DVec3::from_array(d).normalize_or_zero();
                            (self.near_point - position).dot(d).max(0.0)
                        }
                    };
                    let span = fog.end - fog.start;
                    let f = if span > 0.0 {
                        ((fog.end - distance) / span).clamp(0.0, 1.0)
                    } else if distance < fog.end {
                        1.0
                    } else {
                        0.0
                    };
                    c = [0, 1, 2].map(|k| f * c[k] + (1.0 - f) * fog.colour[k]);
                }
            }
            *colour = c.map(|v| if v.is_finite() { v as f32 } else { 0.0 });
        }
    }
}

/// The Phong colour at `s` (`LightingSetup::shade_facing`) and its specular share alone (the
/// same sum with the material's ambient and diffuse zeroed; zero without specular), in one
/// pass over the lights. Each sum repeats `shade_facing`'s operations in its order, so both
/// are bit-identical to evaluating `shade_facing` twice (the unit test checks), while the
/// shared work (normal, eye vector, light vectors, attenuation, the power) is done once.
fn phong_and_specular_share(setup: &LightingSetup<f64>, s: &Sample<f64>, facing: Facing) -> ([f64; 3], [f64; 3]) {
    let mul3 = |a: [f64; 3], b: [f64; 3]| [a[0] * b[0], a[1] * b[1], a[2] * b[2]];
    let material = match facing {
        Facing::Front => &setup.front,
        Facing::Back => &setup.back,
    };
    let with_specular = material.specular != [0.0; 3];
    let mut colour = mul3(material.ambient, setup.ambient_light);
    let mut specular = mul3([0.0; 3], setup.ambient_light);
    let Some(mut n) = normalize3(s.normal) else {
        return (colour, if with_specular { specular } else { [0.0; 3] });
    };
    if facing == Facing::Back {
        n = scale3(n, -1.0);
    }
    let v = setup.towards_eye(s.point);
    for light in &setup.lights {
        let (l, att) = match light.kind {
            LightKind::Directional { towards_light } => (normalize3(towards_light), 1.0),
            LightKind::Positional { position, attenuation } => {
                let to_light = sub3(position, s.point);
                let d = length3(to_light);
                let denom = attenuation[0] + attenuation[1] * d + attenuation[2] * d * d;
                let att = if denom > 0.0 && denom.is_finite() {
                    1.0 / denom
                } else {
                    1.0
                };
                (normalize3(to_light), att)
            }
        };
        let Some(l) = l else { continue };
        let n_dot_l = dot3(n, l);
        if n_dot_l <= 0.0 {
            continue;
        }
        let mut term = scale3(material.diffuse, n_dot_l);
        let mut term_specular = scale3([0.0; 3], n_dot_l);
        if let Some(v) = v {
            let r = sub3(scale3(n, 2.0 * n_dot_l), l);
            let r_dot_v = dot3(r, v);
            if r_dot_v > 0.0 {
                let highlight = scale3(material.specular, r_dot_v.powf(material.shininess));
                term = add3(term, highlight);
                term_specular = add3(term_specular, highlight);
            }
        }
        colour = add3(colour, scale3(mul3(term, light.colour), att));
        specular = add3(specular, scale3(mul3(term_specular, light.colour), att));
    }
    (colour, if with_specular { specular } else { [0.0; 3] })
}

// ---------------------------------------------------------------------------------------
// The fast pass: one fused pass per row over chunks of CHUNK contiguous pixels. Per chunk:
// position in f64; facing from a filtered f64 sign test (exact f64 path near grazing);
// normal and eye vector in f32; every light, fog and the final colour in f32 lanes the
// compiler vectorises; one masked store.

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
struct FastSetup {
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

/// The filtered facing test's margin on the squared cosine: a facing is decided from the
/// unnormalised `t . d` when `(t . d)^2 > FACING_MARGIN |t|^2 |d|^2`, i.e. the cosine is
/// beyond 1e-9, six orders above the rounding error of the reference's own cosine.
const FACING_MARGIN: f64 = 1.0e-18;

/// Largest integer shininess taken by repeated squaring: at most 2 log2(n) = 14 f32
/// multiplications, relative error below 1e-5 (the unit test sweeps it).
const MAX_INTEGER_SHININESS: u32 = 128;

impl FastSetup {
    fn new(setup: &LightingSetup<f64>, eye: Eye<f64>, fog: Option<&Fog>) -> FastSetup {
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

/// One chunk's per-pixel geometry for the light loop: the normal (flipped for back faces),
/// the eye vector (zero without a normal), and the facing (1.0 = back).
struct ChunkGeometry {
    n: [[f32; CHUNK]; 3],
    v: [[f32; CHUNK]; 3],
    /// All ones for a back-facing pixel, zero for a front-facing one (a bit mask, so the
    /// per-side selects stay vector blends: see [`select`]).
    back: [u32; CHUNK],
}

impl Shader {
    /// Whether every material, light and fog value lies where the fast kernels' accuracy
    /// bound is stated (finite, shininess in [1, 1024], coefficients <= 1e6).
    fn fast_domain(&self) -> bool {
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
    /// the reference; the whole body is compiled for AVX2 + FMA when the CPU has them.
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
        let simd = self.kernel == ShadingKernel::Simd;
        with_simd(
            simd,
            #[inline(always)]
            || self.shade_row_body::<LIT, FOG, TEXTURE>(row, out),
        );
    }

    /// The body of [`Self::shade_row_for`], inlined into the AVX2 or the baseline build: one
    /// fused pass over the row in chunks of [`CHUNK`] pixels. Each chunk loads its planes
    /// contiguously, computes geometry, every light, fog and the final colour in registers
    /// and stores the colours once; a chunk with no written pixel is skipped.
    #[inline(always)]
    fn shade_row_body<const LIT: bool, const FOG: bool, const TEXTURE: bool>(
        &self,
        row: &RowInputs<'_>,
        out: &mut [[f32; 3]],
    ) {
        let width = row.depth.len().min(out.len());
        let mut x0 = 0;
        while x0 < width {
            let depth_raw = load_chunk(row.depth, x0, 0u32);
            if depth_raw != [0; CHUNK] {
                let mut colour = self.shade_chunk::<LIT, FOG, TEXTURE>(row, x0, &depth_raw);
                // Unwritten pixels are zero: a mask, so this stays a vector operation.
                let written = depth_raw.map(|d| if d != 0 { u32::MAX } else { 0 });
                for channel in colour.iter_mut() {
                    for j in 0..CHUNK {
                        channel[j] = select(written[j], channel[j], 0.0);
                    }
                }
                match out[..width].get_mut(x0..x0 + CHUNK) {
                    // Whole chunks (all but a row's tail): a fixed-size interleaving store.
                    Some(whole) => {
                        for (j, dst) in whole.iter_mut().enumerate() {
                            *dst = [colour[0][j], colour[1][j], colour[2][j]];
                        }
                    }
                    None => {
                        for (j, dst) in out[x0..width].iter_mut().enumerate() {
                            *dst = [colour[0][j], colour[1][j], colour[2][j]];
                        }
                    }
                }
            }
            x0 += CHUNK;
        }
    }

    /// The colours of the chunk of pixels `x0 ..= x0 + CHUNK - 1` of `row` (lanes past the
    /// row's end or unwritten are computed from placeholder inputs and discarded).
    // `v - v == 0.0` is the finiteness test that keeps the chunk loops branch-free.
    #[allow(clippy::eq_op)]
    #[inline(always)]
    fn shade_chunk<const LIT: bool, const FOG: bool, const TEXTURE: bool>(
        &self,
        row: &RowInputs<'_>,
        x0: usize,
        depth_raw: &[u32; CHUNK],
    ) -> [[f32; CHUNK]; 3] {
        let fast = &self.fast;
        let cs = match row.cs {
            Some(planes) => planes.map(|p| load_chunk(p, x0, 0.0)),
            None => [[1.0; CHUNK]; 3],
        };

        // The position in the space lit in: device (x + 1/2, y + 1/2, depth, 1) through
        // `space_from_device` in f64, the row's terms of the product hoisted.
        let mut p = [[0f64; CHUNK]; 3];
        if LIT || FOG {
            let depth = depth_raw.map(|d| f64::from(d) / 4294967296.0);
            let y = f64::from(row.y) + 0.5;
            if self.space == LightingSpaceChoice::Device {
                for j in 0..CHUNK {
                    p[0][j] = (x0 + j) as f64 + 0.5;
                    p[1][j] = y;
                    p[2][j] = depth[j];
                }
            } else {
                let m = self.space_from_device;
                let (mx, mz) = (m.x_axis.to_array(), m.z_axis.to_array());
                let row_terms = (m.y_axis * y + m.w_axis).to_array();
                for j in 0..CHUNK {
                    let x = (x0 + j) as f64 + 0.5;
                    let z = depth[j];
                    let q0 = mx[0] * x + row_terms[0] + mz[0] * z;
                    let q1 = mx[1] * x + row_terms[1] + mz[1] * z;
                    let q2 = mx[2] * x + row_terms[2] + mz[2] * z;
                    let q3 = mx[3] * x + row_terms[3] + mz[3] * z;
                    // Finite and w != 0 (x - x is 0 only for finite x).
                    let ok = q3 != 0.0 && (q0 - q0) + (q1 - q1) + (q2 - q2) + (q3 - q3) == 0.0;
                    // Divide unconditionally (then select) so the loop stays branch-free.
                    let inv_w = 1.0 / if ok { q3 } else { 1.0 };
                    p[0][j] = if ok { q0 * inv_w } else { 0.0 };
                    p[1][j] = if ok { q1 * inv_w } else { 0.0 };
                    p[2][j] = if ok { q2 * inv_w } else { 0.0 };
                }
            }
        }

        // The base colour: `Cs`, scaled by the checker's `dark` on odd cells (cell parity
        // in f64 with the reference's operations, so no cell edge flips).
        let mut base = cs;
        if TEXTURE {
            if let (Some(t), Some(st)) = (&self.texture, row.st) {
                let (s, tt) = (load_chunk(st[0], x0, 0.0), load_chunk(st[1], x0, 0.0));
                for j in 0..CHUNK {
                    let cell = (f64::from(s[j]) * t.scale).floor() + (f64::from(tt[j]) * t.scale).floor();
                    // cell.rem_euclid(2.0) == 1.0 without the fmod call (exact for every
                    // finite cell).
                    let odd = cell.is_finite() && cell - 2.0 * (cell * 0.5).floor() == 1.0;
                    for k in 0..3 {
                        base[k][j] = if odd {
                            (f64::from(cs[k][j]) * t.dark) as f32
                        } else {
                            cs[k][j]
                        };
                    }
                }
            }
        }

        let mut colour = base;
        if LIT {
            let g = self.chunk_geometry(row, x0, &p, &depth_raw.map(|d| d != 0));
            let mut diffuse = [[0f32; CHUNK]; 3];
            let mut specular = [[0f32; CHUNK]; 3];
            for light in &fast.lights {
                match (light.positional, fast.with_specular) {
                    (false, false) => light_chunk::<false, false>(light, fast, &g, &p, &mut diffuse, &mut specular),
                    (false, true) => light_chunk::<false, true>(light, fast, &g, &p, &mut diffuse, &mut specular),
                    (true, false) => light_chunk::<true, false>(light, fast, &g, &p, &mut diffuse, &mut specular),
                    (true, true) => light_chunk::<true, true>(light, fast, &g, &p, &mut diffuse, &mut specular),
                }
            }
            // Ambient and diffuse take the base colour; the highlight does not.
            for k in 0..3 {
                let (front_ambient, back_ambient) = (fast.ambient[0][k], fast.ambient[1][k]);
                for j in 0..CHUNK {
                    let ambient = select(g.back[j], back_ambient, front_ambient);
                    colour[k][j] = (ambient + diffuse[k][j]) * colour[k][j] + specular[k][j];
                }
            }
        }

        if FOG {
            if let Some(fog) = &self.fog {
                let mut distance = [0f64; CHUNK];
                match (fast.fog_eye_point, fast.fog_direction) {
                    (Some(e), _) => {
                        for j in 0..CHUNK {
                            let d = [p[0][j] - e[0], p[1][j] - e[1], p[2][j] - e[2]];
                            distance[j] = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                        }
                    }
                    (None, Some(d)) => {
                        let q = self.near_point;
                        for j in 0..CHUNK {
                            let along = (q.x - p[0][j]) * d[0] + (q.y - p[1][j]) * d[1] + (q.z - p[2][j]) * d[2];
                            distance[j] = if along > 0.0 { along } else { 0.0 };
                        }
                    }
                    (None, None) => {}
                }
                let span = fog.end - fog.start;
                let mut f = [0f32; CHUNK];
                if span > 0.0 {
                    for j in 0..CHUNK {
                        let t = (fog.end - distance[j]) / span;
                        let t = if t < 0.0 { 0.0 } else { t };
                        f[j] = (if t > 1.0 { 1.0 } else { t }) as f32;
                    }
                } else {
                    for j in 0..CHUNK {
                        f[j] = if distance[j] < fog.end { 1.0 } else { 0.0 };
                    }
                }
                for k in 0..3 {
                    let fog_k = fast.fog_colour[k];
                    for j in 0..CHUNK {
                        colour[k][j] = f[j] * colour[k][j] + (1.0 - f[j]) * fog_k;
                    }
                }
            }
        }

        for channel in colour.iter_mut() {
            for j in 0..CHUNK {
                // Non-finite colours are black, as in the reference.
                let v = channel[j];
                channel[j] = if (v - v) == 0.0 { v } else { 0.0 };
            }
        }
        colour
    }

    /// The chunk's geometry for the light loop: [`Self::chunk_geometry_filtered`] when every
    /// written pixel's facing is clear, otherwise [`Self::chunk_geometry_exact`].
    #[inline(always)]
    fn chunk_geometry(
        &self,
        row: &RowInputs<'_>,
        x0: usize,
        p: &[[f64; CHUNK]; 3],
        written: &[bool; CHUNK],
    ) -> ChunkGeometry {
        match self.chunk_geometry_filtered(row, x0, p, written) {
            Some(g) => g,
            None => self.chunk_geometry_exact(row, x0, p),
        }
    }

    /// The common case without divisions in f64: the normal `t = M g` and the eye offset
    /// `d` (eye - position, or the eye direction) in f64, the facing from the sign of the
    /// *unnormalised* `t . d`, then `t` and `d` normalised in f32 (8 lanes per instruction
    /// instead of 4). The sign is the reference's whenever `|t . d| > 1e-9 |t| |d|` (the
    /// reference's own f64 error in the cosine is ~1e-15; [`FACING_MARGIN`]). `None` when a
    /// written pixel's facing is closer to grazing than that, its normal or eye offset is
    /// zero, non-finite or outside [1e-15, 1e15] in length, or the frame has no normal:
    /// the chunk then runs the exact path.
    #[inline(always)]
    fn chunk_geometry_filtered(
        &self,
        row: &RowInputs<'_>,
        x0: usize,
        p: &[[f64; CHUNK]; 3],
        written: &[bool; CHUNK],
    ) -> Option<ChunkGeometry> {
        let normal = row.normal?;
        let fast = &self.fast;
        let nm = self.normals_from_lighting.matrix;
        let (na, nb, nc) = (nm.x_axis.to_array(), nm.y_axis.to_array(), nm.z_axis.to_array());
        let (g0, g1, g2) = (
            load_chunk(normal[0], x0, 0.0),
            load_chunk(normal[1], x0, 0.0),
            load_chunk(normal[2], x0, 0.0),
        );
        let mut t = [[0f64; CHUNK]; 3];
        for j in 0..CHUNK {
            let g = [f64::from(g0[j]), f64::from(g1[j]), f64::from(g2[j])];
            t[0][j] = na[0] * g[0] + nb[0] * g[1] + nc[0] * g[2];
            t[1][j] = na[1] * g[0] + nb[1] * g[1] + nc[1] * g[2];
            t[2][j] = na[2] * g[0] + nb[2] * g[1] + nc[2] * g[2];
        }
        let mut d = [[0f64; CHUNK]; 3];
        match (fast.lit_eye_point, fast.lit_eye_direction) {
            (Some(e), _) => {
                for k in 0..3 {
                    for j in 0..CHUNK {
                        d[k][j] = e[k] - p[k][j];
                    }
                }
            }
            (None, Some(direction)) => {
                for k in 0..3 {
                    d[k] = [direction[k]; CHUNK];
                }
            }
            (None, None) => return None,
        }
        let mut usable = [false; CHUNK];
        let mut clear = [false; CHUNK];
        let mut back = [0u32; CHUNK];
        for j in 0..CHUNK {
            let tt = t[0][j] * t[0][j] + t[1][j] * t[1][j] + t[2][j] * t[2][j];
            let dd = d[0][j] * d[0][j] + d[1][j] * d[1][j] + d[2][j] * d[2][j];
            let td = t[0][j] * d[0][j] + t[1][j] * d[1][j] + t[2][j] * d[2][j];
            usable[j] = tt > 1.0e-30 && tt < 1.0e30 && dd > 1.0e-30 && dd < 1.0e30;
            clear[j] = td * td > FACING_MARGIN * tt * dd;
            back[j] = if td < 0.0 { u32::MAX } else { 0 };
        }
        let recorded = row.facing.map(|plane| load_chunk(plane, x0, 0.0));
        if let Some(recorded) = recorded {
            for j in 0..CHUNK {
                back[j] = if recorded[j] < 0.0 { u32::MAX } else { 0 };
            }
        }
        // Non-short-circuit `&` and `|` on purpose: `&&`/`||` here compiled to a branch per lane.
        let given = recorded.is_some();
        let mut undecided = false;
        for j in 0..CHUNK {
            undecided |= written[j] & !(usable[j] & (given | clear[j]));
        }
        if undecided {
            return None;
        }
        let mut lane_n = [[0f32; CHUNK]; 3];
        let mut lane_v = [[0f32; CHUNK]; 3];
        for j in 0..CHUNK {
            let tf = [t[0][j] as f32, t[1][j] as f32, t[2][j] as f32];
            let df = [d[0][j] as f32, d[1][j] as f32, d[2][j] as f32];
            let t_len = (tf[0] * tf[0] + tf[1] * tf[1] + tf[2] * tf[2]).sqrt();
            let d_len = (df[0] * df[0] + df[1] * df[1] + df[2] * df[2]).sqrt();
            // Unusable lanes are unwritten (discarded): zero keeps them quiet.
            let t_scale = if usable[j] {
                select(back[j], -1.0, 1.0) / t_len
            } else {
                0.0
            };
            let d_scale = if usable[j] { 1.0 / d_len } else { 0.0 };
            for k in 0..3 {
                lane_n[k][j] = tf[k] * t_scale;
                lane_v[k][j] = df[k] * d_scale;
            }
        }
        Some(ChunkGeometry {
            n: lane_n,
            v: lane_v,
            back,
        })
    }

    /// Per-pixel geometry in f64 with the reference's operations (the decisions: facing,
    /// which lanes have a normal and an eye vector), rounded to f32 for the light loop.
    #[inline(always)]
    fn chunk_geometry_exact(&self, row: &RowInputs<'_>, x0: usize, p: &[[f64; CHUNK]; 3]) -> ChunkGeometry {
        let fast = &self.fast;
        let nm = self.normals_from_lighting.matrix;
        let (na, nb, nc) = (nm.x_axis.to_array(), nm.y_axis.to_array(), nm.z_axis.to_array());
        let mut n = [[0f64; CHUNK]; 3];
        let mut has_n = [false; CHUNK];
        if let Some(normal) = row.normal {
            let (n0, n1, n2) = (
                load_chunk(normal[0], x0, 0.0),
                load_chunk(normal[1], x0, 0.0),
                load_chunk(normal[2], x0, 0.0),
            );
            for j in 0..CHUNK {
                let g = [f64::from(n0[j]), f64::from(n1[j]), f64::from(n2[j])];
                // NormalMatrix::transform: to the space lit in, unit, (0, 0, 1) if
                // degenerate; then normalize3 as the lighting does.
                let t0 = na[0] * g[0] + nb[0] * g[1] + nc[0] * g[2];
                let t1 = na[1] * g[0] + nb[1] * g[1] + nc[1] * g[2];
                let t2 = na[2] * g[0] + nb[2] * g[1] + nc[2] * g[2];
                let len = (t0 * t0 + t1 * t1 + t2 * t2).sqrt();
                let ok = len > 0.0 && len < f64::INFINITY;
                let safe_len = if ok { len } else { 1.0 };
                let t = [
                    if ok { t0 / safe_len } else { 0.0 },
                    if ok { t1 / safe_len } else { 0.0 },
                    if ok { t2 / safe_len } else { 1.0 },
                ];
                let len2 = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
                has_n[j] = len2 > 0.0 && len2 < f64::INFINITY;
                let inv = if has_n[j] {
                    1.0 / if has_n[j] { len2 } else { 1.0 }
                } else {
                    0.0
                };
                for k in 0..3 {
                    n[k][j] = t[k] * inv;
                }
            }
        }
        let mut v = [[0f64; CHUNK]; 3];
        let mut has_v = [false; CHUNK];
        match (fast.lit_eye_point, fast.lit_eye_direction) {
            (Some(e), _) => {
                for j in 0..CHUNK {
                    let d = [e[0] - p[0][j], e[1] - p[1][j], e[2] - p[2][j]];
                    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    let ok = len > 0.0 && len < f64::INFINITY;
                    let inv = if ok { 1.0 / if ok { len } else { 1.0 } } else { 0.0 };
                    has_v[j] = ok;
                    for k in 0..3 {
                        v[k][j] = d[k] * inv;
                    }
                }
            }
            (None, Some(d)) => {
                for j in 0..CHUNK {
                    has_v[j] = true;
                    for k in 0..3 {
                        v[k][j] = d[k];
                    }
                }
            }
            (None, None) => {}
        }
        let mut back = [0u32; CHUNK];
        match row.facing {
            Some(plane) => {
                let recorded = load_chunk(plane, x0, 0.0);
                for j in 0..CHUNK {
                    back[j] = if recorded[j] < 0.0 { u32::MAX } else { 0 };
                }
            }
            None => {
                for j in 0..CHUNK {
                    let dot = n[0][j] * v[0][j] + n[1][j] * v[1][j] + n[2][j] * v[2][j];
                    back[j] = if has_v[j] && has_n[j] && dot < 0.0 { u32::MAX } else { 0 };
                }
            }
        }
        let mut lane_n = [[0f32; CHUNK]; 3];
        let mut lane_v = [[0f32; CHUNK]; 3];
        for k in 0..3 {
            for j in 0..CHUNK {
                lane_n[k][j] = (if back[j] != 0 { -n[k][j] } else { n[k][j] }) as f32;
                // No normal: no eye vector either (the reference skips the lights).
                lane_v[k][j] = if has_n[j] { v[k][j] as f32 } else { 0.0 };
            }
        }
        ChunkGeometry {
            n: lane_n,
            v: lane_v,
            back,
        }
    }
}

/// `if_set` where `mask` is all ones, `if_clear` where it is zero, as bit operations: a
/// plain `if` between two constants can compile to a select of *addresses* and per-lane
/// scalar loads, which kept the light loop from vectorising.
#[inline(always)]
fn select(mask: u32, if_set: f32, if_clear: f32) -> f32 {
    f32::from_bits((if_set.to_bits() & mask) | (if_clear.to_bits() & !mask))
}

/// `CHUNK` values of `plane` from `x0`, `fill` past its end: one fixed-size copy for whole
/// chunks (the common case), element by element for the row's tail.
#[inline(always)]
fn load_chunk<T: Copy>(plane: &[T], x0: usize, fill: T) -> [T; CHUNK] {
    let mut a = [fill; CHUNK];
    match plane.get(x0..x0 + CHUNK) {
        Some(whole) => a.copy_from_slice(whole),
        None => {
            for (dst, src) in a.iter_mut().zip(plane.get(x0..).unwrap_or(&[])) {
                *dst = *src;
            }
        }
    }
    a
}

/// Run `body` compiled for AVX2 + FMA when `simd` is set and the CPU has them (detected
/// once), otherwise as compiled for the baseline target. `body` must be `#[inline(always)]`
/// so its code lands in the feature-enabled function.
#[inline(always)]
fn with_simd<R>(simd: bool, body: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx2,fma")]
        unsafe fn avx2<R>(body: impl FnOnce() -> R) -> R {
            body()
        }
        if simd && avx2_available() {
            // SAFETY: the CPU supports AVX2 and FMA (checked at run time just above).
            return unsafe { avx2(body) };
        }
    }
    let _ = simd;
    body()
}

#[cfg(target_arch = "x86_64")]
fn avx2_available() -> bool {
    use std::sync::OnceLock;
    static AVX2: OnceLock<bool> = OnceLock::new();
    *AVX2.get_or_init(|| is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"))
}

/// Pixels per chunk of the fast pass: each chunk is straight-line code over `[f32; CHUNK]`
/// (and `[f64; CHUNK]` for the geometry) the compiler turns into vectors (one AVX2 register,
/// or two SSE ones, per f32 array).
pub const CHUNK: usize = 8;

/// One light's contribution to a chunk, specialised for its kind and for whether any
/// material has a specular term: branch-free selects over [`CHUNK`] lanes, accumulated into
/// `diffuse` and `specular` (light by light, in the scene's order). Positional lights take
/// the vector to the light, its length and the attenuation in f64 (so huge distances and
/// lights close to a far surface keep their precision), the rest is f32.
#[inline(always)]
fn light_chunk<const POSITIONAL: bool, const SPECULAR: bool>(
    light: &LaneLight,
    fast: &FastSetup,
    g: &ChunkGeometry,
    p: &[[f64; CHUNK]; 3],
    diffuse: &mut [[f32; CHUNK]; 3],
    specular: &mut [[f32; CHUNK]; 3],
) {
    let [c0, c1, c2] = light.attenuation;
    let [qx, qy, qz] = light.position;
    let [nx, ny, nz] = &g.n;
    let back = &g.back;
    let mut l = [[0f32; CHUNK]; 3];
    let mut att = [1f32; CHUNK];
    if POSITIONAL {
        let [px, py, pz] = p;
        for j in 0..CHUNK {
            let (dx, dy, dz) = (qx - px[j], qy - py[j], qz - pz[j]);
            let d = (dx * dx + dy * dy + dz * dz).sqrt();
            let usable = d > 0.0 && d < f64::INFINITY;
            let inv = if usable { 1.0 / d } else { 0.0 };
            let denom = c0 + c1 * d + c2 * d * d;
            let a = if denom > 0.0 && denom < f64::INFINITY {
                1.0 / denom
            } else {
                1.0
            };
            l[0][j] = (dx * inv) as f32;
            l[1][j] = (dy * inv) as f32;
            l[2][j] = (dz * inv) as f32;
            att[j] = a as f32;
        }
    } else {
        for j in 0..CHUNK {
            for k in 0..3 {
                l[k][j] = light.towards[k];
            }
        }
    }
    let mut weight = [0f32; CHUNK];
    let mut n_dot_l = [0f32; CHUNK];
    for j in 0..CHUNK {
        n_dot_l[j] = nx[j] * l[0][j] + ny[j] * l[1][j] + nz[j] * l[2][j];
        weight[j] = if n_dot_l[j] > 0.0 { n_dot_l[j] * att[j] } else { 0.0 };
    }
    for k in 0..3 {
        let (front, back_colour) = (light.diffuse[0][k], light.diffuse[1][k]);
        for j in 0..CHUNK {
            let kd = select(back[j], back_colour, front);
            diffuse[k][j] += weight[j] * kd;
        }
    }
    if SPECULAR {
        let [vx, vy, vz] = &g.v;
        let mut r_dot_v = [0f32; CHUNK];
        let mut base = [0f32; CHUNK];
        for j in 0..CHUNK {
            let two_ndl = 2.0 * n_dot_l[j];
            let r = [
                two_ndl * nx[j] - l[0][j],
                two_ndl * ny[j] - l[1][j],
                two_ndl * nz[j] - l[2][j],
            ];
            r_dot_v[j] = r[0] * vx[j] + r[1] * vy[j] + r[2] * vz[j];
            base[j] = if r_dot_v[j] > 1.0e-30 { r_dot_v[j] } else { 1.0e-30 };
        }
        let power = match fast.integer_power {
            Some((exponent, floor)) => pow_integer(base, exponent, floor),
            None => {
                let mut h = [0f32; CHUNK];
                for j in 0..CHUNK {
                    let shine = select(back[j], fast.shininess[1], fast.shininess[0]);
                    h[j] = pow_positive(base[j], shine);
                }
                h
            }
        };
        let mut highlight = [0f32; CHUNK];
        for j in 0..CHUNK {
            highlight[j] = if n_dot_l[j] > 0.0 && r_dot_v[j] > 0.0 {
                power[j] * att[j]
            } else {
                0.0
            };
        }
        for k in 0..3 {
            let (front, back_colour) = (light.specular[0][k], light.specular[1][k]);
            for j in 0..CHUNK {
                let ks = select(back[j], back_colour, front);
                specular[k][j] += highlight[j] * ks;
            }
        }
    }
}

/// `x^n` for positive `x` and an integer `n` in [1, 128] by repeated squaring over a whole
/// chunk (the exponent is the same for every lane, so the loop is uniform). Bases below
/// `floor` = `2^(-120/n)` ([`integer_power_floor`]) are raised to it first, so no intermediate power is subnormal (subnormal
/// products are slow on x86); the result there is ~2^-120 instead of smaller, an absolute
/// error below 1e-36. Relative error elsewhere <= 2 log2(n) + 1 roundings (< 1e-5).
/// The smallest base [`pow_integer`] takes for exponent `n`: `2^(-120/n)`, so `floor^n`
/// is about 2^-120, well inside f32's normal range.
fn integer_power_floor(n: u32) -> f32 {
    (-120.0 / n.max(1) as f32).exp2()
}

#[inline(always)]
fn pow_integer(x: [f32; CHUNK], n: u32, floor: f32) -> [f32; CHUNK] {
    let mut square = x.map(|v| if v > floor { v } else { floor });
    let mut result = [1f32; CHUNK];
    let mut rest = n;
    while rest > 0 {
        if rest & 1 != 0 {
            for j in 0..CHUNK {
                result[j] *= square[j];
            }
        }
        rest >>= 1;
        if rest > 0 {
            for j in 0..CHUNK {
                square[j] *= square[j];
            }
        }
    }
    result
}

/// `x^s` for normal positive `x` and `s` in [1, 16384], as `2^(s log2 x)` with polynomial
/// log2 and exp2 (branch-free, so it vectorises). Relative error <= 1e-5 (dominated by the
/// f32 rounding of `s log2 x`; the unit test sweeps it against f64 `powf`); results below
/// 2^-126 are flushed to (near) zero.
#[inline(always)]
fn pow_positive(x: f32, s: f32) -> f32 {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The specular share as the two-call path computes it: `shade_facing` on a copy of the
    /// setup whose materials keep only the specular term.
    fn specular_share_reference(setup: &LightingSetup<f64>, s: &Sample<f64>, facing: Facing) -> [f64; 3] {
        let material = match facing {
            Facing::Front => setup.front,
            Facing::Back => setup.back,
        };
        if material.specular == [0.0; 3] {
            return [0.0; 3];
        }
        let m = Material {
            ambient: [0.0; 3],
            diffuse: [0.0; 3],
            ..material
        };
        LightingSetup {
            front: m,
            back: m,
            ..setup.clone()
        }
        .shade_facing(s, facing)
    }

    #[test]
    fn polynomial_power_is_within_its_stated_bound() {
        // Relative error <= 1e-5 over bases in (0, 1.001] and exponents in [1, 16384] (the f32
        // rounding of y = s log2 x, |y| <= 126, dominates), absolute 1e-30 where flushed.
        let mut worst = 0f64;
        for si in 0..=60 {
            let s = 2f64.powf(14.0 * si as f64 / 60.0);
            for xi in 1..=2000 {
                let x = (1.001 * xi as f64 / 2000.0).powf(4.0);
                let (xf, sf) = (x as f32, s as f32);
                let exact = f64::from(xf).powf(f64::from(sf));
                let got = f64::from(pow_positive(xf, sf));
                let err = (got - exact).abs();
                worst = worst.max(err / exact.max(1e-30));
                assert!(err <= 1e-5 * exact + 1e-30, "{xf}^{sf}: {got} vs {exact}");
            }
        }
        println!("worst relative error of pow_positive: {worst:.2e}");
        assert!(worst > 0.0);
    }

    #[test]
    fn fused_phong_is_bit_identical_to_two_shade_calls() {
        let mut seed = 0x9e3779b97f4a7c15u64;
        let mut next = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0
        };
        let mut v3 = || [next(), next(), next()];
        let mut checked = 0;
        for case in 0..400 {
            let material = |spec: bool, v: &mut dyn FnMut() -> [f64; 3]| Material {
                ambient: v().map(f64::abs),
                diffuse: v().map(f64::abs),
                specular: if spec { v().map(f64::abs) } else { [0.0; 3] },
                shininess: 1.0 + v()[0].abs() * 20.0,
            };
            let lights = (0..case % 9)
                .map(|i| Light {
                    kind: if i % 2 == 0 {
                        LightKind::Directional { towards_light: v3() }
                    } else {
                        LightKind::Positional {
                            position: v3(),
                            attenuation: [1.0, v3()[0].abs(), if i % 3 == 0 { -5.0 } else { 0.1 }],
                        }
                    },
                    colour: v3().map(f64::abs),
                })
                .collect();
            let setup = LightingSetup {
                front: material(case % 4 != 0, &mut v3),
                back: material(case % 5 != 0, &mut v3),
                ambient_light: v3().map(f64::abs),
                lights,
                eye: if case % 3 == 0 {
                    Eye::Direction(v3())
                } else {
                    Eye::Point(v3())
                },
            };
            let normal = if case % 17 == 0 { [0.0; 3] } else { v3() };
            let sample = Sample { point: v3(), normal };
            for facing in [Facing::Front, Facing::Back] {
                let (lit, spec) = phong_and_specular_share(&setup, &sample, facing);
                let expected_lit = setup.shade_facing(&sample, facing);
                let expected_spec = specular_share_reference(&setup, &sample, facing);
                assert_eq!(
                    lit.map(f64::to_bits),
                    expected_lit.map(f64::to_bits),
                    "case {case} {facing:?}"
                );
                assert_eq!(
                    spec.map(f64::to_bits),
                    expected_spec.map(f64::to_bits),
                    "case {case} {facing:?}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 800);
    }

    #[test]
    fn integer_power_is_within_its_stated_bound_and_never_subnormal() {
        // Relative error <= 1e-5 against f64 powf for every integer exponent the fast path
        // takes; where x^n would fall below the floor the result is about 2^-120 (absolute
        // error < 1e-36) and no step is subnormal.
        let mut worst = 0f64;
        for n in 1..=MAX_INTEGER_SHININESS {
            let floor = integer_power_floor(n);
            assert!(f64::from(floor).powi(n as i32) >= 2f64.powi(-121), "n = {n}");
            for xi in (1..=4000).step_by(8) {
                let x: [f32; CHUNK] = std::array::from_fn(|j| ((1.001 * (xi + j) as f64 / 4000.0).powf(3.0)) as f32);
                let got = pow_integer(x, n, floor);
                for j in 0..CHUNK {
                    assert!(got[j].is_normal(), "{}^{n} = {}", x[j], got[j]);
                    let exact = f64::from(x[j]).powi(n as i32);
                    let err = (f64::from(got[j]) - exact).abs();
                    assert!(err <= 1e-5 * exact + 1e-36, "{}^{n}: {} vs {exact}", x[j], got[j]);
                    if exact > 1e-30 {
                        worst = worst.max(err / exact);
                    }
                }
            }
        }
        println!("worst relative error of pow_integer: {worst:.2e}");
        assert!(worst > 0.0);
    }

    /// A shader over a 64 x 64 perspective view in LC, lit by one light, for the geometry
    /// tests; `back` gives the back side its own material.
    fn geometry_shader() -> Shader {
        // OpenGL's perspective: 90 degrees, near 0.5, far 50.
        let (near, far) = (0.5, 50.0);
        let clip_from_lighting = DMat4::from_cols_array(&[
            1.0,
            0.0,
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
            0.0,
            0.0,
            0.0,
            (far + near) / (near - far),
            -1.0,
            0.0,
            0.0,
            2.0 * far * near / (near - far),
            0.0,
        ]);
        let device_from_clip = DMat4::from_cols_array(&[
            32.0, 0.0, 0.0, 0.0, 0.0, 32.0, 0.0, 0.0, 0.0, 0.0, -0.5, 0.0, 32.0, 32.0, 0.5, 1.0,
        ]);
        let setup = ShadingSetup {
            lights: vec![SceneLight::Directional {
                towards_light: [0.3, 0.5, 1.0],
                colour: [1.0; 3],
            }],
            ..ShadingSetup::default()
        };
        let spaces = ShadingSpaces {
            device_from_lighting: device_from_clip * clip_from_lighting,
            lighting_from_world: DMat4::IDENTITY,
            device_from_clip,
        };
        Shader::new(&setup, &spaces).expect("an invertible view")
    }

    #[test]
    fn filtered_facing_agrees_with_the_exact_path_and_declines_near_grazing() {
        // Random normals (and some within a hair of the view plane) at random depths: where
        // the filtered path decides a chunk, its facing masks equal the exact path's and its
        // f32 normal and eye vector are within 1e-6 of the exact ones; chunks with a pixel
        // closer to grazing than the margin go to the exact path.
        let shader = geometry_shader();
        let mut seed = 0x2545f4914f6cdd1du64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut decided, mut declined) = (0, 0);
        for case in 0..400 {
            let y = (case % 64) as u32;
            let depth: Vec<u32> = (0..CHUNK)
                .map(|_| (0.2 + 0.7 * next()) as f32)
                .map(|d| (f64::from(d) * 4294967296.0) as u32)
                .collect();
            let mut normal: [Vec<f32>; 3] = Default::default();
            for j in 0..CHUNK {
                let n = [next() * 2.0 - 1.0, next() * 2.0 - 1.0, next() * 2.0 - 1.0];
                for k in 0..3 {
                    normal[k].push(n[k] as f32);
                }
                if case % 5 == 0 && j == 3 {
                    // Perpendicular to the eye vector at this pixel: after rounding the
                    // normal to f32 the cosine is a few 1e-8 at most, below the margin's
                    // 1e-9 in some cases (declined) and above it in others (decided).
                    let x = 8.0 * (case % 8) as f64 + j as f64 + 0.5;
                    let p = shader.position(x as u32, y, f64::from(depth[j]) / 4294967296.0);
                    let v = -p;
                    let n = DVec3::new(v.y, -v.x, 0.0);
                    for k in 0..3 {
                        normal[k][j] = n[k] as f32;
                    }
                }
            }
            let x0 = 8 * (case % 8);
            let mut depth_row = vec![0u32; 64];
            depth_row[x0..x0 + CHUNK].copy_from_slice(&depth);
            let mut planes: [Vec<f32>; 3] = Default::default();
            for k in 0..3 {
                planes[k] = vec![0.0; 64];
                planes[k][x0..x0 + CHUNK].copy_from_slice(&normal[k]);
            }
            let row = RowInputs {
                y,
                depth: &depth_row,
                cs: None,
                normal: Some([&planes[0], &planes[1], &planes[2]]),
                facing: None,
                st: None,
            };
            let p: [[f64; CHUNK]; 3] = std::array::from_fn(|k| {
                std::array::from_fn(|j| shader.position((x0 + j) as u32, y, f64::from(depth[j]) / 4294967296.0)[k])
            });
            let exact = shader.chunk_geometry_exact(&row, x0, &p);
            match shader.chunk_geometry_filtered(&row, x0, &p, &[true; CHUNK]) {
                Some(fast) => {
                    decided += 1;
                    assert_eq!(fast.back, exact.back, "case {case}");
                    for k in 0..3 {
                        for j in 0..CHUNK {
                            assert!((fast.n[k][j] - exact.n[k][j]).abs() <= 1e-6, "case {case}");
                            assert!((fast.v[k][j] - exact.v[k][j]).abs() <= 1e-6, "case {case}");
                        }
                    }
                }
                None => declined += 1,
            }
        }
        println!("filtered path decided {decided} chunks, declined {declined}");
        assert!(decided >= 300, "only {decided} of 400 chunks decided");
        assert!(declined >= 1, "no chunk near grazing was declined");
    }
}
