//! The transform state: model stack, view, viewport, and the composite matrices derived from
//! them, evaluated lazily and cached (seed 000, 4.2.10).
//!
//! Spaces and names (destination_from_source):
//! - object (model coordinates) --`world_from_object` (M, top of the model stack)--> world
//! - world --`camera_from_world` (look-at)--> camera (right-handed, looking down -z, y up)
//! - camera --`clip_from_camera` (the projection)--> clip; `clip_from_world` = V
//! - clip --`device_from_clip` (D, the viewport)--> device
//! - world --`lighting_from_world` (E of V = G Q E, see [`super::factor`])--> lighting
//!
//! Clip space: `-w <= x, y <= w`, `0 <= z <= w`, `w > 0`, near plane at `z = w`
//! (see [`super::clip`]). Device space, after dividing by w: x, y in pixels with the origin
//! at the top-left corner of the viewport's pixel (0, 0), y down, pixel centres at k + 0.5;
//! z in [0, 1] with 1 at the near plane and 0 at the far plane (larger = nearer). `D` is
//!
//! ```text
//! x_d = x0 + (x_c + w_c) * width / 2       (then / w_c)
//! y_d = y0 + (w_c - y_c) * height / 2
//! z_d = z_c
//! ```
//!
//! V is normalised to a single pyramid when possible (seed 000, 4.2.2 item 4): if the
//! eight corners of the clip volume map back to world points that all have w < 0, V is
//! negated (the same projective map, now with w > 0 inside); if their signs differ, the
//! view is a double pyramid and [`TransformState::pyramid_mode`] says so.
//!
//! Every composite is a cached cell cleared by the setters it depends on (the dirty flags):
//! model changes clear object-dependent composites, view changes view- and object-dependent
//! ones, viewport changes device-dependent ones. [`TransformState::evaluations`] counts
//! recomputations, so tests can check that asking twice computes once.
//!
//! Normals (seed 000, 3.0 step 2 and 9.4): by the inverse transpose of the upper 3x3,
//! renormalised. We use the *cofactor* matrix `cof(A) = det(A) A^-T`, whose columns are cross
//! products of A's columns, times `sign(det A)`: for an invertible A it is the inverse
//! transpose up to a positive scale (removed by renormalising) and it keeps normals on the
//! front side under reflections; for a singular A it still exists (it is the limit of the
//! inverse transpose direction), mapping every normal to the normal of the flattened image,
//! which is what the squashed geometry ("fake shadows") needs. That case is reported as
//! [`Warning::SingularModel`]; a normal the cofactor maps to zero (the model collapsed to a
//! line or a point, or the normal lies in the flattened plane) is replaced by +z with
//! [`Warning::DegenerateNormal`] (seed 000 3.0: "we substitute an arbitrary vector").

use std::sync::Mutex;

use glam::{DMat3, DMat4, DVec3, DVec4};

use super::clip::PyramidMode;
use super::factor::{factor_view, NotFactorizable, ViewFactors};
use super::Warning;

/// A cache cell that can be shared between threads (the renderer reads the transform
/// state from its render threads): `Cell`'s `get` / `set` over a mutex. A poisoned lock
/// still holds a valid value (nothing can panic while it is held), so it is used as is.
#[derive(Debug, Default)]
struct Cell<T>(Mutex<T>);

impl<T: Copy> Cell<T> {
    fn new(v: T) -> Cell<T> {
        Cell(Mutex::new(v))
    }
    fn get(&self) -> T {
        *self.0.lock().unwrap_or_else(|e| e.into_inner())
    }
    fn set(&self, v: T) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = v;
    }
}

/// Why a transform call was refused; the state is left unchanged.
#[derive(Clone, Debug, PartialEq)]
pub enum TransformError {
    /// `pop` with only the base entry on the model stack.
    StackUnderflow,
    /// A NaN or infinite argument.
    NonFinite(&'static str),
    /// A rotation axis of zero length.
    ZeroAxis,
    /// A projection or viewport parameter out of range (the message names it).
    BadParameter(String),
    /// look_at with eye == centre or up parallel to the view direction.
    DegenerateLookAt,
}

impl std::fmt::Display for TransformError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TransformError::StackUnderflow => write!(f, "pop of the model transform stack with nothing pushed"),
            TransformError::NonFinite(what) => write!(f, "{what} has a NaN or infinite value"),
            TransformError::ZeroAxis => write!(f, "rotation axis has zero length"),
            TransformError::BadParameter(m) => f.write_str(m),
            TransformError::DegenerateLookAt => {
                write!(f, "look_at: eye equals centre, or up is parallel to the view direction")
            }
        }
    }
}

