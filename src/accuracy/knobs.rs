//! The knobs `primflow accuracy` sweeps, each on a standard scene, and their error figures.
//!
//! | knob | scene | settings | primary figure |
//! |---|---|---|---|
//! | sphere | a unit sphere filling most of the view | procedural (prims/sphere.prim), icosphere of 20 ... 81 920 triangles | silhouette error (px), normal error (deg) |
//! | nurb | a rational bicubic patch seen from above | prims/nurb_surface.prim's `tolerance` 8 ... 0.25 px | geometric error (px) |
//! | nurb_polynomial | the same patch with weights 1 | the same | geometric error (px) |
//! | interpolation | a textured plane at a grazing angle | perspective_linear; linear on 2 ... 512 triangles | texture-coordinate error |
//! | arithmetic | a jittered mesh of small triangles sharing edges | int 1/16 snap (library), fixed<32,16>, fixed<32,8>, f32, f64 | pixels unlike the exact rasteriser |
//! | lighting | a lit icosphere in a wide perspective | per-vertex Phong in LC, WC, DC | colour error |
//! | depth | a decal 2 mm above a floor, 1 to 300 m away | depth as fixed<32,32>, f32, fixed<24,24>, fixed<16,16>, f16-like | z-fighting pixels |
//! | shading | a floor and a sphere under every library light and the fog | each library surface | colour error of the f32 kernels against the f64 evaluator (`super::shading`) |
//! | antialiasing | a sphere on the axis (a disc) and triangles and slivers around it | 1 ... 16 samples, box and Gaussian resolve | resolved coverage against the exact area per pixel (`super::antialiasing`) |
//!
//! Every figure compares a setting's buffers with the [`reference`](super::reference)
//! frame of the same scene; the reference is rendered once per knob, untimed.

use glam::{DMat4, DVec3, Mat4, Vec3};

use crate::pipeline::factor::factor_view;
use crate::pipeline::lighting::{Eye, Light, LightKind, LightingSetup, Material, Sample};
use crate::pipeline::transform::{look_at_matrix, perspective_matrix};
use crate::runtime::{Frame, Renderer, Value};
use crate::workload::Lcg;

use super::reference::{self, ray_sphere, RefFrame};
use super::scene::{Camera, Interp, Item, ParamSpec, Patch, Scene, Sphere, Triangle};
use super::{Ctx, Knob, Metric, Output, Setting};

/// Read access to either renderer's buffers.
pub trait Buffers {
    fn size(&self) -> (u32, u32);
    /// Depth writes at pixel i (1 for a written pixel when writes were not counted).
    fn count(&self, i: usize) -> u32;
    fn covered(&self, i: usize) -> bool;
    fn depth(&self, i: usize) -> f64;
    /// Component `c` of shading parameter `name` at pixel i (0 if there is none).
    fn value(&self, name: &str, c: usize, i: usize) -> f64;
}

/// Pixel `i` (row-major, `width` per row) as the frame's (x, y).
fn pixel_of(frame: &Frame, i: usize) -> (u32, u32) {
    let width = frame.width.max(1) as usize;
    ((i % width) as u32, (i / width) as u32)
}

impl Buffers for Frame {
    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    fn count(&self, i: usize) -> u32 {
        let (x, y) = pixel_of(self, i);
        self.write_count_at(x, y)
            .unwrap_or_else(|| u32::from(self.written(x, y)))
    }
    fn covered(&self, i: usize) -> bool {
        let (x, y) = pixel_of(self, i);
        self.written(x, y)
    }
    fn depth(&self, i: usize) -> f64 {
        let (x, y) = pixel_of(self, i);
        f64::from(self.depth_at(x, y).unwrap_or(0)) / 4294967296.0
    }
    fn value(&self, name: &str, c: usize, i: usize) -> f64 {
        let (x, y) = pixel_of(self, i);
        self.param(name)
            .and_then(|p| self.plane_at(p.first_plane + c as u32, x, y))
            .map_or(0.0, f64::from)
    }
}

impl Buffers for RefFrame {
    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    fn count(&self, i: usize) -> u32 {
        self.count[i]
    }
    fn covered(&self, i: usize) -> bool {
        self.count[i] > 0
    }
    fn depth(&self, i: usize) -> f64 {
        self.depth[i]
    }
    fn value(&self, name: &str, c: usize, i: usize) -> f64 {
        self.param(name).map_or(0.0, |(first, _)| self.planes[first + c][i])
    }
}

fn buffers(out: &Output) -> &dyn Buffers {
    match out {
        Output::Jit(f) => f,
        Output::Reference(r) => r,
    }
}

/// Pixel centre of index i.
fn centre(i: usize, width: u32) -> (f64, f64) {
    ((i as u32 % width) as f64 + 0.5, (i as u32 / width) as f64 + 0.5)
}

/// The scene sizes: the quick run's, or three times larger in each direction.
fn size(quick: bool, w: u32, h: u32) -> (u32, u32) {
    if quick {
        (w, h)
    } else {
        (w * 3, h * 3)
    }
}

/// What every knob needs to know about the run.
pub struct Scenes {
    pub quick: bool,
    pub has_sphere_prim: bool,
    pub has_nurb_prim: bool,
}

impl Scenes {
    pub fn new(quick: bool, ctx: &Ctx) -> Result<Scenes, String> {
        Ok(Scenes {
            quick,
            has_sphere_prim: ctx.has_primitive("sphere"),
            has_nurb_prim: ctx.has_primitive("nurb_surface"),
        })
    }
}

