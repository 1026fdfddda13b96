//! The deterministic scenes that `primflow bench`, `primflow accuracy`, the tests, the
//! examples and the criterion benches share: the benchmark workloads (their geometry for the
//! JIT and, where llvmpipe has a twin, for llvmpipe), the effects series, the random
//! generator they draw from and the frame comparison they are checked with.
//!
//! Invariant: a generator's output depends only on its arguments (each workload seeds its
//! own [`Lcg`]), so every run, thread count and tile size renders the same scene, and the
//! JIT, the hand-written kernels and llvmpipe draw the same geometry.

use std::sync::Arc;

use serde::Serialize;

use crate::handwritten::Flavor;
use crate::ir::Program;
use crate::runtime::shading::{Fog, SceneLight, SurfaceMaterial, Texture};
use crate::runtime::{Frame, Renderer, Value};

/// The bench's frame size (pixels square), and llvmpipe's.
pub const SIZE: u32 = 512;

/// One benchmark scene: instances submitted to a renderer.
pub(crate) struct Workload {
    pub(crate) name: String,
    pub(crate) build: Box<dyn Fn(&mut Renderer)>,
    pub(crate) primitives: usize,
    /// The hand-written forms that exist for it (screen_triangle, polygon and sphere have all
    /// three, NURB surface scalar and AVX2); empty: the JIT's figures are shown alone.
    pub(crate) handwritten: &'static [Flavor],
    /// The same geometry for llvmpipe, `SIZE` pixels square, for the workloads with
    /// reference llvmpipe figures (see [`llvmpipe`]).
    pub(crate) gl: Option<Box<dyn Fn() -> GlScene>>,
}

pub(crate) const ALL_FLAVORS: [Flavor; 3] = [Flavor::Scalar, Flavor::Sse, Flavor::Avx2];

/// (name, interpolation kind) of the four shading parameters of the fill and small workloads.
pub(crate) fn bind(r: &mut Renderer, kind: Option<&str>, k: usize) {
    if let Some(kind) = kind {
        for c in 0..k {
            r.material_interp(&format!("p{c}"), kind, &[])
                .expect("bench scene: material_interp");
        }
    }
}

/// A screen_triangle of a workload: its `screen_vertex` (pixels, depth in [0, 1] with
/// larger nearer, w) and its `k` shading parameters at each vertex (vertex-major).
#[derive(Clone, Debug)]
pub(crate) struct Tri {
    pub v: [[f32; 4]; 3],
    pub params: Vec<f32>,
}

/// The triangle `v` with `k` parameters per vertex, drawn from `rng` in the order the
/// workloads have always drawn them.
pub(crate) fn tri_with_params(v: [[f32; 4]; 3], k: usize, rng: &mut Lcg) -> Tri {
    Tri {
        v,
        params: (0..3 * k).map(|_| rng.next() as f32).collect(),
    }
}

pub(crate) fn submit(r: &mut Renderer, t: &Tri, k: usize) {
    r.begin("screen_triangle").expect("bench scene: begin");
    r.rast_param("screen_vertex", &Value(t.v.iter().flatten().copied().collect()))
        .expect("bench scene: rast_param");
    for vertex in 0..3 {
        for c in 0..k {
            r.material(&format!("p{c}"), &Value(vec![t.params[vertex * k + c]]))
                .expect("bench scene: material");
        }
        r.sequence_point().expect("bench scene: sequence_point");
    }
    r.end().expect("bench scene: end");
}

/// The `fill` triangles at `size` x `size`: full-viewport quads back to front (every pixel
/// passes), per-vertex w in [1, 3].
fn fill_tris(layers: usize, size: u32, k: usize) -> Vec<Tri> {
    let mut rng = Lcg(1);
    let s = size as f32;
    let mut tris = vec![];
    for layer in 0..layers {
        let z = (layer + 1) as f32 / (layers + 1) as f32;
        let mut corner = |x: f32, y: f32| [x, y, z, 1.0 + 2.0 * rng.next() as f32];
        let q = [corner(0.0, 0.0), corner(s, 0.0), corner(s, s), corner(0.0, s)];
        tris.push(tri_with_params([q[0], q[1], q[2]], k, &mut rng));
        tris.push(tri_with_params([q[0], q[2], q[3]], k, &mut rng));
    }
    tris
}