impl std::error::Error for TransformError {}

/// The viewport: where clip space lands on the screen, in pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Viewport {
    pub x0: f64,
    pub y0: f64,
    pub width: f64,
    pub height: f64,
}

/// How the current projection was specified (for `render --explain`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    Perspective {
        fov_y: f64,
        aspect: f64,
        near: f64,
        far: f64,
    },
    Orthographic,
    Oblique,
    /// `set_view_matrix`: an arbitrary clip_from_world.
    Arbitrary,
}

/// How the model matrix behaves (seed 000, 4.2.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelClass {
    /// Rotation, reflection, translation (lengths kept).
    Euclidean,
    /// Euclidean times a uniform scale: lighting in model coordinates is cheap.
    Isotropic,
    /// Affine (last row 0 0 0 1) and invertible.
    Affine,
    /// Last row is not 0 0 0 1 (seed 000 9.3).
    Projective,
    /// Not invertible (seed 000 9.4).
    Singular,
}

/// A normal transformation: `normal_out = normalize(matrix * normal_in)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NormalMatrix {
    /// `sign(det) * cof(A)` of the upper 3x3 A.
    pub matrix: DMat3,
    /// A was singular: the cofactor fallback is in use.
    pub singular: bool,
}

impl NormalMatrix {
    /// The normal matrix of the upper 3x3 of `m`.
    pub fn of(m: &DMat4) -> NormalMatrix {
        let a = DMat3::from_mat4(*m);
        let (c0, c1, c2) = (a.x_axis, a.y_axis, a.z_axis);
        let cof = DMat3::from_cols(c1.cross(c2), c2.cross(c0), c0.cross(c1));
        let det = a.determinant();
        let hadamard = c0.length() * c1.length() * c2.length();
        // Written so that a NaN determinant also counts as singular.
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        let singular = !(det.abs() > 1e-12 * hadamard);
        let matrix = if singular || det > 0.0 { cof } else { -cof };
        NormalMatrix { matrix, singular }
    }
    /// Transforms and renormalises `n`. A zero (or non-finite) result is replaced by +z and
    /// reported with `false`.
    pub fn transform(&self, n: DVec3) -> (DVec3, bool) {
        let t = self.matrix * n;
        let len = t.length();
        if len > 0.0 && len.is_finite() {
            (t / len, true)
        } else {
            (DVec3::Z, false)
        }
    }
}

/// The normal at point `p` (object space) under a *projective* `m`: the tangent plane
/// `(n, -n.p)` transformed by `m^-T`, its xyz renormalised. Falls back like
/// [`NormalMatrix::transform`] (`false`) when `m` is singular or the result is zero.
pub fn transform_normal_projective(m: &DMat4, n: DVec3, p: DVec3) -> (DVec3, bool) {
    let Some(inv) = m.try_inverse() else {
        return (DVec3::Z, false);
    };
    let plane = DVec4::new(n.x, n.y, n.z, -n.dot(p));
    let p_out = m.mul_vec4(p.extend(1.0));
    // The plane transforms by m^-T; orient it so the result faces the same way when the
    // point's w turned negative (the plane and -plane are the same plane).
    let mut t = inv.transpose().mul_vec4(plane).truncate();
    if p_out.w < 0.0 {
        t = -t;
    }
    let len = t.length();
    if len > 0.0 && len.is_finite() {
        (t / len, true)
    } else {
        (DVec3::Z, false)
    }
}

/// Seed 000 9.2 for one model-space point: a negative w is negated with the whole point (the
/// same projective point, now with w > 0); a zero w becomes a small positive value (1e-7
/// times the point's largest coordinate, or 1e-7). The second value says whether anything
/// changed ([`Warning::NonPositiveModelW`]).
pub fn sanitize_model_w(p: DVec4) -> (DVec4, bool) {
    if p.w > 0.0 {
        (p, false)
    } else if p.w < 0.0 {
        (-p, true)
    } else {
        let largest = p.truncate().abs().max_element();
        let w = if largest > 0.0 && largest.is_finite() {
            1e-7 * largest
        } else {
            1e-7
        };
        (DVec4::new(p.x, p.y, p.z, w), true)
    }
}