/// Every knob, in the order of the issue.
pub fn all<'a>(scenes: &'a Scenes, quick: bool, ctx: &Ctx) -> Vec<Knob<'a>> {
    vec![
        sphere_knob(scenes, quick),
        nurb_knob(
            scenes,
            quick,
            "nurb",
            "NURB patch (rational): tessellation tolerance (geometric error)",
            standard_patch(),
        ),
        nurb_knob(
            scenes,
            quick,
            "nurb_polynomial",
            "NURB patch (polynomial, weights 1): tessellation tolerance (geometric error)",
            polynomial_patch(),
        ),
        interpolation_knob(quick),
        arithmetic_knob(quick),
        lighting_knob(quick),
        depth_knob(quick),
        super::shading::shading_knob(ctx, quick),
        super::antialiasing::antialiasing_knob(quick),
    ]
}

// ---------------------------------------------------------------------------------------
// Meshes

/// A triangle mesh with outward winding (counter-clockwise seen from outside).
#[derive(Clone, Debug)]
pub struct Mesh {
    pub positions: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// The unit icosphere: an icosahedron (20 triangles) subdivided `level` times, 20 * 4^level
/// triangles, every vertex on the sphere.
pub fn icosphere(level: u32) -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut positions: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut midpoints = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(triangles.len() * 4);
        let mut mid = |a: u32, b: u32, positions: &mut Vec<DVec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                positions.push(((positions[a as usize] + positions[b as usize]) * 0.5).normalize());
                positions.len() as u32 - 1
            })
        };
        for [a, b, c] in triangles {
            let ab = mid(a, b, &mut positions);
            let bc = mid(b, c, &mut positions);
            let ca = mid(c, a, &mut positions);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    // Make every triangle wind outward.
    for t in &mut triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        if (b - a).cross(c - a).dot(a + b + c) < 0.0 {
            t.swap(1, 2);
        }
    }
    Mesh { positions, triangles }
}

/// Whether the outward-wound world triangle faces the eye.
fn front_facing(eye: DVec3, p: [DVec3; 3]) -> bool {
    (p[1] - p[0]).cross(p[2] - p[0]).dot(eye - p[0]) > 0.0
}

/// The front-facing triangles of a sphere mesh (unit mesh scaled to `s`) as device-space
/// triangles with per-vertex values from `values(vertex index, world point)`.
fn mesh_triangles(
    camera: &Camera,
    s: &Sphere,
    mesh: &Mesh,
    screen: &[[f64; 4]],
    values: &dyn Fn(usize) -> Vec<f64>,
) -> Vec<Item> {
    let mut items = Vec::with_capacity(mesh.triangles.len() / 2 + 1);
    for t in &mesh.triangles {
        let p = t.map(|i| s.centre + mesh.positions[i as usize] * s.radius);
        if !front_facing(camera.eye, p) {
            continue;
        }
        items.push(Item::Triangle(Triangle {
            vertices: t.map(|i| screen[i as usize]),
            values: t.map(|i| values(i as usize)),
        }));
    }
    items
}

// ---------------------------------------------------------------------------------------
// Knob 1: sphere

fn sphere_setup(quick: bool) -> (Camera, Sphere) {
    let (w, h) = size(quick, 128, 128);
    let camera = Camera::perspective(w, h, DVec3::new(0.6, 0.8, 3.2), DVec3::ZERO, DVec3::Y, 40.0, 0.1, 100.0)
        .expect("the sphere camera is valid");
    let sphere = Sphere {
        centre: DVec3::ZERO,
        radius: 1.0,
        normal_param: Some("N".into()),
    };
    (camera, sphere)
}

