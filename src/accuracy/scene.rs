//! The scene description both renderers consume: a camera, shading parameters with their
//! interpolation, and items (device-space triangles, analytic spheres, rational Bezier
//! patches), all in f64.
//!
//! [`Scene::submit`] feeds the triangles to the JIT runtime through the primitive API (each
//! triangle as one instance of a screen-triangle primitive, its device coordinates rounded
//! to f32, the only precision the API carries); [`super::reference`] renders the same
//! description in f64. Spheres and patches have no JIT form here: a knob turns them into
//! triangles (its tessellation setting) or into a procedural primitive instance first.
//!
//! Conventions are the runtime's (docs/scene.md): device x, y in pixels with y down, pixel
//! (px, py) centred at (px + 0.5, py + 0.5), depth z/w in [0, 1] with LARGER NEARER.
//! Cameras are built from the geometry pipeline's own matrices
//! ([`crate::pipeline::transform`]), so `device_from_world` is exactly what the pipeline
//! would use.

use glam::{DMat4, DVec3, DVec4};

use crate::pipeline::transform::{device_from_clip, look_at_matrix, perspective_matrix, Viewport};
use crate::runtime::{Renderer, Value};

/// A perspective camera in f64.
#[derive(Clone, Debug)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub eye: DVec3,
    pub device_from_world: DMat4,
    pub world_from_device: DMat4,
}

impl Camera {
    /// Looking from `eye` at `centre`, vertical field of view `fov_y_degrees`, near and far
    /// distances. Fails (with a message) only on parameters the pipeline refuses.
    pub fn perspective(
        width: u32,
        height: u32,
        eye: DVec3,
        centre: DVec3,
        up: DVec3,
        fov_y_degrees: f64,
        near: f64,
        far: f64,
    ) -> Result<Camera, String> {
        let aspect = width as f64 / height as f64;
        let clip_from_camera =
            perspective_matrix(fov_y_degrees.to_radians(), aspect, near, far).map_err(|e| format!("{e:?}"))?;
        let viewport = Viewport {
            x0: 0.0,
            y0: 0.0,
            width: width as f64,
            height: height as f64,
        };
        let device_from_world = device_from_clip(viewport) * clip_from_camera * look_at_matrix(eye, centre, up);
        Ok(Camera {
            width,
            height,
            eye,
            device_from_world,
            world_from_device: device_from_world.inverse(),
        })
    }

    /// Homogeneous device coordinates of a world point.
    pub fn homogeneous(&self, p: DVec3) -> DVec4 {
        self.device_from_world * p.extend(1.0)
    }

    /// `[x/w, y/w, z/w, w]`: what a screen triangle takes per vertex.
    pub fn screen(&self, p: DVec3) -> [f64; 4] {
        let h = self.homogeneous(p);
        [h.x / h.w, h.y / h.w, h.z / h.w, h.w]
    }

    /// The unit direction of the ray from the eye through the device point (x, y).
    pub fn ray(&self, x: f64, y: f64) -> DVec3 {
        // Any depth on the ray will do; the near plane (depth 1) is well conditioned.
        let h = self.world_from_device * DVec4::new(x, y, 1.0, 1.0);
        (h.truncate() / h.w - self.eye).normalize()
    }

    /// Device depth (z/w) of a world point.
    pub fn depth(&self, p: DVec3) -> f64 {
        let h = self.homogeneous(p);
        h.z / h.w
    }
}

/// How a shading parameter is interpolated across a triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interp {
    Linear,
    Perspective,
    /// One value per item (the value at its last vertex).
    Constant,
}

impl Interp {
    fn api_name(self) -> &'static str {
        match self {
            Interp::Linear => "linear",
            Interp::Perspective => "perspective_linear",
            Interp::Constant => "constant",
        }
    }
}

#[derive(Clone, Debug)]
pub struct ParamSpec {
    pub name: String,
    pub components: usize,
    pub interp: Interp,
}

/// A triangle in device space: per vertex `[x/w, y/w, z/w, w]` and the values of every
/// shading parameter, concatenated in the scene's parameter order.
#[derive(Clone, Debug)]
pub struct Triangle {
    pub vertices: [[f64; 4]; 3],
    pub values: [Vec<f64>; 3],
}