/// The `small` triangles at `size` x `size`: 20 px area, random centre and rotation, back to
/// front.
fn small_tris(count: usize, size: u32, k: usize) -> Vec<Tri> {
    let mut rng = Lcg(2);
    // Equilateral, area 20: side^2 * sqrt(3)/4 = 20.
    let radius = (20.0f64 * 4.0 / 3f64.sqrt()).sqrt() / 3f64.sqrt();
    (0..count)
        .map(|i| {
            let z = (i + 1) as f32 / (count + 1) as f32;
            let size = f64::from(size);
            let (cx, cy) = (rng.next() * size, rng.next() * size);
            let a = rng.next() * std::f64::consts::TAU;
            let v = std::array::from_fn(|j| {
                let t = a + j as f64 * std::f64::consts::TAU / 3.0;
                [
                    (cx + radius * t.cos()) as f32,
                    (cy + radius * t.sin()) as f32,
                    z,
                    1.0 + 2.0 * rng.next() as f32,
                ]
            });
            tri_with_params(v, k, &mut rng)
        })
        .collect()
}

/// A workload of screen_triangles and its llvmpipe twin.
fn triangles(
    name: String,
    kind: Option<&'static str>,
    k: usize,
    handwritten: &'static [Flavor],
    make: impl Fn(u32) -> Vec<Tri> + Clone + 'static,
    primitives: usize,
) -> Workload {
    let for_gl = make.clone();
    Workload {
        name,
        primitives,
        handwritten,
        build: Box::new(move |r| {
            bind(r, kind, k);
            for t in make(r.options.width) {
                submit(r, &t, k);
            }
        }),
        gl: Some(Box::new(move || GlScene::Triangles {
            size: SIZE,
            tris: for_gl(SIZE),
            k,
            interpolation: kind,
        })),
    }
}

/// `fill`: full-viewport quads drawn back to front (every pixel passes), per-vertex w in [1, 3].
fn fill(layers: usize, kind: Option<&'static str>, k: usize) -> Workload {
    let label = kind.unwrap_or("none");
    triangles(
        format!("fill {label} K={k}"),
        kind,
        k,
        &ALL_FLAVORS,
        move |size| fill_tris(layers, size, k),
        layers * 2,
    )
}

/// `small`: triangles of 20 px area, random centre and rotation, back to front.
fn small(count: usize, k: usize) -> Workload {
    triangles(
        format!("small perspective_linear K={k}"),
        Some("perspective_linear"),
        k,
        &ALL_FLAVORS,
        move |size| small_tris(count, size, k),
        count,
    )
}

/// The sphere workloads' camera (vertical field of view in degrees, near, far) and spheres
/// (eye-space centre, radius).
const SPHERE_CAMERA: (f32, f32, f32) = (50.0, 1.0, 100.0);
fn sphere_list() -> Vec<([f32; 3], f32)> {
    let mut rng = Lcg(4);
    (0..20)
        .map(|i| {
            let (x, y) = ((i % 5) as f64 * 2.2 - 4.4, (i / 5) as f64 * 2.0 - 3.0);
            let z = -8.0 - rng.next() * 2.0;
            ([x as f32, y as f32, z as f32], 1.2 + 0.3 * rng.next() as f32)
        })
        .collect()
}

/// `sphere`: 20 spheres filling most of the viewport, per-pixel quadrics, normal returned
/// through the `implicit` interpolation.
fn spheres() -> Workload {
    Workload {
        name: "sphere implicit N".into(),
        primitives: 20,
        handwritten: &ALL_FLAVORS,
        build: Box::new(|r| {
            let (fovy, near, far) = SPHERE_CAMERA;
            r.perspective(fovy, near, far);
            r.material_interp("N", "implicit", &[])
                .expect("bench scene: material_interp");
            r.material("N", &Value(vec![0.0, 0.0, 1.0]))
                .expect("bench scene: material");
            for (center, radius) in sphere_list() {
                r.begin("sphere").expect("bench scene: begin");
                r.rast_param("center", &Value(center.to_vec()))
                    .expect("bench scene: center");
                r.rast_param("radius", &Value(vec![radius]))
                    .expect("bench scene: radius");
                r.end().expect("bench scene: end");
            }
        }),
        gl: Some(Box::new(|| GlScene::Spheres {
            size: SIZE,
            camera: SPHERE_CAMERA,
            spheres: sphere_list(),
            lit: false,
        })),
    }
}