/// Distance in pixels from device point (x, y) to the sphere's silhouette, along the line
/// from the projected centre (the silhouette is star-shaped about it): bisection on the
/// ray-hits-sphere predicate.
pub fn silhouette_distance(camera: &Camera, s: &Sphere, x: f64, y: f64) -> f64 {
    let c = camera.screen(s.centre);
    let (dx, dy) = (x - c[0], y - c[1]);
    let r = (dx * dx + dy * dy).sqrt();
    if r == 0.0 {
        return 0.0;
    }
    let (ux, uy) = (dx / r, dy / r);
    let inside = |t: f64| ray_sphere(camera.eye, camera.ray(c[0] + ux * t, c[1] + uy * t), s).is_some();
    let (mut lo, mut hi) = (0.0, r.max(1.0));
    while inside(hi) {
        hi *= 2.0;
        if hi > 1e7 {
            return 0.0;
        }
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if inside(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (0.5 * (lo + hi) - r).abs()
}

/// A renderer for one frame of `camera` whose current transform is the camera's
/// `device_from_world` (rounded to f32, the API's precision), with no model or view stack:
/// world, object and lighting coordinates are then one space, so a primitive's points and
/// its `implicit` normals come back in world coordinates, where the reference works.
pub(super) fn world_renderer(ctx: &Ctx, camera: &Camera) -> Result<Renderer, String> {
    let mut r = Renderer::new(ctx.program.clone());
    r.set_image_size(camera.width, camera.height)
        .map_err(|e| e.to_string())?;
    r.set_transform(camera.device_from_world.as_mat4());
    Ok(r)
}

/// Close the instances of a renderer filled by hand: any API warning is a failure (an
/// accuracy figure of a half-submitted scene would mean nothing).
pub(super) fn no_warnings(r: &mut Renderer) -> Result<(), String> {
    match r.take_warnings().first() {
        Some(w) => Err(w.to_string()),
        None => Ok(()),
    }
}

/// The procedural sphere (prims/sphere.prim) of `s` under `camera`, its normal bound to
/// `N` by `implicit` interpolation.
fn procedural_sphere(ctx: &Ctx, camera: &Camera, s: &Sphere) -> Result<Renderer, String> {
    let issue = |e: crate::runtime::ApiIssue| e.to_string();
    let mut r = world_renderer(ctx, camera)?;
    r.material_interp("N", "implicit", &[]).map_err(issue)?;
    // The value before the first write; the sphere replaces it at every pixel it covers.
    r.material("N", &Value(vec![0.0, 0.0, 1.0])).map_err(issue)?;
    r.begin("sphere").map_err(issue)?;
    let centre = s.centre.as_vec3().to_array().to_vec();
    r.rast_param("center", &Value(centre)).map_err(issue)?;
    r.rast_param("radius", &Value(vec![s.radius as f32])).map_err(issue)?;
    r.end().map_err(issue)?;
    no_warnings(&mut r)?;
    Ok(r)
}

/// Knob 1. Every setting renders the same unit sphere under the same camera: the
/// procedural sphere (a quadric per pixel, its normal from the `implicit` interpolation)
/// and icosphere tessellations of 20 ... 81 920 triangles (per-vertex normals,
/// perspective-correct; back faces culled on the host). Silhouette error: for every pixel
/// whose coverage differs from the reference's analytic ray casting, the distance of its
/// centre from the true silhouette (so a pixel centre 0.01 px from the rim that flips
/// counts 0.01 px, not a whole pixel). Normal error: the angle between the returned normal
/// and the analytic one, over the pixels both cover.
fn sphere_knob<'a>(scenes: &'a Scenes, quick: bool) -> Knob<'a> {
    let (camera, sphere) = sphere_setup(quick);
    let params = vec![ParamSpec {
        name: "N".into(),
        components: 3,
        interp: Interp::Perspective,
    }];
    let mut reference_scene = Scene::new(camera.width, camera.height, params.clone());
    reference_scene.camera = Some(camera.clone());
    reference_scene.items.push(Item::Sphere(sphere.clone()));
    let reference = reference::render(&reference_scene);

    let mut settings = vec![];
    let mut missing = vec![];
    if scenes.has_sphere_prim {
        let (camera, sphere) = (camera.clone(), sphere.clone());
        settings.push(Setting::new(PROCEDURAL_SPHERE, move |ctx: &mut Ctx| {
            let r = procedural_sphere(ctx, &camera, &sphere)?;
            Ok(Output::Jit(ctx.render(&r)?))
        }));
    } else {
        missing.push("procedural sphere: the library has no `sphere` primitive (prims/sphere.prim)".into());
    }
    let levels = if quick { 0..=5 } else { 0..=6 };
    for level in levels {
        let mesh = icosphere(level);
        let (camera, sphere, params) = (camera.clone(), sphere.clone(), params.clone());
        let label = format!("tessellated {} tris", mesh.triangles.len());
        settings.push(Setting::new(label, move |ctx: &mut Ctx| {
            let screen: Vec<[f64; 4]> = mesh
                .positions
                .iter()
                .map(|&p| camera.screen(sphere.centre + p * sphere.radius))
                .collect();
            let mut scene = Scene::new(camera.width, camera.height, params.clone());
            scene.items = mesh_triangles(&camera, &sphere, &mesh, &screen, &|i| {
                mesh.positions[i].to_array().to_vec()
            });
            let r = scene.submit(&ctx.program, "screen_triangle")?;
            Ok(Output::Jit(ctx.render(&r)?))
        }));
    }
    Knob {
        name: "sphere",
        title: "sphere: procedural vs tessellated (silhouette error)",
        settings,
        measure: Box::new(move |_, out| {
            let b = buffers(out);
            let mut silhouette = vec![];
            let mut normal = vec![];
            for i in 0..reference.count.len() {
                let (x, y) = centre(i, reference.width);
                match (b.covered(i), reference.covered(i)) {
                    (true, true) => {
                        let n = DVec3::new(b.value("N", 0, i), b.value("N", 1, i), b.value("N", 2, i));
                        let m = DVec3::new(
                            reference.value("N", 0, i),
                            reference.value("N", 1, i),
                            reference.value("N", 2, i),
                        );
                        normal.push(angle_degrees(n, m));
                    }
                    (false, false) => {}
                    _ => silhouette.push(silhouette_distance(&camera, &sphere, x, y)),
                }
            }
            Ok(vec![
                Metric::of("silhouette", "px", &silhouette),
                Metric::of("normal", "deg", &normal),
            ])
        }),
        missing,
    }
}

/// The label of knob 1's procedural setting.
pub const PROCEDURAL_SPHERE: &str = "procedural (sphere.prim)";

/// The angle between `n` (any length) and the unit vector `m`, in degrees; 180 for a zero
/// `n` (no normal at all is as wrong as it gets). The angle comes from atan2 of the cross
/// and dot products, which keeps its digits for tiny angles where acos of a dot product
/// near 1 would round to 0 (the procedural sphere's normals are off by ~1e-5 degrees).
pub fn angle_degrees(n: DVec3, m: DVec3) -> f64 {
    if n.length_squared() == 0.0 || !n.is_finite() {
        return 180.0;
    }
    n.cross(m).length().atan2(n.dot(m)).to_degrees()
}

