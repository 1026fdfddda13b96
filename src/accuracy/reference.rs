//! The f64 reference renderer: plain Rust written for clarity, not speed, and the yardstick
//! of every error figure `primflow accuracy` prints.
//!
//! It renders a [`Scene`] to the buffers the JIT runtime fills — coverage (depth writes per
//! pixel), depth, every shading parameter, colour — with the runtime's rules: pixel centres
//! at half-integers, depth z/w in [0, 1] with larger nearer, a write when the new depth is
//! at least the stored one (so of two equal depths the later item wins), items in order.
//! What it does differently is only the arithmetic and the geometry:
//! - triangles are covered by the exact edge-function test on the vertices as given (no
//!   snapping), with the same top-left rule as `prims/screen_triangle.prim`. For vertices
//!   that are f32 values (what the API carries) every edge function is computed exactly in
//!   f64 (differences of f32 are exact, their products fit 53 bits, and one rounding of a
//!   sum keeps its sign), so this IS the exact rasteriser. Depth and `linear` parameters are
//!   interpolated with the screen barycentrics, `perspective_linear` ones with the
//!   perspective-correct ratio;
//! - spheres are ray-cast analytically (nearest root of the ray-sphere quadric);
//! - rational Bezier patches are inverted per pixel: Newton's method on
//!   `project(S(u, v)) = pixel centre`, seeded from a fine f64 tessellation, so the depth
//!   and (u, v) at a pixel are those of the true surface. Patches must not fold over in the
//!   view (every pixel sees at most one sheet), which the standard scenes respect.

use super::scene::{Camera, Interp, Item, Patch, Scene, Sphere, Triangle};

/// The reference frame: row-major buffers of `width * height` pixels from the top-left.
#[derive(Clone, Debug)]
pub struct RefFrame {
    pub width: u32,
    pub height: u32,
    /// Depth of the visible surface (0 where nothing was written).
    pub depth: Vec<f64>,
    /// Depth writes per pixel (what `Frame::write_counts` counts).
    pub count: Vec<u32>,
    /// Index (in `Scene::items`) of the item that wrote last, -1 for none.
    pub item: Vec<i64>,
    /// One plane per shading-parameter component, in the scene's order.
    pub planes: Vec<Vec<f64>>,
    /// Per parameter: (name, first plane, components).
    pub params: Vec<(String, usize, usize)>,
}

impl RefFrame {
    fn new(scene: &Scene) -> RefFrame {
        let n = (scene.width * scene.height) as usize;
        let mut params = vec![];
        let mut at = 0;
        for p in &scene.params {
            params.push((p.name.clone(), at, p.components));
            at += p.components;
        }
        RefFrame {
            width: scene.width,
            height: scene.height,
            depth: vec![0.0; n],
            count: vec![0; n],
            item: vec![-1; n],
            planes: vec![vec![0.0; n]; at],
            params,
        }
    }

    pub fn written(&self, i: usize) -> bool {
        self.count[i] > 0
    }

    /// The planes of parameter `name`: (first plane, components).
    pub fn param(&self, name: &str) -> Option<(usize, usize)> {
        self.params.iter().find(|p| p.0 == name).map(|p| (p.1, p.2))
    }

    /// The colour the runtime would show (see `Frame::color_at`): `Cs` clamped to [0, 1]
    /// where written (white without `Cs`), the background elsewhere.
    pub fn color(&self, i: usize, background: [f64; 3]) -> [f64; 3] {
        if !self.written(i) {
            return background;
        }
        match self.param("Cs") {
            Some((first, 3)) => [0, 1, 2].map(|k| self.planes[first + k][i].clamp(0.0, 1.0)),
            Some((first, 1)) => [self.planes[first][i].clamp(0.0, 1.0); 3],
            _ => [1.0; 3],
        }
    }

    /// The depth test and write of one sample; `values` fills the parameter planes.
    fn write(&mut self, i: usize, z: f64, item: usize, values: impl Fn(usize) -> f64) {
        if !(0.0..=1.0).contains(&z) || z < self.depth[i] {
            return;
        }
        self.depth[i] = z;
        self.count[i] += 1;
        self.item[i] = item as i64;
        for (k, plane) in self.planes.iter_mut().enumerate() {
            plane[i] = values(k);
        }
    }
}

/// Render `scene` in f64.
pub fn render(scene: &Scene) -> RefFrame {
    let mut frame = RefFrame::new(scene);
    for (index, item) in scene.items.iter().enumerate() {
        match item {
            Item::Triangle(t) => triangle(scene, &mut frame, index, t),
            Item::Sphere(s) => {
                if let Some(camera) = &scene.camera {
                    sphere(scene, camera, &mut frame, index, s)
                }
            }
            Item::Patch(p) => {
                if let Some(camera) = &scene.camera {
                    patch(scene, camera, &mut frame, index, p)
                }
            }
        }
    }
    frame
}