/// Classifies a model matrix (tolerance relative to its scale).
pub fn classify_model(m: &DMat4) -> ModelClass {
    let tol = 1e-12;
    let row3 = m.row(3);
    let scale = m.to_cols_array().iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    if !m.is_finite() || scale == 0.0 {
        return ModelClass::Singular;
    }
    let affine = row3.truncate().abs().max_element() <= tol * scale && row3.w != 0.0;
    if !affine {
        return if m.determinant().abs() <= 1e-12 * scale.powi(4) {
            ModelClass::Singular
        } else {
            ModelClass::Projective
        };
    }
    let a = DMat3::from_mat4(*m) * (1.0 / row3.w);
    let (c0, c1, c2) = (a.x_axis, a.y_axis, a.z_axis);
    let hadamard = c0.length() * c1.length() * c2.length();
    if a.determinant().abs() <= 1e-12 * hadamard {
        return ModelClass::Singular;
    }
    let ata = a.transpose() * a;
    let s2 = (ata.x_axis.x + ata.y_axis.y + ata.z_axis.z) / 3.0;
    let off = (ata - DMat3::from_diagonal(DVec3::splat(s2)))
        .to_cols_array()
        .iter()
        .fold(0.0f64, |acc, &v| acc.max(v.abs()));
    if off > 1e-9 * s2 {
        ModelClass::Affine
    } else if (s2 - 1.0).abs() <= 1e-9 {
        ModelClass::Euclidean
    } else {
        ModelClass::Isotropic
    }
}

/// The model/view/viewport state and its cached composites.
#[derive(Debug)]
pub struct TransformState {
    /// world_from_object stack; never empty, the last entry is current.
    model_stack: Vec<DMat4>,
    camera_from_world: DMat4,
    clip_from_camera: DMat4,
    projection: Projection,
    viewport: Viewport,
    cache: Cache,
    evaluations: Cell<u64>,
}

/// The lazily evaluated composites; `None` = dirty.
#[derive(Debug, Default)]
struct Cache {
    /// V (sign-normalised) and the pyramid mode.
    view: Cell<Option<(DMat4, PyramidMode)>>,
    factors: Cell<Option<Result<ViewFactors, NotFactorizable>>>,
    device_from_clip: Cell<Option<DMat4>>,
    device_from_world: Cell<Option<DMat4>>,
    clip_from_object: Cell<Option<DMat4>>,
    device_from_object: Cell<Option<DMat4>>,
    lighting_from_object: Cell<Option<DMat4>>,
    device_from_lighting: Cell<Option<DMat4>>,
    lighting_normals: Cell<Option<NormalMatrix>>,
    world_normals: Cell<Option<NormalMatrix>>,
    model_class: Cell<Option<ModelClass>>,
}

impl Default for TransformState {
    fn default() -> Self {
        TransformState::new()
    }
}

impl TransformState {
    /// Identity model, camera and projection; a 1x1 viewport.
    pub fn new() -> TransformState {
        TransformState {
            model_stack: vec![DMat4::IDENTITY],
            camera_from_world: DMat4::IDENTITY,
            clip_from_camera: DMat4::IDENTITY,
            projection: Projection::Arbitrary,
            viewport: Viewport {
                x0: 0.0,
                y0: 0.0,
                width: 1.0,
                height: 1.0,
            },
            cache: Cache::default(),
            evaluations: Cell::new(0),
        }
    }

    /// How many composite matrices have been computed so far.
    pub fn evaluations(&self) -> u64 {
        self.evaluations.get()
    }

    // --- dirty flags -------------------------------------------------------------------

    fn model_changed(&mut self) {
        let c = &self.cache;
        c.clip_from_object.set(None);
        c.device_from_object.set(None);
        c.lighting_from_object.set(None);
        c.lighting_normals.set(None);
        c.world_normals.set(None);
        c.model_class.set(None);
    }
    fn view_changed(&mut self) {
        let c = &self.cache;
        c.view.set(None);
        c.factors.set(None);
        c.device_from_world.set(None);
        c.device_from_lighting.set(None);
        self.model_changed();
    }
    fn viewport_changed(&mut self) {
        let c = &self.cache;
        c.device_from_clip.set(None);
        c.device_from_world.set(None);
        c.device_from_object.set(None);
        c.device_from_lighting.set(None);
    }