// ---------------------------------------------------------------------------------------
// Knob 2: NURB surface

/// The standard patch: a rational bicubic bump over [-1, 1]^2, heavier in the middle.
pub fn standard_patch() -> Patch {
    let mut points = [[DVec3::ZERO; 4]; 4];
    let mut weights = [[1.0; 4]; 4];
    for (i, row) in points.iter_mut().enumerate() {
        for (j, p) in row.iter_mut().enumerate() {
            let inner_i = i == 1 || i == 2;
            let inner_j = j == 1 || j == 2;
            let height = match (inner_i, inner_j) {
                (true, true) => 0.5,
                (false, false) => -0.1,
                _ => 0.15,
            };
            *p = DVec3::new(-1.0 + 2.0 * i as f64 / 3.0, height, -1.0 + 2.0 * j as f64 / 3.0);
            if inner_i && inner_j {
                weights[i][j] = 2.0;
            }
        }
    }
    Patch {
        points,
        weights,
        uv_param: Some("uv".into()),
    }
}

/// The standard patch with every weight 1: a polynomial bicubic, the case for which
/// nurb_surface.prim's step-count bound is exact (up to perspective).
pub fn polynomial_patch() -> Patch {
    Patch {
        weights: [[1.0; 4]; 4],
        ..standard_patch()
    }
}

fn nurb_camera(quick: bool) -> Camera {
    let (w, h) = size(quick, 128, 128);
    Camera::perspective(
        w,
        h,
        DVec3::new(0.3, 3.2, 2.0),
        DVec3::new(0.0, 0.1, 0.0),
        DVec3::Y,
        45.0,
        0.1,
        100.0,
    )
    .expect("the patch camera is valid")
}

/// The parameter knob 2 binds on the NURB primitive: homogeneous texture coordinates
/// `(u / D, v / D, 1 / D)`, `D` the rational denominator of the patch.
///
/// Why homogeneous: nurb_surface.prim evaluates a shading parameter as the rational spline
/// of its control values, `sum B w d / sum B w`. Control values `d = (i/3, j/3, 1) / w`
/// turn that into `(sum B i/3, sum B j/3, sum B) / D = (u, v, 1) / D` (Bernstein
/// polynomials reproduce linear functions), so at every tessellation vertex the ratio of
/// the components is exactly the vertex's (u, v), whatever the weights. Between vertices
/// the primitive interpolates the three components perspective-correctly across each flat
/// triangle, and (c0 / c2, c1 / c2) is the parameter the tessellation assigns to the
/// pixel. Plain (u, v) control values would instead come out as `sum B w u_i / D`, not u,
/// for a rational patch.
pub const NURB_UV_PARAM: &str = "uvh";

/// The standard patch as one instance of prims/nurb_surface.prim with tessellation
/// tolerance `tolerance` px: control points in world coordinates through the camera's
/// transform (so the primitive receives their homogeneous device coordinates), weights per
/// point, and [`NURB_UV_PARAM`] per point.
fn procedural_patch(ctx: &Ctx, camera: &Camera, p: &Patch, tolerance: f64) -> Result<Renderer, String> {
    let issue = |e: crate::runtime::ApiIssue| e.to_string();
    let mut r = world_renderer(ctx, camera)?;
    r.material_interp(NURB_UV_PARAM, "perspective_linear", &[])
        .map_err(issue)?;
    r.material(NURB_UV_PARAM, &Value(vec![0.0, 0.0, 1.0])).map_err(issue)?;
    r.begin("nurb_surface").map_err(issue)?;
    r.rast_param("tolerance", &Value(vec![tolerance as f32]))
        .map_err(issue)?;
    // Sequence points u fastest: point (i, j) of the patch (i along u) is number 4 j + i.
    for j in 0..4 {
        for i in 0..4 {
            let w = p.weights[i][j];
            r.rast_param("weight", &Value(vec![w as f32])).map_err(issue)?;
            let uvh = [i as f64 / 3.0 / w, j as f64 / 3.0 / w, 1.0 / w];
            r.material(NURB_UV_PARAM, &Value(uvh.map(|c| c as f32).to_vec()))
                .map_err(issue)?;
            let q = p.points[i][j].as_vec3();
            r.vertex(q.x, q.y, q.z, 1.0).map_err(issue)?;
        }
    }
    r.end().map_err(issue)?;
    no_warnings(&mut r)?;
    Ok(r)
}