/// Whether the pixel centre (x, y) is inside the triangle, and its screen barycentrics.
/// Edge i runs from vertex i to vertex i+1; inside is e > 0, or e == 0 on a top-left edge
/// (a > 0, or a == 0 and b < 0), exactly as the library's screen_triangle decides.
pub fn cover(v: &[[f64; 4]; 3], x: f64, y: f64) -> Option<[f64; 3]> {
    let det = (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[2][0] - v[0][0]) * (v[1][1] - v[0][1]);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let orient = det.signum();
    let mut e = [0.0; 3];
    for i in 0..3 {
        let j = (i + 1) % 3;
        let a = -orient * (v[j][1] - v[i][1]);
        let b = orient * (v[j][0] - v[i][0]);
        e[i] = a * (x - v[i][0]) + b * (y - v[i][1]);
        let top_left = a > 0.0 || (a == 0.0 && b < 0.0);
        if e[i] < 0.0 || (e[i] == 0.0 && !top_left) {
            return None;
        }
    }
    // Edge i is opposite vertex i + 2.
    let sum = e[0] + e[1] + e[2];
    Some([e[1] / sum, e[2] / sum, e[0] / sum])
}

fn triangle(scene: &Scene, frame: &mut RefFrame, index: usize, t: &Triangle) {
    let v = &t.vertices;
    if v.iter().flatten().any(|c| !c.is_finite()) {
        return;
    }
    let (w, h) = (scene.width as f64, scene.height as f64);
    let lo_x = v.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min).floor().max(0.0);
    let hi_x = v.iter().map(|p| p[0]).fold(f64::NEG_INFINITY, f64::max).ceil().min(w);
    let lo_y = v.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min).floor().max(0.0);
    let hi_y = v.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max).ceil().min(h);
    // Component k of the flattened values -> its interpolation.
    let interp: Vec<Interp> = scene
        .params
        .iter()
        .flat_map(|p| std::iter::repeat_n(p.interp, p.components))
        .collect();
    let q = [1.0 / v[0][3], 1.0 / v[1][3], 1.0 / v[2][3]];
    for py in lo_y as u32..hi_y as u32 {
        for px in lo_x as u32..hi_x as u32 {
            let (x, y) = (px as f64 + 0.5, py as f64 + 0.5);
            let Some(l) = cover(v, x, y) else { continue };
            let z = l[0] * v[0][2] + l[1] * v[1][2] + l[2] * v[2][2];
            let inv_w = l[0] * q[0] + l[1] * q[1] + l[2] * q[2];
            let value = |k: usize| {
                let a = [t.values[0][k], t.values[1][k], t.values[2][k]];
                match interp[k] {
                    Interp::Linear => l[0] * a[0] + l[1] * a[1] + l[2] * a[2],
                    Interp::Perspective => (l[0] * a[0] * q[0] + l[1] * a[1] * q[1] + l[2] * a[2] * q[2]) / inv_w,
                    Interp::Constant => a[2],
                }
            };
            frame.write((py * scene.width + px) as usize, z, index, value);
        }
    }
}

/// Distance along the unit ray `dir` from `origin` to the nearest point of the sphere in
/// front of it, if any.
pub fn ray_sphere(origin: glam::DVec3, dir: glam::DVec3, s: &Sphere) -> Option<f64> {
    let oc = origin - s.centre;
    let b = dir.dot(oc);
    let c = oc.length_squared() - s.radius * s.radius;
    let disc = b * b - c;
    if disc < 0.0 {
        return None;
    }
    let root = disc.sqrt();
    // The numerically stable pair of roots (no cancellation in -b - root).
    let t = if b > 0.0 { c / (-b - root) } else { -b - root };
    let far = if b > 0.0 { -b - root } else { c / (-b - root) };
    [t, far].into_iter().filter(|t| *t > 0.0).reduce(f64::min)
}

fn sphere(scene: &Scene, camera: &Camera, frame: &mut RefFrame, index: usize, s: &Sphere) {
    let normal_at = s.normal_param.as_deref().and_then(|n| scene.value_offset(n));
    for py in 0..scene.height {
        for px in 0..scene.width {
            let dir = camera.ray(px as f64 + 0.5, py as f64 + 0.5);
            let Some(t) = ray_sphere(camera.eye, dir, s) else {
                continue;
            };
            let hit = camera.eye + dir * t;
            let normal = ((hit - s.centre) / s.radius).to_array();
            let value = |k: usize| match normal_at {
                Some(at) if (at..at + 3).contains(&k) => normal[k - at],
                _ => 0.0,
            };
            frame.write((py * scene.width + px) as usize, camera.depth(hit), index, value);
        }
    }
}

/// Device (x, y) of the patch point at (u, v).
fn patch_xy(camera: &Camera, p: &Patch, u: f64, v: f64) -> [f64; 2] {
    let s = camera.screen(p.eval(u, v));
    [s[0], s[1]]
}

