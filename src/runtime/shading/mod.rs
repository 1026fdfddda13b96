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
//! the *reference*. The default kernel ([`Shader::shade_row`], in `fast.rs`) is one fused
//! pass over a row of the G-buffer in vectors of 32 pixels (`lanes.rs`): each vector loads its
//! planes contiguously ([`RowInputs`]; unwritten pixels ride along and are masked to zero),
//! computes the position and the eye offset in f64, decides the facing from the sign of the
//! unnormalised f32 `N . (eye - P)` when it is clear by a 1e-5 margin on the cosine (40
//! times its rounding error; otherwise the vector takes the exact path with the reference's
//! f64 operations), normalises normal and eye vector in f32, runs every light (f32;
//! positional light vectors and attenuation in f64), fog and the final colour in registers,
//! and stores the colours once. Built three times:
//! AVX-512 (two registers per 32 f32 lanes) or AVX2 (four), chosen at run time by what the
//! CPU has, and element-wise loops for any target — with bit-identical results.
//! Stated bound (tests/runtime/shading_fast.rs, tests/runtime/shading_rows.rs): every channel within 1/4096
//! of the reference before quantisation, the 8-bit image equal or off by one on at most 2% of
//! covered pixels. Values outside the bound's domain (shininess outside [1, 1024],
//! coefficients above 1e6 or non-finite) run the reference instead.

use glam::{DMat4, DVec3, DVec4};

use crate::pipeline::face::Facing;
use crate::pipeline::lighting::{Eye, Light, LightKind, LightingSetup, Material, Sample};
use crate::pipeline::real::{add3, dot3, length3, normalize3, scale3, sub3};
use crate::pipeline::transform::NormalMatrix;

#[doc(hidden)]
pub mod fast;
#[doc(hidden)]
pub mod lanes;
pub mod language;
pub(crate) mod quads;
pub mod reference;

use fast::FastSetup;
pub use fast::{simd_build, RowInputs};

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
/// within the bound stated in the module documentation; `Simd`, `Avx2` and `Portable` give
/// bit-identical results (same IEEE operations in the same order, no fused multiply-add).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ShadingKernel {
    /// f32 lanes on AVX-512 or AVX2 registers when the CPU has them (detected at run
    /// time), otherwise the portable loop.
    #[default]
    Simd,
    /// The same f32 lanes on AVX2 registers even where the CPU has AVX-512 (the portable
    /// loop where it has no AVX2): to compare the builds.
    Avx2,
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
                // A zero normal stays zero (ambient light only, `pipeline::lighting`): the
                // API zeroes `N` given under a singular M (seed 000 9.4).
                let normal = px
                    .normal
                    .and_then(|n| match self.normals_from_lighting.transform(DVec3::from_array(n)) {
                        (t, true) => Some(t.to_array()),
                        (_, false) => None,
                    })
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
/// are bit-identical to evaluating `shade_facing` twice (tests/runtime/shading_phong.rs
/// checks), while the shared work (normal, eye vector, light vectors, attenuation, the
/// power) is done once.
#[doc(hidden)]
pub fn phong_and_specular_share(setup: &LightingSetup<f64>, s: &Sample<f64>, facing: Facing) -> ([f64; 3], [f64; 3]) {
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