/// Knob 2 (`patch` is the rational [`standard_patch`] for knob `nurb`, its polynomial twin
/// for `nurb_polynomial`). prims/nurb_surface.prim tessellates the patch itself, at its
/// `tolerance` of 8 ... 0.25 px. Geometric error at a pixel both cover: the screen
/// distance between where the true surface point of the tessellation's (u, v) projects
/// and where the reference's (Newton inversion of the f64 patch at the pixel centre) does.
/// That is the screen displacement of everything attached to the surface by its parameters
/// (texture, the surface point itself), the figure the tolerance promises to bound.
pub fn nurb_knob<'a>(
    scenes: &'a Scenes,
    quick: bool,
    name: &'static str,
    title: &'static str,
    patch: Patch,
) -> Knob<'a> {
    let camera = nurb_camera(quick);
    let params = vec![ParamSpec {
        name: "uv".into(),
        components: 2,
        interp: Interp::Perspective,
    }];
    let mut reference_scene = Scene::new(camera.width, camera.height, params.clone());
    reference_scene.camera = Some(camera.clone());
    reference_scene.items.push(Item::Patch(patch.clone()));
    let reference = reference::render(&reference_scene);

    let mut settings = vec![];
    let mut missing = vec![];
    if scenes.has_nurb_prim {
        for tolerance in NURB_TOLERANCES {
            let (camera, patch) = (camera.clone(), patch.clone());
            settings.push(Setting::new(
                format!("tolerance {tolerance} px"),
                move |ctx: &mut Ctx| {
                    let r = procedural_patch(ctx, &camera, &patch, tolerance)?;
                    Ok(Output::Jit(ctx.render(&r)?))
                },
            ));
        }
    } else {
        missing.push("NURB tessellation: the library has no `nurb_surface` primitive (prims/nurb_surface.prim)".into());
    }
    Knob {
        name,
        title,
        settings,
        measure: Box::new(move |_, out| {
            let b = buffers(out);
            let mut geometric = vec![];
            let mut edge = 0u64;
            let total = reference.count.iter().filter(|&&c| c > 0).count() as u64;
            let xy = |u: f64, v: f64| {
                let s = camera.screen(patch.eval(u, v));
                glam::DVec2::new(s[0], s[1])
            };
            for i in 0..reference.count.len() {
                match (b.covered(i), reference.covered(i)) {
                    (true, true) => {
                        let h = [0, 1, 2].map(|c| b.value(NURB_UV_PARAM, c, i));
                        let truth = xy(reference.value("uv", 0, i), reference.value("uv", 1, i));
                        // A tessellation's (u, v) is inside the patch; the clamp only
                        // keeps rounding at its border from leaving the domain.
                        let (u, v) = ((h[0] / h[2]).clamp(0.0, 1.0), (h[1] / h[2]).clamp(0.0, 1.0));
                        geometric.push(if h[2] != 0.0 && u.is_finite() && v.is_finite() {
                            xy(u, v).distance(truth)
                        } else {
                            f64::INFINITY
                        });
                    }
                    (false, false) => {}
                    _ => edge += 1,
                }
            }
            Ok(vec![
                Metric::of("geometric", "px", &geometric),
                Metric::count("coverage differs", edge, total),
            ])
        }),
        missing,
    }
}

/// Knob 2's settings: prims/nurb_surface.prim's `tolerance`, in pixels.
pub const NURB_TOLERANCES: [f64; 6] = [8.0, 4.0, 2.0, 1.0, 0.5, 0.25];

// ---------------------------------------------------------------------------------------
// Knob 3: interpolation

/// The grazing textured plane: y = 0, x in [-4, 4], z from -0.5 to -40, seen from 0.3 above
/// it; texture coordinates u = across, v = along, cut into `strips` strips along z (two
/// triangles each).
fn grazing_plane(camera: &Camera, strips: usize, interp: Interp) -> Scene {
    let params = vec![ParamSpec {
        name: "uv".into(),
        components: 2,
        interp,
    }];
    let mut scene = Scene::new(camera.width, camera.height, params);
    let (near, far) = (-0.5, -40.0);
    let z_at = |k: usize| near + (far - near) * k as f64 / strips as f64;
    for k in 0..strips {
        let (z0, z1) = (z_at(k), z_at(k + 1));
        let corner = |x: f64, z: f64| {
            (
                camera.screen(DVec3::new(x, 0.0, z)),
                vec![(x + 4.0) / 8.0, (z - near) / (far - near)],
            )
        };
        let q = [corner(-4.0, z0), corner(4.0, z0), corner(4.0, z1), corner(-4.0, z1)];
        for t in [[0, 1, 2], [0, 2, 3]] {
            scene.items.push(Item::Triangle(Triangle {
                vertices: t.map(|i| q[i].0),
                values: t.map(|i| q[i].1.clone()),
            }));
        }
    }
    scene
}

fn interpolation_knob<'a>(quick: bool) -> Knob<'a> {
    let (w, h) = size(quick, 192, 128);
    let camera = Camera::perspective(
        w,
        h,
        DVec3::new(0.0, 0.3, 0.0),
        DVec3::new(0.0, 0.0, -6.0),
        DVec3::Y,
        60.0,
        0.1,
        100.0,
    )
    .expect("the plane camera is valid");
    let reference = reference::render(&grazing_plane(&camera, 1, Interp::Perspective));
    let mut settings = vec![];
    let mut variants = vec![("perspective_linear, 2 tris".to_string(), 1, Interp::Perspective)];
    for strips in [1, 16, 256] {
        variants.push((format!("linear, {} tris", 2 * strips), strips, Interp::Linear));
    }
    for (label, strips, interp) in variants {
        let camera = camera.clone();
        settings.push(Setting::new(label, move |ctx: &mut Ctx| {
            let scene = grazing_plane(&camera, strips, interp);
            let r = scene.submit(&ctx.program, "screen_triangle")?;
            Ok(Output::Jit(ctx.render(&r)?))
        }));
    }
    Knob {
        name: "interpolation",
        title: "interpolation on a grazing plane (texture-coordinate error)",
        settings,
        measure: Box::new(move |_, out| {
            let b = buffers(out);
            let mut errors = vec![];
            let mut displacement = vec![];
            for i in 0..reference.count.len() {
                if b.covered(i) && reference.covered(i) {
                    let du = (b.value("uv", 0, i) - reference.value("uv", 0, i)).abs();
                    let dv = (b.value("uv", 1, i) - reference.value("uv", 1, i)).abs();
                    errors.push(du.max(dv));
                    // The same error as a displacement on screen: the pixel offset whose
                    // change of (u, v) is the error, through the inverse of the reference's
                    // Jacobian (forward differences where the neighbours are covered).
                    let w = reference.width as usize;
                    let right = i % w + 1 < w && reference.covered(i + 1);
                    let below = i + w < reference.count.len() && reference.covered(i + w);
                    if right && below {
                        let d = |c: usize, j: usize| reference.value("uv", c, j) - reference.value("uv", c, i);
                        let (ux, uy, vx, vy) = (d(0, i + 1), d(0, i + w), d(1, i + 1), d(1, i + w));
                        let det = ux * vy - uy * vx;
                        let eu = b.value("uv", 0, i) - reference.value("uv", 0, i);
                        let ev = b.value("uv", 1, i) - reference.value("uv", 1, i);
                        if det != 0.0 {
                            let px = (vy * eu - uy * ev) / det;
                            let py = (-vx * eu + ux * ev) / det;
                            displacement.push(px.hypot(py));
                        }
                    }
                }
            }
            Ok(vec![
                Metric::of("uv", "uv units", &errors),
                Metric::of("uv displacement", "px", &displacement),
            ])
        }),
        missing: vec![],
    }
}