/// `polygon hither`: quads (4 float parameters, perspective_linear) half of which cross the
/// hither plane and are clipped in the language.
fn polygons(count: usize) -> Workload {
    Workload {
        name: "polygon hither K=4".into(),
        primitives: count,
        handwritten: &ALL_FLAVORS,
        gl: None,
        build: Box::new(move |r| {
            r.perspective(60.0, 1.0, 100.0);
            bind(r, Some("perspective_linear"), 4);
            let mut rng = Lcg(5);
            for _ in 0..count {
                let (cx, cy) = (rng.next() * 8.0 - 4.0, rng.next() * 8.0 - 4.0);
                // Near corners at z = -0.5 (in front of the eye, behind the hither plane at 1).
                let (z_near, z_far) = (-0.5 - rng.next(), -6.0 - 4.0 * rng.next());
                r.begin("polygon").expect("bench scene: begin");
                for (x, y, z) in [
                    (cx, cy, z_far),
                    (cx + 2.0, cy, z_far),
                    (cx + 2.0, cy + 2.0, z_near),
                    (cx, cy + 2.0, z_near),
                ] {
                    for c in 0..4 {
                        r.material(&format!("p{c}"), &Value(vec![rng.next() as f32]))
                            .expect("bench scene: material");
                    }
                    r.vertex(x as f32, y as f32, z as f32, 1.0)
                        .expect("bench scene: vertex");
                }
                r.end().expect("bench scene: end");
            }
        }),
    }
}

/// `nurb`: bicubic patches tessellated to 0.5 px in the language.
fn nurbs(count: usize) -> Workload {
    Workload {
        name: "nurb bicubic tol=0.5".into(),
        primitives: count,
        handwritten: &[Flavor::Scalar, Flavor::Avx2],
        gl: None,
        build: Box::new(move |r| {
            r.perspective(50.0, 1.0, 100.0);
            let mut rng = Lcg(6);
            for _ in 0..count {
                let (cx, cy, cz) = (rng.next() * 8.0 - 4.0, rng.next() * 6.0 - 3.0, -10.0 - rng.next() * 4.0);
                r.begin("nurb_surface").expect("bench scene: begin");
                r.rast_param("tolerance", &Value(vec![0.5]))
                    .expect("bench scene: tolerance");
                for j in 0..4 {
                    for i in 0..4 {
                        r.rast_param("weight", &Value(vec![1.0])).expect("bench scene: weight");
                        let bump = rng.next() * 1.5 - 0.75;
                        let (x, y, z) = (cx + i as f64 * 0.8, cy + j as f64 * 0.8, cz + bump);
                        r.vertex(x as f32, y as f32, z as f32, 1.0)
                            .expect("bench scene: vertex");
                    }
                }
                r.end().expect("bench scene: end");
            }
        }),
    }
}

/// Layers of the fill workloads and of the effects series.
pub(crate) fn layers_for(quick: bool) -> usize {
    if quick {
        20
    } else {
        100
    }
}

pub(crate) fn workloads(quick: bool) -> Vec<Workload> {
    let layers = layers_for(quick);
    let small_count = if quick { 20_000 } else { 200_000 };
    vec![
        fill(layers, Some("perspective_linear"), 4),
        fill(layers, Some("linear"), 4),
        fill(layers, None, 0),
        small(small_count, 4),
        fill(layers, Some("perspective_linear"), 1),
        fill(layers, Some("perspective_linear"), 16),
        small(small_count, 0),
        spheres(),
        spheres_lit(),
        polygons(if quick { 500 } else { 5_000 }),
        nurbs(if quick { 20 } else { 50 }),
    ]
}

/// A tiny deterministic generator (a 64-bit LCG, the top 53 bits as a float in [0, 1)), so
/// every run benchmarks (and `accuracy` measures) the same scene.
pub struct Lcg(pub u64);
impl Lcg {
    pub fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A value in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

/// A `size` x `size` renderer holding workload `w`'s primitives.
pub(crate) fn scene(program: &Arc<Program>, size: u32, w: &Workload, count_writes: bool) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(size, size).expect("bench scene: image size");
    r.options.count_writes = count_writes;
    (w.build)(&mut r);
    r
}

