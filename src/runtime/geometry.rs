//! The geometry stage of the runtime: what happens to a primitive instance between `end`
//! and its kernel (seeds 000, 001, 002). It uses the pure math of [`crate::pipeline`].
//!
//! The API records point, normal and vector parameters in *object* coordinates. At `end`,
//! [`GeometryState::process`] turns the instance into zero or more instances ready for a
//! kernel:
//! 1. Model data with `w <= 0` is fixed as seed 000 9.2 says (with a warning).
//! 2. Points go to clip space (`clip_from_object`, f64). A *facet* primitive (declared
//!    `primitive facet`: polygon, triangle) gets branch-free clip codes per vertex,
//!    ANDed and ORed (seed 002): all vertices outside one view plane or one model clip plane
//!    = trivially rejected (no kernel runs); no vertex outside the guard band, the far
//!    plane, `w > 0` or a model plane = no runtime clipping. Otherwise the runtime clips the
//!    polygon (Sutherland-Hodgman in homogeneous clip space, [`crate::pipeline::clip`])
//!    against exactly the crossed planes among: `w = epsilon`, the four guard-band planes,
//!    the far plane and the model clip planes, carrying the interpolation data along; the
//!    result is fanned into triangles, each an instance of the same primitive.
//!    The near (hither) plane is left to the primitive (polygon.prim clips it in the
//!    language): the instance's key has `trivial_accept` when no vertex is in front of it,
//!    which compiles the variant where `clipping()` is false.
//!    In a double-pyramid view the runtime clips against every plane, near included.
//! 3. Face determination in device space ([`crate::pipeline::face`]): culled facets are
//!    dropped; with `distinguish`, the facing is handed to shading in the reserved `facing`
//!    shading parameter (1 front, -1 back).
//! 4. Points go on to homogeneous device coordinates: original vertices by
//!    `device_from_object * p` (the same f64 arithmetic for every instance, so a vertex
//!    shared by two primitives gets the same bits whichever was clipped), new ones by
//!    `device_from_clip * p_clip`; normals and vectors go to lighting coordinates.
//!    A facet with fewer than three sequence points, and any non-finite point of a
//!    non-facet, is passed to its kernel as it is (the kernel draws nothing).
//!
//! A *point* primitive (`primitive point`) has each point tested by its centre
//! ([`GeometryState::clip_points`]) and drawn as one instance of its own.
//!
//! A *line* primitive (`primitive line`) has each polyline segment clipped alone
//! ([`GeometryState::clip_polyline`], Liang-Barsky) and becomes one instance per segment
//! with its neighbours (docs/pipeline.md, "Lines"); lines are never culled.
//!
//! Primitives with no geometry type (sphere, NURB surface, user primitives) are not
//! polygons, so the runtime cannot clip them: their points are transformed, their key keeps `clipping()` true, and
//! a primitive whose points are all outside one plane is still sent to its kernel (points
//! need not bound its surface).
//!
//! The guard band is the viewport grown by [`GUARD_BAND_PX`] pixels on each side, expressed
//! in clip space by scaling x and y; pixels outside the viewport are never touched because
//! kernels only see their tile. Clipped vertices are computed in f64 and rounded once.

use glam::{DMat3, DMat4, DVec3, DVec4};

use crate::pipeline::clip::{
    clip_code_f64, clip_polygon, transform_plane, ClipAccumulator, ClipOptions, ClipPolygon, ClipVerdict, PyramidMode,
    CLIP_PLANES, CLIP_W, CLIP_Z_NEAR,
};
use crate::pipeline::face::{facing_device, CullMode, Facing};
use crate::pipeline::transform::{normalise_pyramid, sanitize_model_w, NormalMatrix, TransformState};
use crate::pipeline::{choose_pipeline, GeometryType, PipelineChoice, PipelineState, Warning};

/// Pixels the guard band adds on each side of the viewport.
pub const GUARD_BAND_PX: f64 = 64.0;

/// What the clip codes decided for one primitive (for `--explain` and tests).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ClipOutcome {
    /// Not a facet: points transformed, no codes.
    NotClipped,
    TriviallyRejected,
    TriviallyAccepted,
    /// Clipped by the runtime into this many triangles (0: nothing left).
    Clipped,
    /// Dropped by face culling.
    Culled,
    /// A vertex was NaN or infinite: dropped.
    NonFinite,
}

