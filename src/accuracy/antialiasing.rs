//! The `antialiasing` knob: samples per pixel (1 to 16, the standard patterns) and the
//! resolve filter, measured against the exact area each shape covers in each pixel
//! ([`super::coverage`]).
//!
//! The scene: the procedural sphere (prims/sphere.prim) on the camera's axis, whose
//! silhouette is then exactly a circle (of radius `f tan(asin(R / d))` pixels about the
//! image centre), and screen triangles around it (broad ones and slivers down to 0.2 px,
//! at angles of every kind) that neither overlap each other nor the disc, all white on
//! black with no shading parameter: the image's resolved grey level at a pixel is the
//! filtered fraction of its samples some shape covers, and the exact figure is the sum of
//! the shapes' areas in the pixel. A setting's figure is the resolved level's error against
//! that area (for the Gaussian filter too: the box area is what a pixel should show), over
//! every pixel a shape touches or the image shows lit; the second figure is the same over
//! the edge pixels alone (exact area strictly between 0 and 1).

use glam::DVec3;

use super::coverage::{disc_coverage, triangle_coverage};
use super::scene::{Camera, Scene, Sphere};
use super::{Ctx, Knob, Metric, Output, Setting};
use crate::runtime::samples::Filter;

/// The settings: (samples, filter).
const SETTINGS: [(u32, Filter); 7] = [
    (1, Filter::Box),
    (2, Filter::Box),
    (4, Filter::Box),
    (8, Filter::Box),
    (16, Filter::Box),
    (4, Filter::Gaussian),
    (16, Filter::Gaussian),
];

/// The knob's scene at `side` x `side` pixels: its camera, sphere, the silhouette's radius
/// in pixels, and the triangles (screen pixels, f32-exact, non-overlapping).
pub struct AaScene {
    pub side: u32,
    pub camera: Camera,
    pub sphere: Sphere,
    pub disc_radius: f64,
    pub triangles: Vec<[[f64; 2]; 3]>,
}

/// Field of view of the camera (degrees) and its distance from the sphere.
const FOV_DEGREES: f64 = 40.0;
const DISTANCE: f64 = 4.0;

impl AaScene {
    pub fn new(side: u32) -> AaScene {
        let camera = Camera::perspective(
            side,
            side,
            DVec3::new(0.0, 0.0, DISTANCE),
            DVec3::ZERO,
            DVec3::Y,
            FOV_DEGREES,
            0.1,
            100.0,
        )
        .expect("the antialiasing camera is valid");
        let sphere = Sphere {
            centre: DVec3::ZERO,
            radius: 1.0,
            normal_param: None,
        };
        let focal = 0.5 * f64::from(side) / (0.5 * FOV_DEGREES.to_radians()).tan();
        let disc_radius = focal * (sphere.radius / DISTANCE).asin().tan();
        // Triangles in the four corners, outside the disc (radius ~0.35 side about the
        // centre): each corner square holds a broad triangle and three slivers.
        let s = f64::from(side);
        let q = 0.22 * s;
        let f32_exact = |p: [f64; 2]| [p[0] as f32 as f64, p[1] as f32 as f64];
        let mut triangles = vec![];
        for (k, (cx, cy)) in [(0.0, 0.0), (s - q, 0.0), (0.0, s - q), (s - q, s - q)]
            .into_iter()
            .enumerate()
        {
            let at = |u: f64, v: f64| f32_exact([cx + u * q, cy + v * q]);
            // A broad triangle in the upper half of the corner square, its edges at odd angles.
            triangles.push([at(0.05, 0.07), at(0.93, 0.11 + 0.05 * k as f64), at(0.37, 0.45)]);
            // Slivers in the lower half, 0.2 to 0.8 px thick, rising at different slopes.
            for (j, width) in [0.2, 0.5, 0.8].into_iter().enumerate() {
                let y0 = 0.55 + 0.13 * j as f64;
                let rise = 0.02 + 0.09 * j as f64 + 0.03 * k as f64;
                let a = at(0.05, y0);
                let b = at(0.95, y0 - rise);
                triangles.push([a, b, [b[0], b[1] + width].map(|c| c as f32 as f64)]);
            }
        }
        AaScene {
            side,
            camera,
            sphere,
            disc_radius,
            triangles,
        }
    }