/// The `fill` workload (full-viewport quads back to front) at `size` x `size`; the criterion
/// benches use it too.
pub fn fill_scene(program: &Arc<Program>, size: u32, layers: usize, kind: Option<&'static str>, k: usize) -> Renderer {
    scene(program, size, &fill(layers, kind, k), false)
}

/// The `small` workload (20 px triangles, perspective_linear) at `size` x `size`.
pub fn small_scene(program: &Arc<Program>, size: u32, count: usize, k: usize) -> Renderer {
    scene(program, size, &small(count, k), false)
}

/// The workloads of the other built-in primitives at `size` x `size` — `sphere implicit N`,
/// `sphere lit`, `polygon hither` (`polygons` quads) and `nurb` (`patches` patches) — each
/// with its name and the hand-written forms that exist for it; the criterion benches use them.
pub fn shape_scenes(
    program: &Arc<Program>,
    size: u32,
    polygons_count: usize,
    patches: usize,
) -> Vec<(String, Renderer, &'static [Flavor])> {
    [spheres(), spheres_lit(), polygons(polygons_count), nurbs(patches)]
        .into_iter()
        .map(|w| (w.name.clone(), scene(program, size, &w, false), w.handwritten))
        .collect()
}

/// Bit-for-bit equal depth and shading-parameter planes.
pub fn same_frame(a: &Frame, b: &Frame) -> bool {
    a.same_buffers(b)
}

/// `sphere lit`: the sphere workload with one light and a specular highlight, so the timed
/// frame includes the deferred shading pass (llvmpipe's sphere figure is a lit fragment
/// shader). Built from [`spheres`] so it shares its geometry and kernels.
fn spheres_lit() -> Workload {
    let mut w = spheres();
    w.name = "sphere lit (diffuse + specular)".into();
    w.gl = Some(Box::new(|| GlScene::Spheres {
        size: SIZE,
        camera: SPHERE_CAMERA,
        spheres: sphere_list(),
        lit: true,
    }));
    let geometry = std::mem::replace(&mut w.build, Box::new(|_| {}));
    w.build = Box::new(move |r| {
        geometry(r);
        r.shading_setup.front = SurfaceMaterial {
            ka: 1.0,
            kd: 0.8,
            ks: 0.5,
            shininess: 32.0,
            specular_colour: [1.0; 3],
        };
        r.shading_setup.lights.push(SceneLight::Directional {
            towards_light: [0.4, 0.6, 1.0],
            colour: [1.0; 3],
        });
    });
    w
}

/// The geometry of a workload as llvmpipe draws it.
pub(crate) enum GlScene {
    /// Screen triangles on a `size` x `size` target with `k` parameters per vertex,
    /// interpolated as the JIT's `interpolation` kind (`None`: no parameters).
    Triangles {
        size: u32,
        tris: Vec<Tri>,
        k: usize,
        interpolation: Option<&'static str>,
    },
    /// Spheres (eye-space centre, radius) seen through a perspective camera (vertical field
    /// of view in degrees, near, far), shaded by their normal or lit.
    Spheres {
        size: u32,
        camera: (f32, f32, f32),
        spheres: Vec<([f32; 3], f32)>,
        lit: bool,
    },
}

/// Which deferred-shading effects one frame of the effects series turns on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct EffectSet {
    /// Number of lights (half directional, half positional); 0 = unlit.
    pub lights: usize,
    pub fog: bool,
    pub texture: bool,
}

/// The frames of the effects series, in report order: none, each effect alone, all.
pub const EFFECT_SETS: [(&str, EffectSet); 5] = [
    (
        "none (colour = Cs)",
        EffectSet {
            lights: 0,
            fog: false,
            texture: false,
        },
    ),
    (
        "8 lights",
        EffectSet {
            lights: 8,
            fog: false,
            texture: false,
        },
    ),
    (
        "fog",
        EffectSet {
            lights: 0,
            fog: true,
            texture: false,
        },
    ),
    (
        "texture",
        EffectSet {
            lights: 0,
            fog: false,
            texture: true,
        },
    ),
    (
        "8 lights + fog + texture",
        EffectSet {
            lights: 8,
            fog: true,
            texture: true,
        },
    ),
];