/// A sphere in world space. The reference writes its unit world normal into the parameter
/// named `normal_param` (if the scene has one) and `constants` into the others.
#[derive(Clone, Debug)]
pub struct Sphere {
    pub centre: DVec3,
    pub radius: f64,
    pub normal_param: Option<String>,
}

/// A rational bicubic Bezier patch (a one-span NURB surface): control points in world space
/// with weights. The reference writes (u, v) into the parameter named `uv_param`.
#[derive(Clone, Debug)]
pub struct Patch {
    pub points: [[DVec3; 4]; 4],
    pub weights: [[f64; 4]; 4],
    pub uv_param: Option<String>,
}

impl Patch {
    /// The surface point at (u, v) in [0, 1]^2.
    pub fn eval(&self, u: f64, v: f64) -> DVec3 {
        let (bu, bv) = (bernstein3(u), bernstein3(v));
        let mut num = DVec3::ZERO;
        let mut den = 0.0;
        for i in 0..4 {
            for j in 0..4 {
                let c = bu[i] * bv[j] * self.weights[i][j];
                num += self.points[i][j] * c;
                den += c;
            }
        }
        num / den
    }
}

/// The four cubic Bernstein polynomials at t.
pub fn bernstein3(t: f64) -> [f64; 4] {
    let s = 1.0 - t;
    [s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t]
}

#[derive(Clone, Debug)]
pub enum Item {
    Triangle(Triangle),
    Sphere(Sphere),
    Patch(Patch),
}

/// One frame: size, camera (needed by spheres and patches), parameters, items in drawing
/// order.
#[derive(Clone, Debug)]
pub struct Scene {
    pub width: u32,
    pub height: u32,
    pub camera: Option<Camera>,
    pub params: Vec<ParamSpec>,
    pub items: Vec<Item>,
}

impl Scene {
    pub fn new(width: u32, height: u32, params: Vec<ParamSpec>) -> Scene {
        Scene {
            width,
            height,
            camera: None,
            params,
            items: vec![],
        }
    }

    /// Total components of all parameters (the length of a vertex's `values`).
    pub fn value_len(&self) -> usize {
        self.params.iter().map(|p| p.components).sum()
    }

    /// Where parameter `name`'s components start in a vertex's `values`.
    pub fn value_offset(&self, name: &str) -> Option<usize> {
        let mut at = 0;
        for p in &self.params {
            if p.name == name {
                return Some(at);
            }
            at += p.components;
        }
        None
    }

    /// A renderer with this scene's triangles submitted as instances of `prim` (a primitive
    /// with the screen-triangle interface: `screen_vertex[3][4]` and three sequence points).
    /// Spheres and patches are skipped (see the module doc).
    pub fn submit(&self, program: &std::sync::Arc<crate::ir::Program>, prim: &str) -> Result<Renderer, String> {
        let mut r = Renderer::new(program.clone());
        self.submit_into(&mut r, prim)?;
        Ok(r)
    }

    /// [`Scene::submit`] into an existing renderer (whose image size is set here).
    pub fn submit_into(&self, r: &mut Renderer, prim: &str) -> Result<(), String> {
        let issue = |e: crate::runtime::ApiIssue| e.to_string();
        r.set_image_size(self.width, self.height).map_err(issue)?;
        for p in &self.params {
            r.material_interp(&p.name, p.interp.api_name(), &[]).map_err(issue)?;
        }
        let mut flat = Vec::with_capacity(12);
        let mut value = Value(Vec::with_capacity(4));
        for item in &self.items {
            let Item::Triangle(t) = item else { continue };
            r.begin(prim).map_err(issue)?;
            flat.clear();
            flat.extend(t.vertices.iter().flatten().map(|&c| c as f32));
            r.rast_param("screen_vertex", &Value(flat.clone())).map_err(issue)?;
            for values in &t.values {
                let mut at = 0;
                for p in &self.params {
                    value.0.clear();
                    value.0.extend(values[at..at + p.components].iter().map(|&c| c as f32));
                    r.material(&p.name, &value).map_err(issue)?;
                    at += p.components;
                }
                r.sequence_point().map_err(issue)?;
            }
            r.end().map_err(issue)?;
        }
        // Nothing here may warn (every parameter is set); drop what a caller never reads.
        r.take_warnings();
        Ok(())
    }
}