    /// The cached value in `cell`, computing (and counting) it if dirty.
    fn cached<T: Copy>(&self, cell: &Cell<Option<T>>, compute: impl FnOnce() -> T) -> T {
        if let Some(v) = cell.get() {
            return v;
        }
        let v = compute();
        self.evaluations.set(self.evaluations.get() + 1);
        cell.set(Some(v));
        v
    }

    // --- model stack -------------------------------------------------------------------

    pub fn world_from_object(&self) -> DMat4 {
        *self.model_stack.last().unwrap_or(&DMat4::IDENTITY)
    }
    /// Replaces the current model matrix.
    pub fn set_model(&mut self, world_from_object: DMat4) -> Result<(), TransformError> {
        if !world_from_object.is_finite() {
            return Err(TransformError::NonFinite("model matrix"));
        }
        if let Some(top) = self.model_stack.last_mut() {
            *top = world_from_object;
        }
        self.model_changed();
        Ok(())
    }
    /// Saves the current model matrix.
    pub fn push(&mut self) {
        let top = self.world_from_object();
        self.model_stack.push(top);
    }
    /// Restores the model matrix saved by the matching `push`.
    pub fn pop(&mut self) -> Result<(), TransformError> {
        if self.model_stack.len() <= 1 {
            return Err(TransformError::StackUnderflow);
        }
        self.model_stack.pop();
        self.model_changed();
        Ok(())
    }
    /// Depth of the model stack (1 = nothing pushed).
    pub fn stack_depth(&self) -> usize {
        self.model_stack.len()
    }
    /// `M = M * m`: `m` applies to object coordinates first (RenderMan ConcatTransform).
    pub fn concat(&mut self, m: DMat4) -> Result<(), TransformError> {
        if !m.is_finite() {
            return Err(TransformError::NonFinite("concatenated matrix"));
        }
        let top = self.world_from_object() * m;
        self.set_model(top)
    }
    pub fn translate(&mut self, t: DVec3) -> Result<(), TransformError> {
        self.concat(DMat4::from_translation(t))
    }
    /// Rotation by `degrees` about `axis` (right-handed, as RenderMan's Rotate).
    pub fn rotate_degrees(&mut self, degrees: f64, axis: DVec3) -> Result<(), TransformError> {
        if !degrees.is_finite() || !axis.is_finite() {
            return Err(TransformError::NonFinite("rotation"));
        }
        let len = axis.length();
        if len == 0.0 || !len.is_finite() {
            return Err(TransformError::ZeroAxis);
        }
        self.concat(DMat4::from_axis_angle(axis / len, degrees.to_radians()))
    }
    /// Scale (zero factors are allowed: they make M singular, reported as a warning).
    pub fn scale(&mut self, s: DVec3) -> Result<(), TransformError> {
        self.concat(DMat4::from_scale(s))
    }

    // --- view --------------------------------------------------------------------------

    pub fn camera_from_world(&self) -> DMat4 {
        self.camera_from_world
    }
    pub fn clip_from_camera(&self) -> DMat4 {
        self.clip_from_camera
    }
    pub fn projection(&self) -> Projection {
        self.projection
    }
    /// Camera at `eye` looking at `centre`, `up` towards screen-up.
    pub fn look_at(&mut self, eye: DVec3, centre: DVec3, up: DVec3) -> Result<(), TransformError> {
        if !(eye.is_finite() && centre.is_finite() && up.is_finite()) {
            return Err(TransformError::NonFinite("look_at"));
        }
        let dir = centre - eye;
        if dir.length() == 0.0 || dir.cross(up).length() <= 1e-12 * dir.length() * up.length() {
            return Err(TransformError::DegenerateLookAt);
        }
        self.camera_from_world = look_at_matrix(eye, centre, up);
        self.view_changed();
        Ok(())
    }
    /// Perspective with vertical field of view `fov_y` (radians), `aspect` = width/height,
    /// near and far distances (`far` may be infinite). Near maps to z = 1, far to z = 0.
    pub fn perspective(&mut self, fov_y: f64, aspect: f64, near: f64, far: f64) -> Result<(), TransformError> {
        self.clip_from_camera = perspective_matrix(fov_y, aspect, near, far)?;
        self.projection = Projection::Perspective {
            fov_y,
            aspect,
            near,
            far,
        };
        self.view_changed();
        Ok(())
    }
    /// Orthographic box `[left, right] x [bottom, top]` in camera x, y, from `near` to `far`
    /// along the view direction (-z).
    pub fn orthographic(&mut self, bounds: [f64; 4], near: f64, far: f64) -> Result<(), TransformError> {
        self.clip_from_camera = orthographic_matrix(bounds, near, far)?;
        self.projection = Projection::Orthographic;
        self.view_changed();
        Ok(())
    }
    /// Oblique parallel projection along `direction` (camera space, pointing away from the
    /// viewer, `direction.z < 0`), with the window `bounds` on the near plane.
    pub fn oblique(&mut self, bounds: [f64; 4], near: f64, far: f64, direction: DVec3) -> Result<(), TransformError> {
        self.clip_from_camera = oblique_matrix(bounds, near, far, direction)?;
        self.projection = Projection::Oblique;
        self.view_changed();
        Ok(())
    }
    /// An arbitrary view: `clip_from_world` given directly (the camera becomes identity).
    pub fn set_view_matrix(&mut self, clip_from_world: DMat4) -> Result<(), TransformError> {
        if !clip_from_world.is_finite() {
            return Err(TransformError::NonFinite("view matrix"));
        }
        self.camera_from_world = DMat4::IDENTITY;
        self.clip_from_camera = clip_from_world;
        self.projection = Projection::Arbitrary;
        self.view_changed();
        Ok(())
    }