/// Newton's method on `project(S(u, v)) = (x, y)` from `seed`; the converged (u, v) if it
/// lies on the patch.
pub fn invert_patch(camera: &Camera, p: &Patch, x: f64, y: f64, seed: [f64; 2]) -> Option<[f64; 2]> {
    const H: f64 = 1e-7;
    let [mut u, mut v] = seed;
    for _ in 0..20 {
        let f = patch_xy(camera, p, u, v);
        let (fx, fy) = (f[0] - x, f[1] - y);
        if fx.abs() < 1e-9 && fy.abs() < 1e-9 {
            let eps = 1e-9;
            return ((-eps..=1.0 + eps).contains(&u) && (-eps..=1.0 + eps).contains(&v))
                .then_some([u.clamp(0.0, 1.0), v.clamp(0.0, 1.0)]);
        }
        let fu = patch_xy(camera, p, u + H, v);
        let fv = patch_xy(camera, p, u, v + H);
        let (a, b) = ((fu[0] - f[0]) / H, (fv[0] - f[0]) / H);
        let (c, d) = ((fu[1] - f[1]) / H, (fv[1] - f[1]) / H);
        let det = a * d - b * c;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        u -= (d * fx - b * fy) / det;
        v -= (-c * fx + a * fy) / det;
        // Stay near the patch: a wild step from a poor seed would leave its domain.
        u = u.clamp(-0.5, 1.5);
        v = v.clamp(-0.5, 1.5);
    }
    None
}

fn patch(scene: &Scene, camera: &Camera, frame: &mut RefFrame, index: usize, p: &Patch) {
    let (w, h) = (scene.width as usize, scene.height as usize);
    // Seeds: a fine tessellation rasterised with (u, v) per pixel (nearest sheet wins).
    const GRID: usize = 96;
    let mut seed: Vec<Option<([f64; 2], f64)>> = vec![None; w * h];
    let grid: Vec<Vec<[f64; 4]>> = (0..=GRID)
        .map(|i| {
            (0..=GRID)
                .map(|j| camera.screen(p.eval(i as f64 / GRID as f64, j as f64 / GRID as f64)))
                .collect()
        })
        .collect();
    let uv = |i: usize, j: usize| [i as f64 / GRID as f64, j as f64 / GRID as f64];
    for i in 0..GRID {
        for j in 0..GRID {
            for corners in [
                [(i, j), (i + 1, j), (i + 1, j + 1)],
                [(i, j), (i + 1, j + 1), (i, j + 1)],
            ] {
                let v = corners.map(|(a, b)| grid[a][b]);
                let t = corners.map(|(a, b)| uv(a, b));
                let lo_x = v.iter().map(|q| q[0]).fold(f64::INFINITY, f64::min).floor().max(0.0);
                let hi_x = v
                    .iter()
                    .map(|q| q[0])
                    .fold(f64::NEG_INFINITY, f64::max)
                    .ceil()
                    .min(w as f64);
                let lo_y = v.iter().map(|q| q[1]).fold(f64::INFINITY, f64::min).floor().max(0.0);
                let hi_y = v
                    .iter()
                    .map(|q| q[1])
                    .fold(f64::NEG_INFINITY, f64::max)
                    .ceil()
                    .min(h as f64);
                for py in lo_y as usize..hi_y as usize {
                    for px in lo_x as usize..hi_x as usize {
                        let Some(l) = cover(&v, px as f64 + 0.5, py as f64 + 0.5) else {
                            continue;
                        };
                        let z = l[0] * v[0][2] + l[1] * v[1][2] + l[2] * v[2][2];
                        let s = &mut seed[py * w + px];
                        if s.is_none_or(|(_, old)| z > old) {
                            let st = [0, 1].map(|k| l[0] * t[0][k] + l[1] * t[1][k] + l[2] * t[2][k]);
                            *s = Some((st, z));
                        }
                    }
                }
            }
        }
    }
    let uv_at = p.uv_param.as_deref().and_then(|n| scene.value_offset(n));
    for py in 0..h {
        for px in 0..w {
            let (x, y) = (px as f64 + 0.5, py as f64 + 0.5);
            // Pixels between the fine tessellation's chords and the true boundary have no
            // seed of their own: try a neighbour's.
            let own = seed[py * w + px].map(|s| s.0);
            let neighbours = [(0i64, -1i64), (0, 1), (-1, 0), (1, 0)]
                .into_iter()
                .filter_map(|(dx, dy)| {
                    let (nx, ny) = (px as i64 + dx, py as i64 + dy);
                    ((0..w as i64).contains(&nx) && (0..h as i64).contains(&ny))
                        .then(|| seed[ny as usize * w + nx as usize].map(|s| s.0))
                        .flatten()
                });
            let found = own
                .into_iter()
                .chain(neighbours)
                .find_map(|s| invert_patch(camera, p, x, y, s));
            let Some([u, v]) = found else { continue };
            let z = camera.depth(p.eval(u, v));
            let value = |k: usize| match uv_at {
                Some(at) if k == at => u,
                Some(at) if k == at + 1 => v,
                _ => 0.0,
            };
            frame.write(py * w + px, z, index, value);
        }
    }
}