// ---------------------------------------------------------------------------------------
// Knob 4: arithmetic of X, Y and the edge functions

/// A mesh of `cells` x `cells` jittered quads (two triangles each) over a `side`-pixel
/// image, one constant `id` per triangle (its index + 1), all at depth 0.5. Vertices are
/// f32 values (the reference sees exactly what the kernels see).
pub fn jittered_mesh(side: u32, cells: usize, seed: u64) -> Scene {
    let params = vec![ParamSpec {
        name: "id".into(),
        components: 1,
        interp: Interp::Constant,
    }];
    let mut scene = Scene::new(side, side, params);
    let mut rng = Lcg(seed);
    let margin = 4.0;
    let cell = (side as f64 - 2.0 * margin) / cells as f64;
    let grid: Vec<Vec<[f64; 2]>> = (0..=cells)
        .map(|i| {
            (0..=cells)
                .map(|j| {
                    let jitter = |r: &mut Lcg, k: usize| {
                        if k == 0 || k == cells {
                            0.0
                        } else {
                            (r.next() - 0.5) * 0.6 * cell
                        }
                    };
                    let x = margin + j as f64 * cell + jitter(&mut rng, j);
                    let y = margin + i as f64 * cell + jitter(&mut rng, i);
                    [x as f32 as f64, y as f32 as f64]
                })
                .collect()
        })
        .collect();
    for i in 0..cells {
        for j in 0..cells {
            let q = [grid[i][j], grid[i][j + 1], grid[i + 1][j + 1], grid[i + 1][j]];
            // Alternate the diagonal so edges of every direction occur.
            let tris = if (i + j) % 2 == 0 {
                [[0, 1, 2], [0, 2, 3]]
            } else {
                [[0, 1, 3], [1, 2, 3]]
            };
            for t in tris {
                let id = (scene.items.len() + 1) as f64;
                scene.items.push(Item::Triangle(Triangle {
                    vertices: t.map(|k| [q[k][0], q[k][1], 0.5, 1.0]),
                    values: [vec![id], vec![id], vec![id]],
                }));
            }
        }
    }
    scene
}

fn arithmetic_knob<'a>(quick: bool) -> Knob<'a> {
    let (side, _) = size(quick, 128, 128);
    let cells = if quick { 10 } else { 30 };
    let scene = jittered_mesh(side, cells, 7);
    let reference = reference::render(&scene);
    let mut settings = vec![];
    for (label, prim) in [
        ("int, 1/16 px snap (library)", "screen_triangle"),
        ("fixed<32,16>", "acc_tri_fixed16"),
        ("fixed<32,8>", "acc_tri_fixed8"),
        ("f32", "acc_tri_f32"),
    ] {
        let scene = scene.clone();
        settings.push(Setting::new(label, move |ctx: &mut Ctx| {
            let mut r = scene.submit(&ctx.program, prim)?;
            r.options.count_writes = true;
            Ok(Output::Jit(ctx.render(&r)?))
        }));
    }
    let f64_scene = scene.clone();
    settings.push(Setting::new("f64 (reference, Rust)", move |_ctx: &mut Ctx| {
        Ok(Output::Reference(reference::render(&f64_scene)))
    }));
    Knob {
        name: "arithmetic",
        title: "coverage arithmetic: X, Y and edge functions (pixels unlike the exact rasteriser)",
        settings,
        measure: Box::new(move |_, out| {
            let b = buffers(out);
            let total = reference.count.iter().filter(|&&c| c > 0).count() as u64;
            let (mut wrong, mut cracks, mut overdraw) = (0u64, 0u64, 0u64);
            for i in 0..reference.count.len() {
                let (got, want) = (b.count(i), reference.count[i]);
                let id_ok = want == 0 || b.value("id", 0, i) == (reference.item[i] + 1) as f64;
                if got != want || !id_ok {
                    wrong += 1;
                }
                if want > 0 && got == 0 {
                    cracks += 1;
                }
                if got >= 2 {
                    overdraw += 1;
                }
            }
            Ok(vec![
                Metric::count("coverage differs", wrong, total),
                Metric::count("cracks", cracks, total),
                Metric::count("overdraw", overdraw, total),
            ])
        }),
        missing: vec![],
    }
}