    // --- viewport ----------------------------------------------------------------------

    pub fn viewport(&self) -> Viewport {
        self.viewport
    }
    pub fn set_viewport(&mut self, x0: f64, y0: f64, width: f64, height: f64) -> Result<(), TransformError> {
        if !(x0.is_finite() && y0.is_finite() && width.is_finite() && height.is_finite()) {
            return Err(TransformError::NonFinite("viewport"));
        }
        if width <= 0.0 || height <= 0.0 {
            return Err(TransformError::BadParameter(format!(
                "viewport size must be positive, got {width} x {height}"
            )));
        }
        self.viewport = Viewport { x0, y0, width, height };
        self.viewport_changed();
        Ok(())
    }

    // --- composites --------------------------------------------------------------------

    fn view(&self) -> (DMat4, PyramidMode) {
        self.cached(&self.cache.view, || {
            normalise_pyramid(self.clip_from_camera * self.camera_from_world)
        })
    }
    /// V, negated if that makes the view a single pyramid with w > 0.
    pub fn clip_from_world(&self) -> DMat4 {
        self.view().0
    }
    /// Single pyramid, or double (seed 000 9.6) when the view volume wraps around infinity.
    pub fn pyramid_mode(&self) -> PyramidMode {
        self.view().1
    }
    /// G Q E / S H E of V, or why not.
    pub fn view_factors(&self) -> Result<ViewFactors, NotFactorizable> {
        self.cached(&self.cache.factors, || factor_view(&self.clip_from_world()))
    }
    /// E, or the identity when V is not factorizable (lighting then happens in world
    /// coordinates, seed 000 9.5).
    pub fn lighting_from_world(&self) -> DMat4 {
        self.view_factors()
            .map(|f| f.lighting_from_world())
            .unwrap_or(DMat4::IDENTITY)
    }
    pub fn device_from_clip(&self) -> DMat4 {
        self.cached(&self.cache.device_from_clip, || device_from_clip(self.viewport))
    }
    pub fn device_from_world(&self) -> DMat4 {
        self.cached(&self.cache.device_from_world, || {
            self.device_from_clip() * self.clip_from_world()
        })
    }
    pub fn clip_from_object(&self) -> DMat4 {
        self.cached(&self.cache.clip_from_object, || {
            self.clip_from_world() * self.world_from_object()
        })
    }
    pub fn device_from_object(&self) -> DMat4 {
        self.cached(&self.cache.device_from_object, || {
            self.device_from_world() * self.world_from_object()
        })
    }
    pub fn lighting_from_object(&self) -> DMat4 {
        self.cached(&self.cache.lighting_from_object, || {
            self.lighting_from_world() * self.world_from_object()
        })
    }
    /// D G Q (or D V when V is not factorizable).
    pub fn device_from_lighting(&self) -> DMat4 {
        self.cached(&self.cache.device_from_lighting, || {
            let clip_from_lighting = match self.view_factors() {
                Ok(f) => f.clip_from_lighting(),
                Err(_) => self.clip_from_world(),
            };
            self.device_from_clip() * clip_from_lighting
        })
    }
    /// Normals from object to lighting coordinates.
    pub fn lighting_normal_matrix(&self) -> NormalMatrix {
        self.cached(&self.cache.lighting_normals, || {
            NormalMatrix::of(&self.lighting_from_object())
        })
    }
    /// Normals from object to world coordinates.
    pub fn world_normal_matrix(&self) -> NormalMatrix {
        self.cached(&self.cache.world_normals, || {
            NormalMatrix::of(&self.world_from_object())
        })
    }
    pub fn model_class(&self) -> ModelClass {
        self.cached(&self.cache.model_class, || classify_model(&self.world_from_object()))
    }