    /// The exact area covered in each pixel, row-major.
    pub fn exact_coverage(&self) -> Vec<f64> {
        let c = 0.5 * f64::from(self.side);
        let mut area = disc_coverage([c, c], self.disc_radius, self.side, self.side);
        for t in &self.triangles {
            for (a, t) in area.iter_mut().zip(triangle_coverage(*t, self.side, self.side)) {
                *a += t;
            }
        }
        area
    }

    /// A renderer of the scene at `samples` per pixel resolved with `filter`.
    pub fn renderer(&self, ctx: &Ctx, samples: u32, filter: Filter) -> Result<crate::runtime::Renderer, String> {
        let issue = |e: crate::runtime::ApiIssue| e.to_string();
        let mut r = super::knobs::world_renderer(ctx, &self.camera)?;
        r.set_samples(samples).map_err(issue)?;
        r.set_filter(filter);
        r.begin("sphere").map_err(issue)?;
        let centre = self.sphere.centre.as_vec3().to_array().to_vec();
        r.rast_param("center", &crate::runtime::Value(centre)).map_err(issue)?;
        r.rast_param("radius", &crate::runtime::Value(vec![self.sphere.radius as f32]))
            .map_err(issue)?;
        r.end().map_err(issue)?;
        let mut scene = Scene::new(self.side, self.side, vec![]);
        for t in &self.triangles {
            scene.items.push(super::scene::Item::Triangle(super::scene::Triangle {
                vertices: t.map(|p| [p[0], p[1], 0.5, 1.0]),
                values: [vec![], vec![], vec![]],
            }));
        }
        scene.submit_into(&mut r, "screen_triangle")?;
        super::knobs::no_warnings(&mut r)?;
        Ok(r)
    }
}

/// Every pixel's displayed grey level (the red channel, before 8-bit rounding), row-major.
fn resolved_levels(frame: &crate::runtime::Frame) -> Vec<f64> {
    (0..frame.height)
        .flat_map(|y| (0..frame.width).map(move |x| (x, y)))
        .map(|(x, y)| f64::from(frame.color_at(x, y)[0]))
        .collect()
}

/// (coverage error over every pixel touched, over the edge pixels) of `levels` against
/// `exact`.
pub fn coverage_errors(levels: &[f64], exact: &[f64]) -> (Metric, Metric) {
    let (mut all, mut edge) = (vec![], vec![]);
    for (&got, &want) in levels.iter().zip(exact) {
        if got == 0.0 && want == 0.0 {
            continue;
        }
        let e = (got - want).abs();
        all.push(e);
        if want > 0.0 && want < 1.0 {
            edge.push(e);
        }
    }
    (
        Metric::of("coverage error", "px area", &all),
        Metric::of("coverage error, edge pixels", "px area", &edge),
    )
}

pub fn antialiasing_knob<'a>(quick: bool) -> Knob<'a> {
    let side = if quick { 128 } else { 384 };
    let scene = std::rc::Rc::new(AaScene::new(side));
    let exact = scene.exact_coverage();
    let settings = SETTINGS
        .iter()
        .map(|&(samples, filter)| {
            let scene = scene.clone();
            let label = match samples {
                1 => "1 sample".to_string(),
                n => format!("{n} samples, {}", filter.name()),
            };
            Setting::new(label, move |ctx: &mut Ctx| {
                let r = scene.renderer(ctx, samples, filter)?;
                Ok(Output::Jit(ctx.render(&r)?))
            })
        })
        .collect();
    Knob {
        name: "antialiasing",
        title: "antialiasing: samples per pixel and resolve filter (coverage against the exact area)",
        settings,
        measure: Box::new(move |_, out| {
            let Output::Jit(frame) = out else {
                return Err("the antialiasing knob has no reference setting".into());
            };
            let (all, edge) = coverage_errors(&resolved_levels(frame), &exact);
            Ok(vec![all, edge])
        }),
        missing: vec![],
    }
}