// ---------------------------------------------------------------------------------------
// Knob 5: lighting space

fn material(kd: f64, ks: f64) -> Material<f64> {
    Material {
        ambient: [0.1, 0.1, 0.1],
        diffuse: [kd, kd * 0.8, kd * 0.6],
        specular: [ks, ks, ks],
        shininess: 20.0,
    }
}

/// The lit scene's lights and materials in world coordinates, for an eye point `eye`.
fn lighting_setup(eye: Eye<f64>, light: [f64; 3]) -> LightingSetup<f64> {
    LightingSetup {
        front: material(0.6, 0.4),
        back: material(0.3, 0.0),
        ambient_light: [0.2, 0.2, 0.2],
        lights: vec![Light {
            kind: LightKind::Positional {
                position: light,
                attenuation: [1.0, 0.05, 0.01],
            },
            colour: [1.0, 0.9, 0.8],
        }],
        eye,
    }
}

/// Where per-vertex lighting happens.
#[derive(Clone, Copy, Debug)]
enum LightSpace {
    Lighting,
    World,
    Device,
}

fn lighting_knob<'a>(quick: bool) -> Knob<'a> {
    let (w, h) = size(quick, 128, 128);
    let eye = DVec3::new(1.3, 0.7, 1.6);
    let (fov, near, far) = (70.0, 0.1, 20.0);
    let camera = Camera::perspective(w, h, eye, DVec3::ZERO, DVec3::Y, fov, near, far).expect("valid camera");
    let clip_from_world = perspective_matrix(f64::to_radians(fov), w as f64 / h as f64, near, far)
        .expect("valid perspective")
        * look_at_matrix(eye, DVec3::ZERO, DVec3::Y);
    let light = DVec3::new(2.5, 3.0, 1.5);
    let sphere = Sphere {
        centre: DVec3::ZERO,
        radius: 1.0,
        normal_param: None,
    };
    let mesh = icosphere(if quick { 3 } else { 4 });
    let params = vec![ParamSpec {
        name: "Cs".into(),
        components: 3,
        interp: Interp::Perspective,
    }];
    let screen: Vec<[f64; 4]> = mesh.positions.iter().map(|&p| camera.screen(p)).collect();

    // The reference: every vertex lit in f64 world coordinates.
    let wc64 = lighting_setup(Eye::Point(eye.to_array()), light.to_array());
    let reference_colours: Vec<[f64; 3]> = mesh
        .positions
        .iter()
        .map(|&p| {
            wc64.shade(&Sample {
                point: p.to_array(),
                normal: p.to_array(),
            })
        })
        .collect();
    let mut reference_scene = Scene::new(w, h, params.clone());
    reference_scene.items = mesh_triangles(&camera, &sphere, &mesh, &screen, &|i| reference_colours[i].to_vec());
    let reference = reference::render(&reference_scene);

    let lighting_from_world = factor_view(&clip_from_world)
        .expect("a perspective look-at view is canonical")
        .lighting_from_world();
    let mut settings = vec![];
    for (label, space) in [
        ("LC (lighting coordinates)", LightSpace::Lighting),
        ("WC (world coordinates)", LightSpace::World),
        ("DC (device coordinates)", LightSpace::Device),
    ] {
        // The setup and the vertex transform of this space (set up once, like a pipeline
        // state change); the per-vertex work happens per frame, in f32.
        let (setup, point_from_world, normal_from_world, divide): (LightingSetup<f32>, DMat4, DMat4, bool) = match space
        {
            LightSpace::World => (wc64.to_f32(), DMat4::IDENTITY, DMat4::IDENTITY, false),
            LightSpace::Lighting => {
                let e = lighting_from_world;
                let s = lighting_setup(
                    Eye::Point(e.transform_point3(eye).to_array()),
                    e.transform_point3(light).to_array(),
                );
                (s.to_f32(), e, e.inverse().transpose(), false)
            }
            LightSpace::Device => {
                // Points through V and the divide; normals as tangent planes through V^-T;
                // the eye at infinity towards +z (nearer is larger z).
                let v = clip_from_world;
                let h = v * light.extend(1.0);
                let s = lighting_setup(Eye::Direction([0.0, 0.0, 1.0]), (h.truncate() / h.w).to_array());
                (s.to_f32(), v, v.inverse().transpose(), true)
            }
        };
        let point_m = point_from_world.as_mat4();
        let normal_m = normal_from_world.as_mat4();
        let (camera, mesh, screen, params, sphere) = (
            camera.clone(),
            mesh.clone(),
            screen.clone(),
            params.clone(),
            sphere.clone(),
        );
        settings.push(Setting::new(label, move |ctx: &mut Ctx| {
            let colours: Vec<[f32; 3]> = mesh
                .positions
                .iter()
                .map(|&p| {
                    let p = p.as_vec3();
                    let (point, normal) = light_space_sample(point_m, normal_m, divide, p, p);
                    setup.shade(&Sample { point, normal })
                })
                .collect();
            let mut scene = Scene::new(camera.width, camera.height, params.clone());
            scene.items = mesh_triangles(&camera, &sphere, &mesh, &screen, &|i| {
                colours[i].iter().map(|&c| c as f64).collect()
            });
            let r = scene.submit(&ctx.program, "screen_triangle")?;
            Ok(Output::Jit(ctx.render(&r)?))
        }));
    }
    Knob {
        name: "lighting",
        title: "per-vertex lighting space (colour error)",
        settings,
        measure: Box::new(move |_, out| {
            let b = buffers(out);
            let mut errors = vec![];
            for i in 0..reference.count.len() {
                if b.covered(i) && reference.covered(i) {
                    let e = (0..3)
                        .map(|k| (b.value("Cs", k, i) - reference.value("Cs", k, i)).abs())
                        .fold(0.0, f64::max);
                    errors.push(e);
                }
            }
            Ok(vec![Metric::of("colour", "colour units", &errors)])
        }),
        missing: vec![],
    }
}