    /// The six matrices of the kernel ABI's `spaces` block, row-major f32, in its order:
    /// device_from_object, device_from_world, device_from_lighting, object_from_device,
    /// world_from_device, lighting_from_device. A matrix without an inverse gives zeros there.
    pub fn abi_spaces(&self) -> [[f32; 16]; 6] {
        abi_spaces_from([
            self.device_from_object(),
            self.device_from_world(),
            self.device_from_lighting(),
        ])
    }

    /// The ill-behaved cases the current state is in (seed 000 section 9), each once.
    pub fn warnings(&self) -> Vec<Warning> {
        let mut out = vec![];
        match self.model_class() {
            ModelClass::Singular => out.push(Warning::SingularModel),
            ModelClass::Projective => out.push(Warning::ProjectiveModel),
            _ => {}
        }
        match self.view_factors() {
            Err(NotFactorizable::Singular) | Err(NotFactorizable::NonFinite) => out.push(Warning::SingularView),
            Err(reason) => out.push(Warning::NonFactorizableView(reason)),
            Ok(_) => {}
        }
        if self.pyramid_mode() == PyramidMode::Double {
            out.push(Warning::DoublePyramidView);
        }
        out
    }
}

/// camera_from_world for a camera at `eye` looking at `centre` (right-handed: the camera looks
/// down its -z, `up` projects onto its +y). The caller checks the arguments are not degenerate.
pub fn look_at_matrix(eye: DVec3, centre: DVec3, up: DVec3) -> DMat4 {
    let forward = (centre - eye).normalize();
    let right = forward.cross(up).normalize();
    let cam_up = right.cross(forward);
    DMat4::from_cols(
        DVec4::new(right.x, cam_up.x, -forward.x, 0.0),
        DVec4::new(right.y, cam_up.y, -forward.y, 0.0),
        DVec4::new(right.z, cam_up.z, -forward.z, 0.0),
        DVec4::new(-right.dot(eye), -cam_up.dot(eye), forward.dot(eye), 1.0),
    )
}

/// D for a viewport (see the module doc).
pub fn device_from_clip(vp: Viewport) -> DMat4 {
    let (hw, hh) = (vp.width * 0.5, vp.height * 0.5);
    DMat4::from_cols(
        DVec4::new(hw, 0.0, 0.0, 0.0),
        DVec4::new(0.0, -hh, 0.0, 0.0),
        DVec4::new(0.0, 0.0, 1.0, 0.0),
        DVec4::new(vp.x0 + hw, vp.y0 + hh, 0.0, 1.0),
    )
}

/// `v` or `-v`, whichever keeps w > 0 in the view volume, and whether the volume is a
/// single or a double pyramid (seed 000 4.2.2 item 4: map the 8 clip-volume corners back to
/// world space and compare the signs of their w).
pub fn normalise_pyramid(v: DMat4) -> (DMat4, PyramidMode) {
    let Some(inv) = v.try_inverse() else {
        return (v, PyramidMode::Single);
    };
    let mut pos = 0;
    let mut neg = 0;
    for x in [-1.0, 1.0] {
        for y in [-1.0, 1.0] {
            for z in [0.0, 1.0] {
                let w = inv.mul_vec4(DVec4::new(x, y, z, 1.0)).w;
                if w > 0.0 {
                    pos += 1;
                } else if w < 0.0 {
                    neg += 1;
                }
            }
        }
    }
    if pos == 8 {
        (v, PyramidMode::Single)
    } else if neg == 8 {
        (-v, PyramidMode::Single)
    } else {
        (v, PyramidMode::Double)
    }
}

fn check_finite(values: &[f64], what: &'static str) -> Result<(), TransformError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(TransformError::NonFinite(what))
    }
}