/// The transform-related state the API keeps: the pipeline's transform state, or a
/// `device_from_world` matrix given directly (the `transform` command and the default
/// identity, under which points are device coordinates already).
#[derive(Debug)]
pub struct GeometryState {
    pub transforms: TransformState,
    /// `Some`: device_from_world given directly (no camera, lighting in "world").
    pub direct: Option<DMat4>,
    /// Model clip planes in world coordinates (`a x + b y + c z + d w >= 0` kept).
    pub clip_planes: Vec<DVec4>,
    pub cull: CullMode,
    /// Hand the device-space facing to shading (front/back materials).
    pub distinguish: bool,
    pub w_epsilon: f64,
}

impl GeometryState {
    pub fn new(width: u32, height: u32) -> GeometryState {
        let mut transforms = TransformState::new();
        let _ = transforms.set_viewport(0.0, 0.0, f64::from(width), f64::from(height));
        GeometryState {
            transforms,
            direct: Some(DMat4::IDENTITY),
            clip_planes: vec![],
            cull: CullMode::None,
            distinguish: false,
            w_epsilon: ClipOptions::default().w_epsilon,
        }
    }

    /// V (sign-normalised) and the pyramid mode.
    pub fn clip_from_world(&self) -> (DMat4, PyramidMode) {
        match self.direct {
            Some(device_from_world) => {
                let clip_from_device = self.transforms.device_from_clip().inverse();
                normalise_pyramid(clip_from_device * device_from_world)
            }
            None => (self.transforms.clip_from_world(), self.transforms.pyramid_mode()),
        }
    }
    pub fn clip_from_object(&self) -> DMat4 {
        self.clip_from_world().0 * self.transforms.world_from_object()
    }
    pub fn device_from_clip(&self) -> DMat4 {
        self.transforms.device_from_clip()
    }
    pub fn device_from_world(&self) -> DMat4 {
        self.device_from_clip() * self.clip_from_world().0
    }
    /// For a directly given device transform this is `direct * M` (no round trip through
    /// clip space, so the identity leaves points exactly as given).
    pub fn device_from_object(&self) -> DMat4 {
        match self.direct {
            Some(device_from_world) => device_from_world * self.transforms.world_from_object(),
            None => self.device_from_clip() * self.clip_from_object(),
        }
    }
    /// E (identity when lighting happens in world coordinates).
    pub fn lighting_from_world(&self) -> DMat4 {
        match self.direct {
            Some(_) => DMat4::IDENTITY,
            None => self.transforms.lighting_from_world(),
        }
    }
    pub fn lighting_from_object(&self) -> DMat4 {
        self.lighting_from_world() * self.transforms.world_from_object()
    }
    pub fn device_from_lighting(&self) -> DMat4 {
        match self.direct {
            Some(_) => self.device_from_world(),
            None => self.transforms.device_from_lighting(),
        }
    }
    pub fn lighting_normal_matrix(&self) -> NormalMatrix {
        NormalMatrix::of(&self.lighting_from_object())
    }

    /// The six matrices of the kernel ABI's `spaces` block (see `abi::ArgLayout`).
    pub fn abi_spaces(&self) -> [[f32; 16]; 6] {
        crate::pipeline::transform::abi_spaces_from([
            self.device_from_object(),
            self.device_from_world(),
            self.device_from_lighting(),
        ])
    }

    /// The pipeline seed 000 would run for a primitive of `geometry`.
    pub fn choose(&self, geometry: GeometryType, lit: bool, view_clipping: bool) -> PipelineChoice {
        let mut state = PipelineState::from_transforms(
            &self.transforms,
            geometry,
            lit,
            view_clipping,
            !self.clip_planes.is_empty(),
        );
        if self.direct.is_some() {
            // No camera: a device transform was given directly, lighting is in its world.
            state.view_factoring = Err(crate::pipeline::factor::NotFactorizable::NotSparse);
            state.pyramid = self.clip_from_world().1;
        }
        let mut choice = choose_pipeline(&state);
        // Shading is deferred: a pixel is lit once, in LC (WC when V is not factorizable),
        // never in model coordinates, whatever the facet pipeline would do per vertex.
        if choice.lighting == crate::pipeline::LightingSpace::Model {
            choice.lighting = if state.view_factoring.is_ok() {
                crate::pipeline::LightingSpace::Lighting
            } else {
                crate::pipeline::LightingSpace::World
            };
        }
        if self.direct.is_some() {
            choice
                .warnings
                .retain(|w| !matches!(w, Warning::NonFactorizableView(_)));
        } else if let Err(why) = state.view_factoring {
            // Deferred shading lights in world coordinates whenever V has no factoring,
            // whichever facet pipeline was chosen: say so (seed 000 9.5).
            let singular = choice.warnings.contains(&Warning::SingularView);
            if lit
                && !singular
                && !choice
                    .warnings
                    .iter()
                    .any(|w| matches!(w, Warning::NonFactorizableView(_)))
            {
                choice.warnings.push(Warning::NonFactorizableView(why));
            }
        }
        choice
    }