/// The fog colour of the effects series (tests check colours move towards it).
pub const EFFECTS_FOG_COLOUR: [f64; 3] = [0.6, 0.7, 0.9];

/// The scene of the effects series: `layers` full-viewport quads drawn back to front (the
/// `fill` workload's geometry, device coordinates, every pixel visible), with a colour `Cs`,
/// a normal `N` and texture coordinates `st` interpolated perspective-correctly; then the
/// effects of `set`. Every set renders the same primitives with the same kernel, so frames
/// differ only in the shading pass.
pub fn effects_scene(program: &Arc<Program>, size: u32, layers: usize, set: EffectSet) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(size, size).expect("bench scene: image size");
    for name in ["Cs", "N", "st"] {
        r.material_interp(name, "perspective_linear", &[])
            .expect("bench scene: material_interp");
    }
    let s = size as f32;
    let mut rng = Lcg(7);
    for layer in 0..layers {
        let z = (layer + 1) as f32 / (layers + 1) as f32;
        let corners = [(0.0, 0.0), (s, 0.0), (s, s), (0.0, s)];
        let w: Vec<f32> = (0..4).map(|_| 1.0 + 2.0 * rng.next() as f32).collect();
        let mut corner_values = vec![];
        for (c, &(x, y)) in corners.iter().enumerate() {
            let cs = [0.3 + 0.7 * rng.next(), 0.3 + 0.7 * rng.next(), 0.3 + 0.7 * rng.next()];
            let n = [rng.next() - 0.5, rng.next() - 0.5, 1.0];
            let st = [(c == 1 || c == 2) as u8 as f64, (c >= 2) as u8 as f64];
            corner_values.push(([x, y, z, w[c]], cs, n, st));
        }
        for tri in [[0, 1, 2], [0, 2, 3]] {
            r.begin("screen_triangle").expect("bench scene: begin");
            let v: Vec<f32> = tri.iter().flat_map(|&c| corner_values[c].0).collect();
            r.rast_param("screen_vertex", &Value(v))
                .expect("bench scene: rast_param");
            for &c in &tri {
                let (_, cs, n, st) = corner_values[c];
                for (name, value) in [("Cs", &cs[..]), ("N", &n[..]), ("st", &st[..])] {
                    r.material(name, &Value(value.iter().map(|&x| x as f32).collect()))
                        .expect("bench scene: material");
                }
                r.sequence_point().expect("bench scene: sequence_point");
            }
            r.end().expect("bench scene: end");
        }
    }
    let setup = &mut r.shading_setup;
    setup.front = SurfaceMaterial {
        ka: 1.0,
        kd: 0.8,
        ks: 0.5,
        shininess: 16.0,
        specular_colour: [1.0; 3],
    };
    let f = f64::from(size);
    for i in 0..set.lights {
        let t = i as f64 / set.lights.max(1) as f64 * std::f64::consts::TAU;
        let colour = [
            0.5 + 0.5 * t.cos(),
            0.5 + 0.5 * (t + 2.1).cos(),
            0.5 + 0.5 * (t + 4.2).cos(),
        ]
        .map(|c| c * 0.3);
        setup.lights.push(if i % 2 == 0 {
            SceneLight::Directional {
                towards_light: [t.cos() * 0.5, t.sin() * 0.5, 1.0],
                colour,
            }
        } else {
            SceneLight::Positional {
                position: [f * (0.5 + 0.4 * t.cos()), f * (0.5 + 0.4 * t.sin()), 2.0],
                colour,
                attenuation: [1.0, 0.0, 0.0],
            }
        });
    }
    if set.fog {
        // Device coordinates: distance from the eye is 1 - z (the nearest layer is at
        // z = layers / (layers + 1)), so fog from 0 to 0.5 tints every visible pixel.
        setup.fog = Some(Fog {
            colour: EFFECTS_FOG_COLOUR,
            start: 0.0,
            end: 0.5,
        });
    }
    if set.texture {
        setup.texture = Some(Texture {
            param: "st".into(),
            scale: 8.0,
            dark: 0.5,
        });
    }
    r
}