/// The perspective clip_from_camera (see [`TransformState::perspective`]).
pub fn perspective_matrix(fov_y: f64, aspect: f64, near: f64, far: f64) -> Result<DMat4, TransformError> {
    check_finite(&[fov_y, aspect, near], "perspective")?;
    if far.is_nan() {
        return Err(TransformError::NonFinite("perspective far"));
    }
    if !(fov_y > 0.0 && fov_y < std::f64::consts::PI) {
        return Err(TransformError::BadParameter(format!(
            "perspective field of view must be in (0, pi) radians, got {fov_y}"
        )));
    }
    if aspect <= 0.0 {
        return Err(TransformError::BadParameter(format!(
            "perspective aspect must be positive, got {aspect}"
        )));
    }
    if !(near > 0.0 && far > near) {
        return Err(TransformError::BadParameter(format!(
            "perspective needs 0 < near < far, got near {near}, far {far}"
        )));
    }
    let c = 1.0 / (fov_y * 0.5).tan();
    // z_c = a z_e + b with z_c / w_c = 1 at z_e = -near and 0 at z_e = -far; w_c = -z_e.
    let (a, b) = if far.is_infinite() {
        (0.0, near)
    } else {
        (near / (far - near), near * far / (far - near))
    };
    Ok(DMat4::from_cols(
        DVec4::new(c / aspect, 0.0, 0.0, 0.0),
        DVec4::new(0.0, c, 0.0, 0.0),
        DVec4::new(0.0, 0.0, a, -1.0),
        DVec4::new(0.0, 0.0, b, 0.0),
    ))
}

/// The orthographic clip_from_camera (see [`TransformState::orthographic`]).
pub fn orthographic_matrix(bounds: [f64; 4], near: f64, far: f64) -> Result<DMat4, TransformError> {
    let [l, r, b, t] = bounds;
    check_finite(&[l, r, b, t, near, far], "orthographic")?;
    if !(r != l && t != b && far > near) {
        return Err(TransformError::BadParameter(format!(
            "orthographic needs left != right, bottom != top, near < far; got {bounds:?}, {near}, {far}"
        )));
    }
    Ok(DMat4::from_cols(
        DVec4::new(2.0 / (r - l), 0.0, 0.0, 0.0),
        DVec4::new(0.0, 2.0 / (t - b), 0.0, 0.0),
        DVec4::new(0.0, 0.0, 1.0 / (far - near), 0.0),
        DVec4::new(-(r + l) / (r - l), -(t + b) / (t - b), far / (far - near), 1.0),
    ))
}

/// The oblique clip_from_camera: orthographic after a shear that makes `direction`
/// parallel to -z, anchored at the near plane.
pub fn oblique_matrix(bounds: [f64; 4], near: f64, far: f64, direction: DVec3) -> Result<DMat4, TransformError> {
    if !direction.is_finite() {
        return Err(TransformError::NonFinite("oblique direction"));
    }
    if direction.z >= 0.0 {
        return Err(TransformError::BadParameter(format!(
            "oblique projection direction must point away from the viewer (z < 0), got {direction}"
        )));
    }
    let (hx, hy) = (-direction.x / direction.z, -direction.y / direction.z);
    // x' = x + hx (z + near): moving along `direction` keeps x', the near plane is fixed.
    let shear = DMat4::from_cols(
        DVec4::new(1.0, 0.0, 0.0, 0.0),
        DVec4::new(0.0, 1.0, 0.0, 0.0),
        DVec4::new(hx, hy, 1.0, 0.0),
        DVec4::new(hx * near, hy * near, 0.0, 1.0),
    );
    Ok(orthographic_matrix(bounds, near, far)? * shear)
}

/// The kernel ABI's `spaces` block from device_from_object, device_from_world and
/// device_from_lighting: those three, then their inverses (taken in f64 and rounded once; a
/// matrix without an inverse gives zeros), each row-major f32.
pub fn abi_spaces_from(device_from: [DMat4; 3]) -> [[f32; 16]; 6] {
    let inv = |m: DMat4| m.try_inverse().unwrap_or(DMat4::ZERO);
    let mats = [
        device_from[0],
        device_from[1],
        device_from[2],
        inv(device_from[0]),
        inv(device_from[1]),
        inv(device_from[2]),
    ];
    mats.map(|m| {
        let cols = m.to_cols_array_2d();
        let mut out = [0f32; 16];
        for (c, col) in cols.iter().enumerate() {
            for (r, v) in col.iter().enumerate() {
                out[r * 4 + c] = *v as f32;
            }
        }
        out
    })
}