    /// A model-space point with w <= 0 fixed (seed 000 9.2), widened to f64.
    pub fn object_point(&self, p: [f32; 4], warnings: &mut Vec<Warning>) -> DVec4 {
        let p = DVec4::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]), f64::from(p[3]));
        // (0, 0, 0, 0) is no point at all (a zero-filled missing value, already warned
        // about): it stays as it is rather than becoming a point at the origin.
        let (p, changed) = if p.is_finite() && p != DVec4::ZERO {
            sanitize_model_w(p)
        } else {
            (p, false)
        };
        if changed {
            note(warnings, Warning::NonPositiveModelW);
        }
        p
    }

    /// Guard-band scale of clip x and y: the band spans `(W + 2 * GUARD_BAND_PX) / W` times
    /// the view in x.
    fn guard_scale(&self) -> (f64, f64) {
        let vp = self.transforms.viewport();
        (
            (vp.width + 2.0 * GUARD_BAND_PX) / vp.width,
            (vp.height + 2.0 * GUARD_BAND_PX) / vp.height,
        )
    }

    /// Model clip planes in clip space, or `None` when V is singular (seed 000 9.1: model
    /// clipping is skipped).
    fn clip_space_planes(&self) -> Option<Vec<DVec4>> {
        let (clip_from_world, _) = self.clip_from_world();
        self.clip_planes
            .iter()
            .map(|&p| transform_plane(p, &clip_from_world))
            .collect()
    }

    /// Clip-code, clip, cull and fan one facet. `positions` are clip space, `attrs` the
    /// per-vertex floats carried along (`n_attrs` each). Returns the pieces (each a list of
    /// device-homogeneous positions with attributes), the outcome, whether the near plane
    /// is still crossed, and the facing of the result.
    pub fn clip_facet(
        &self,
        positions: &[DVec4],
        device: &[DVec4],
        attrs: &[Vec<f32>],
        warnings: &mut Vec<Warning>,
    ) -> FacetResult {
        let (_, mode) = self.clip_from_world();
        let n_attrs = attrs.first().map_or(0, Vec::len);
        let mut result = FacetResult {
            outcome: ClipOutcome::TriviallyAccepted,
            near_crossed: false,
            pieces: vec![],
        };
        if positions.iter().any(|p| !p.is_finite()) {
            note(warnings, Warning::NonFiniteVertex);
            result.outcome = ClipOutcome::NonFinite;
            return result;
        }
        let planes = match self.clip_space_planes() {
            Some(p) => p,
            None => {
                note(warnings, Warning::SingularView);
                vec![]
            }
        };
        // Codes: the real view for rejection, the guard band for acceptance.
        let (gx, gy) = self.guard_scale();
        let mut view = ClipAccumulator::new();
        let mut guard = ClipAccumulator::new();
        let mut model_and = if planes.is_empty() { 0 } else { u32::MAX };
        let mut model_or = 0u32;
        for p in positions {
            view.add(clip_code_f64(p.to_array(), mode));
            guard.add(clip_code_f64([p.x / gx, p.y / gy, p.z, p.w], mode));
            for (i, plane) in planes.iter().enumerate().take(32) {
                let outside = u32::from(plane.dot(*p) < 0.0) << i;
                model_and &= outside | !(1 << i);
                model_or |= outside;
            }
        }
        let model_and = if planes.is_empty() {
            0
        } else {
            model_and & ((1u64 << planes.len().min(32)) as u32).wrapping_sub(1)
        };
        if matches!(view.verdict(mode), ClipVerdict::Reject) || model_and != 0 {
            result.outcome = ClipOutcome::TriviallyRejected;
            return result;
        }
        let or = guard.or();
        let small_w = positions.iter().any(|p| p.w < self.w_epsilon);
        let runtime_planes = match mode {
            PyramidMode::Single => or & !CLIP_Z_NEAR & (CLIP_PLANES | CLIP_W),
            PyramidMode::Double => or,
        };
        let needs_clip = runtime_planes != 0 || model_or != 0 || small_w || mode == PyramidMode::Double && or != 0;
        result.near_crossed = mode == PyramidMode::Single && or & CLIP_Z_NEAR != 0;
        let d = self.device_from_clip();
        if !needs_clip {
            let piece = device
                .iter()
                .zip(attrs)
                .map(|(p, a)| (*p, a.clone()))
                .collect::<Vec<_>>();
            result.pieces = self.cull_and_fan(vec![piece], false, &mut result.outcome);
            return result;
        }
        // Clip in guard-band space: x and y scaled so the band is the unit view volume.
        let mut poly = ClipPolygon::<f64>::new(n_attrs);
        for (p, a) in positions.iter().zip(attrs) {
            let wide: Vec<f64> = a.iter().map(|&v| f64::from(v)).collect();
            // Attribute counts match by construction; a mismatch would only drop the facet.
            if poly.push([p.x / gx, p.y / gy, p.z, p.w], &wide).is_err() {
                result.outcome = ClipOutcome::NonFinite;
                return result;
            }
        }
        let guard_planes: Vec<[f64; 4]> = planes.iter().map(|m| [m.x * gx, m.y * gy, m.z, m.w]).collect();
        let opts = ClipOptions {
            w_epsilon: self.w_epsilon,
        };
        let pieces = match clip_polygon(&poly, runtime_planes, &guard_planes, mode, opts) {
            Ok(p) => p,
            Err(_) => {
                note(warnings, Warning::NonFiniteVertex);
                result.outcome = ClipOutcome::NonFinite;
                return result;
            }
        };
        result.outcome = ClipOutcome::Clipped;
        let device_pieces = pieces
            .iter()
            .map(|piece| {
                (0..piece.len())
                    .map(|i| {
                        let g = piece.position(i);
                        let guard_pos = DVec4::from_array(g);
                        // A vertex the clipper passed through keeps its original device
                        // position, so it gets the same bits as in a neighbour that was not
                        // clipped; new vertices go from clip to device space.
                        let original = positions
                            .iter()
                            .position(|p| DVec4::new(p.x / gx, p.y / gy, p.z, p.w) == guard_pos)
                            .map(|k| device[k])
                            .unwrap_or_else(|| d * DVec4::new(g[0] * gx, g[1] * gy, g[2], g[3]));
                        let a = piece.attrs(i).iter().map(|&v| v as f32).collect();
                        (original, a)
                    })
                    .collect()
            })
            .collect();
        result.pieces = self.cull_and_fan(device_pieces, true, &mut result.outcome);
        result
    }

    /// Clip-code and clip each segment of a polyline alone (seed 000 6.1): a segment with
    /// both ends outside one view or model plane is dropped, one with both ends inside the
    /// guard band, the near and far planes, every model plane and `w >= epsilon` is kept as
    /// it is, and any other is clipped by Liang-Barsky in homogeneous clip space against
    /// exactly the planes its ends' codes cross (the near plane included: a line primitive
    /// has no clipping of its own). `positions` are clip space, `device` the same points by
    /// `device_from_object`; attributes are interpolated linearly in clip space
    /// (perspective-correct). In a double-pyramid view the segment is also clipped negated
    /// (the same projective points with `w > 0`), giving up to two pieces.
    pub fn clip_polyline(
        &self,
        positions: &[DVec4],
        device: &[DVec4],
        attrs: &[Vec<f32>],
        warnings: &mut Vec<Warning>,
    ) -> PolylineResult {
        let (_, mode) = self.clip_from_world();
        let mut result = PolylineResult {
            outcome: ClipOutcome::TriviallyAccepted,
            segments: vec![],
        };
        let planes = match self.clip_space_planes() {
            Some(p) => p,
            None => {
                note(warnings, Warning::SingularView);
                vec![]
            }
        };
        let (gx, gy) = self.guard_scale();
        let guard = |p: DVec4| DVec4::new(p.x / gx, p.y / gy, p.z, p.w);
        let guard_planes: Vec<DVec4> = planes
            .iter()
            .map(|m| DVec4::new(m.x * gx, m.y * gy, m.z, m.w))
            .collect();
        let d = self.device_from_clip();
        let (mut any_kept, mut any_clipped) = (false, false);
        for index in 0..positions.len().saturating_sub(1) {
            let (a, b) = (positions[index], positions[index + 1]);
            if !a.is_finite() || !b.is_finite() {
                note(warnings, Warning::NonFiniteVertex);
                continue;
            }
            let mut view = ClipAccumulator::new();
            view.add(clip_code_f64(a.to_array(), mode));
            view.add(clip_code_f64(b.to_array(), mode));
            let outside_model = |p: DVec4| planes.iter().map(|m| m.dot(p) < 0.0).collect::<Vec<_>>();
            let (ma, mb) = (outside_model(a), outside_model(b));
            if matches!(view.verdict(mode), ClipVerdict::Reject) || ma.iter().zip(&mb).any(|(x, y)| *x && *y) {
                continue;
            }
            let signs: &[f64] = match mode {
                PyramidMode::Single => &[1.0],
                PyramidMode::Double => &[1.0, -1.0],
            };
            for &sign in signs {
                let (ga, gb) = (guard(a) * sign, guard(b) * sign);
                // Every half-space as an affine function of the guard-space point, kept
                // where it is >= 0: w >= epsilon, the four guard-band planes, near, far,
                // and the model planes.
                // Every half-space kept, as `n . p + c >= 0` in guard space: w >= epsilon,
                // the four guard-band planes, near (z <= w), far (z >= 0), the model planes.
                let view = [
                    (DVec4::W, -self.w_epsilon),
                    (DVec4::new(-1.0, 0.0, 0.0, 1.0), 0.0),
                    (DVec4::new(1.0, 0.0, 0.0, 1.0), 0.0),
                    (DVec4::new(0.0, -1.0, 0.0, 1.0), 0.0),
                    (DVec4::new(0.0, 1.0, 0.0, 1.0), 0.0),
                    (DVec4::new(0.0, 0.0, -1.0, 1.0), 0.0),
                    (DVec4::Z, 0.0),
                ];
                let half_spaces = view.into_iter().chain(guard_planes.iter().map(|&m| (m, 0.0)));
                // Each end as its parameter along a -> b and along b -> a, from the plane
                // that set it: a new end is computed from the endpoint nearer it (as the
                // polygon clipper does), so a far endpoint's magnitude does not swamp it.
                let (mut start, mut stop) = ((0.0f64, 1.0f64), (1.0f64, 0.0f64));
                let mut rejected = false;
                for (n, c) in half_spaces {
                    let (d0, d1) = (n.dot(ga) + c, n.dot(gb) + c);
                    if d0 < 0.0 && d1 < 0.0 {
                        rejected = true;
                        break;
                    }
                    let crossing = (d0 / (d0 - d1), d1 / (d1 - d0));
                    if d0 < 0.0 && crossing.0 > start.0 {
                        start = crossing;
                    } else if d1 < 0.0 && crossing.0 < stop.0 {
                        stop = crossing;
                    }
                }
                if rejected || !(start.0 < stop.0) {
                    continue;
                }
                let lerp = |x: f64, y: f64, (t, s): (f64, f64)| if t <= s { x + (y - x) * t } else { y + (x - y) * s };
                let end = |(t, s): (f64, f64), k: usize| -> (DVec4, Vec<f32>) {
                    if [t, s][k] == 0.0 && sign > 0.0 {
                        return (device[index + k], attrs.get(index + k).cloned().unwrap_or_default());
                    }
                    let p = DVec4::from_array([0, 1, 2, 3].map(|i| lerp(a[i], b[i], (t, s)))) * sign;
                    let (fa, fb) = (
                        attrs.get(index).map_or(&[][..], Vec::as_slice),
                        attrs.get(index + 1).map_or(&[][..], Vec::as_slice),
                    );
                    let data = fa
                        .iter()
                        .zip(fb)
                        .map(|(&x, &y)| lerp(f64::from(x), f64::from(y), (t, s)) as f32)
                        .collect();
                    (d * p, data)
                };
                let original = [start.0 == 0.0 && sign > 0.0, stop.1 == 0.0 && sign > 0.0];
                any_clipped |= !(original[0] && original[1]);
                any_kept = true;
                result.segments.push(Segment {
                    index,
                    ends: [end(start, 0), end(stop, 1)],
                    original,
                });
            }
        }
        result.outcome = if !any_kept {
            ClipOutcome::TriviallyRejected
        } else if any_clipped {
            ClipOutcome::Clipped
        } else {
            ClipOutcome::TriviallyAccepted
        };
        result
    }

    /// The points of a `point` primitive that are drawn (seed 000 5.1): those whose centre
    /// is finite and inside the guard band, the near and far planes, every model plane and
    /// `w >= epsilon` (in a double-pyramid view, either as given or negated). A point is
    /// clipped by its centre alone: one whose centre is out of the guard band is dropped
    /// whatever its size, as OpenGL drops a wide point. Returns the outcome and the indices.
    pub fn clip_points(&self, positions: &[DVec4], warnings: &mut Vec<Warning>) -> (ClipOutcome, Vec<usize>) {
        let (_, mode) = self.clip_from_world();
        let planes = self.clip_space_planes().unwrap_or_else(|| {
            note(warnings, Warning::SingularView);
            vec![]
        });
        let (gx, gy) = self.guard_scale();
        let inside = |p: DVec4| {
            p.w >= self.w_epsilon
                && p.x.abs() / gx <= p.w
                && p.y.abs() / gy <= p.w
                && p.z >= 0.0
                && p.z <= p.w
                && planes.iter().all(|m| m.dot(p) >= 0.0)
        };
        let mut kept = vec![];
        for (i, &p) in positions.iter().enumerate() {
            if !p.is_finite() {
                note(warnings, Warning::NonFiniteVertex);
            } else if inside(p) || (mode == PyramidMode::Double && inside(-p)) {
                kept.push(i);
            }
        }
        let outcome = if kept.is_empty() {
            ClipOutcome::TriviallyRejected
        } else if kept.len() < positions.len() {
            ClipOutcome::Clipped
        } else {
            ClipOutcome::TriviallyAccepted
        };
        (outcome, kept)
    }

    /// Face culling in device space, then (for clipped pieces) a fan of triangles.
    fn cull_and_fan(&self, pieces: Vec<Piece>, fan: bool, outcome: &mut ClipOutcome) -> Vec<(Piece, Facing)> {
        let mut out = vec![];
        for piece in pieces {
            let screen: Vec<[f64; 2]> = piece.iter().map(|(p, _)| [p.x / p.w, p.y / p.w]).collect();
            let facing = facing_device(&screen);
            if self.cull.culls(facing) {
                *outcome = ClipOutcome::Culled;
                continue;
            }
            if fan && piece.len() > 3 {
                for i in 1..piece.len() - 1 {
                    out.push((vec![piece[0].clone(), piece[i].clone(), piece[i + 1].clone()], facing));
                }
            } else if piece.len() >= 3 || !fan {
                out.push((piece, facing));
            }
        }
        out
    }
}