/// A world point and normal taken to the lighting space in f32: `point_m` for points (with
/// the perspective divide for device space), `normal_m` (the inverse transpose) for the
/// normal, which in device space is the tangent plane through the point.
fn light_space_sample(point_m: Mat4, normal_m: Mat4, divide: bool, p: Vec3, n: Vec3) -> ([f32; 3], [f32; 3]) {
    if divide {
        let h = point_m * p.extend(1.0);
        let plane = normal_m * n.extend(-n.dot(p));
        ((h.truncate() / h.w).to_array(), plane.truncate().to_array())
    } else {
        (
            point_m.transform_point3(p).to_array(),
            normal_m.transform_vector3(n).to_array(),
        )
    }
}

// ---------------------------------------------------------------------------------------
// Knob 6: depth precision

/// Gap between the decal and the floor, in metres (scene units).
pub const DECAL_GAP: f64 = 0.002;

/// A floor (y = 0) and a decal strip DECAL_GAP above it, both from 1 to 300 units away,
/// cut into rows along z so triangles stay small; the decal is drawn first, so a depth tie
/// lets the floor through. `id` is 1 on the decal, 2 on the floor.
fn decal_scene(camera: &Camera) -> Scene {
    let params = vec![ParamSpec {
        name: "id".into(),
        components: 1,
        interp: Interp::Constant,
    }];
    let mut scene = Scene::new(camera.width, camera.height, params);
    let rows = 48;
    // Rows spaced geometrically: equal screen heights, roughly.
    let z_at = |k: usize| -(300f64 / 1.0).powf(k as f64 / rows as f64);
    for (id, y, half_width) in [(1.0, DECAL_GAP, 1.5), (2.0, 0.0, 6.0)] {
        let columns = if id == 1.0 { 2 } else { 8 };
        for k in 0..rows {
            let (z0, z1) = (z_at(k), z_at(k + 1));
            for c in 0..columns {
                let x0 = -half_width + 2.0 * half_width * c as f64 / columns as f64;
                let x1 = -half_width + 2.0 * half_width * (c + 1) as f64 / columns as f64;
                let q = [(x0, z0), (x1, z0), (x1, z1), (x0, z1)].map(|(x, z)| camera.screen(DVec3::new(x, y, z)));
                for t in [[0, 1, 2], [0, 2, 3]] {
                    scene.items.push(Item::Triangle(Triangle {
                        vertices: t.map(|i| q[i]),
                        values: [vec![id], vec![id], vec![id]],
                    }));
                }
            }
        }
    }
    scene
}

fn depth_knob<'a>(quick: bool) -> Knob<'a> {
    let (w, h) = size(quick, 192, 128);
    let camera = Camera::perspective(
        w,
        h,
        DVec3::new(0.0, 1.5, 0.0),
        DVec3::new(0.0, 0.9, -20.0),
        DVec3::Y,
        50.0,
        0.1,
        1000.0,
    )
    .expect("valid camera");
    let scene = decal_scene(&camera);
    let reference = reference::render(&scene);
    // The id of each item, to read the reference's visible surface.
    let item_id: Vec<f64> = scene
        .items
        .iter()
        .map(|it| match it {
            Item::Triangle(t) => t.values[2][0],
            _ => 0.0,
        })
        .collect();
    let mut settings = vec![];
    for (label, prim) in [
        ("fixed<32,32> (library)", "screen_triangle"),
        ("f32", "acc_depth_f32"),
        ("fixed<24,24>", "acc_depth_fixed24"),
        ("fixed<16,16>", "acc_depth_fixed16"),
        ("f16-like (11 bits)", "acc_depth_half"),
    ] {
        let scene = scene.clone();
        settings.push(Setting::new(label, move |ctx: &mut Ctx| {
            let r = scene.submit(&ctx.program, prim)?;
            Ok(Output::Jit(ctx.render(&r)?))
        }));
    }
    Knob {
        name: "depth",
        title: "depth precision: decal 2 mm above a floor, 1-300 m (z-fighting pixels)",
        settings,
        measure: Box::new(move |_, out| {
            let b = buffers(out);
            let decal_pixels = (0..reference.count.len())
                .filter(|&i| reference.covered(i) && item_id[reference.item[i] as usize] == 1.0)
                .count() as u64;
            let mut fighting = 0u64;
            let mut depth_errors = vec![];
            for i in 0..reference.count.len() {
                if !(b.covered(i) && reference.covered(i)) {
                    continue;
                }
                let want = item_id[reference.item[i] as usize];
                if b.value("id", 0, i) != want {
                    fighting += 1;
                }
                depth_errors.push((b.depth(i) - reference.depth(i)).abs());
            }
            Ok(vec![
                Metric::count("z-fighting", fighting, decal_pixels),
                Metric::of("depth", "depth units", &depth_errors),
            ])
        }),
        missing: vec![],
    }
}