/// One clipped segment of a polyline ([`GeometryState::clip_polyline`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Segment {
    /// The polyline segment it comes from: vertex `index` to vertex `index + 1`.
    pub index: usize,
    /// Its two ends in homogeneous device coordinates, with their attributes.
    pub ends: [(DVec4, Vec<f32>); 2],
    /// Whether each end is the polyline's own vertex (with its `device_from_object` bits),
    /// not a point the clipper made: only such an end can be a joint.
    pub original: [bool; 2],
}

/// What [`GeometryState::clip_polyline`] produced.
#[derive(Debug)]
pub struct PolylineResult {
    pub outcome: ClipOutcome,
    /// The surviving segments, in polyline order.
    pub segments: Vec<Segment>,
}

/// A polygon in homogeneous device coordinates with per-vertex attributes.
pub type Piece = Vec<(DVec4, Vec<f32>)>;

/// What [`GeometryState::clip_facet`] produced.
#[derive(Debug)]
pub struct FacetResult {
    pub outcome: ClipOutcome,
    /// Some vertex is in front of the hither plane: the kernel keeps its clipping code.
    pub near_crossed: bool,
    pub pieces: Vec<(Piece, Facing)>,
}

/// Push `w` once.
pub fn note(warnings: &mut Vec<Warning>, w: Warning) {
    if !warnings.contains(&w) {
        warnings.push(w);
    }
}

/// A normal from object to lighting coordinates, renormalised (zero ones become +z).
pub fn normal_to_lighting(m: &NormalMatrix, n: [f32; 3], warnings: &mut Vec<Warning>) -> [f32; 3] {
    let v = DVec3::new(f64::from(n[0]), f64::from(n[1]), f64::from(n[2]));
    if !v.is_finite() {
        return n;
    }
    let (out, ok) = m.transform(v);
    if !ok {
        note(warnings, Warning::DegenerateNormal);
    }
    [out.x as f32, out.y as f32, out.z as f32]
}

/// A direction (no translation) from object to lighting coordinates.
pub fn vector_to_lighting(lighting_from_object: &DMat4, v: [f32; 3]) -> [f32; 3] {
    let m = DMat3::from_mat4(*lighting_from_object);
    let out = m * DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]));
    [out.x as f32, out.y as f32, out.z as f32]
}
