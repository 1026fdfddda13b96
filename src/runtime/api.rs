//! The primitive API (seed 004's OpenGL extension as Rust calls) and the instances it builds.
//!
//! State follows OpenGL: `material` values are current state that persists across primitives;
//! `rast_param` values belong to the primitive between `begin` and `end`. At every sequence
//! point (`sequence_point`, or `vertex` = set `vertex` + sequence point) the current values of
//! the per-sequence-point parameters and of every shading parameter are recorded. At `end` the
//! instance is built: its [`VariantKey`] and its argument block, laid out exactly as
//! `abi::ArgLayout::new` says.
//!
//! Shading parameters: a name becomes a shading parameter at its first `material` value, which
//! fixes its component count; G-buffer planes are allocated then, in that order, and the
//! key's bindings list every shading parameter in that same order. `material_interp` chooses
//! how a parameter is interpolated (`linear`, `perspective_linear`, any other per-sequence-point
//! kind a primitive handles, `constant`, or a shared interpolator with its arguments); a
//! parameter without one is `constant` (its value current at `end`).
//!
//! Geometry: points, normals and vectors are recorded in object coordinates; at `end` the
//! instance goes through the geometry stage ([`super::geometry`]): clip codes, trivial
//! reject / accept, runtime clipping and culling for facets, points to homogeneous device
//! coordinates, normals and vectors to lighting coordinates. One `end` may thus yield no
//! instance (rejected, culled) or several (a clipped polygon's fan). The transform state
//! (model stack, camera, viewport = image) and the shading setup are public fields.
//!
//! Every call validates its input and returns an [`ApiIssue`] for an error (the call then has
//! no effect, or — for a bad `begin` — opens a block that is discarded at `end`, so one
//! mistake does not cascade). Warnings (zero-filled parameters, ...) are queued and taken
//! with [`Renderer::take_warnings`]. No input panics.

use std::collections::HashMap;
use std::sync::Arc;

use glam::{DMat4, DVec3, DVec4, Mat4};

use crate::abi::{interpolator_arg_words, ArgLayout, Binding, BindingKind, ParamSlot, VariantKey};
use crate::diag::Severity;
use crate::ir::{FuncId, FuncKind, Geometry, ParamRole, Program};

use super::geometry::{self, ClipOutcome, GeometryState};
use super::instances::{
    arg_floats, directions_to_lighting, instance_with_points, line_instances, param_spans, write_words,
};
use super::shading::language::{LanguageShading, ShaderArg, ShaderUse, ShadingCache, SURFACE_PARAM};
use super::shading::ShadingSetup;
use super::value::{encode, encode_default, EncodeError, Value};
use crate::ir::ParamSpace;
use crate::pipeline::face::{CullMode, Facing};
use crate::pipeline::transform::TransformError;
use crate::pipeline::{GeometryType, Warning};
use crate::syntax::ast::ItemKind;

/// The reserved shading parameter that carries a facet's facing to shading (`distinguish`).
pub const FACING_PARAM: &str = "facing";
/// The shading parameter holding the surface normal (given in object coordinates, stored in
/// lighting coordinates).
pub const NORMAL_PARAM: &str = "N";

/// Largest image side accepted, in pixels (keeps a typo from allocating gigabytes).
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// Largest tile side accepted.
pub const MAX_TILE_SIDE: u32 = 4096;
/// Largest frame a render allocates: depth, write counts, colours (counted whether or not
/// the scene shades) and every G-buffer plane. A 16384 x 16384 frame takes 1 GiB per plane,
/// so a scene with many or wide shading parameters at that size would otherwise abort the
/// process when the allocation fails; above this the render is refused with E0803.
pub const MAX_FRAME_BYTES: u64 = 16 << 30;

/// Stack of each thread of a [`render_pool`](super::render_pool): room for
/// primitives with large local arrays nested in calls (a kernel's frame holds its arrays;
/// one whose frame does not fit records a run-time error instead of running, see
/// `abi::TileCtx::stack_limit`). Reserved, not committed: pages are used as touched.
pub const RENDER_THREAD_STACK: usize = 64 << 20;
/// Largest number of components of one shading parameter.
pub const MAX_COMPONENTS: usize = 64;

/// Which argument of a call an issue is about (the scene reader underlines that token).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Target {
    /// The call as a whole.
    Call,
    /// The name argument (primitive or parameter name).
    Name,
    /// The value components.
    Values,
    /// The interpolation kind of `material_interp`.
    Kind,
    /// The i-th `name=value` argument of `material_interp` or of a shader line.
    Arg(usize),
}

/// An error or warning from an API call.
#[derive(Clone, Debug, PartialEq)]
pub struct ApiIssue {
    pub severity: Severity,
    /// Stable code (`E07xx` errors, `W07xx` warnings; listed in docs/scene.md).
    pub code: &'static str,
    pub message: String,
    pub target: Target,
    /// "did you mean `x`?" for an unknown name with a close known one.
    pub help: Option<String>,
}

impl ApiIssue {
    fn error(code: &'static str, target: Target, message: impl Into<String>) -> ApiIssue {
        ApiIssue {
            severity: Severity::Error,
            code,
            message: message.into(),
            target,
            help: None,
        }
    }
    fn warning(code: &'static str, target: Target, message: impl Into<String>) -> ApiIssue {
        ApiIssue {
            severity: Severity::Warning,
            code,
            message: message.into(),
            target,
            help: None,
        }
    }
    /// For an unknown `name`: the help [`crate::diag::did_you_mean`] gives among
    /// `candidates`, the names known there.
    fn suggest<'c>(mut self, name: &str, candidates: impl IntoIterator<Item = &'c str>) -> ApiIssue {
        self.help = crate::diag::did_you_mean(name, candidates);
        self
    }
}

impl std::fmt::Display for ApiIssue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "[{}] {}", self.code, self.message)
    }
}

/// Frame-wide settings.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    pub width: u32,
    pub height: u32,
    /// Tile side in pixels (tiles are square; edge tiles are cut by the image). A render
    /// rounds it up to whole pixel groups (`frame::tile_side`: 5 renders as 8), because
    /// kernels render straight into the frame, a group at a time, and tiles must not share
    /// a group.
    pub tile_size: u32,
    /// Compile kernels that count depth writes per pixel (`Frame::write_count_at`).
    pub count_writes: bool,
    pub background: [f32; 3],
    /// Run each instance of a primitive that only calls other primitives (`abi::expands`)
    /// once in `MODE_EXPAND` and render the calls it makes as instances of their own, binned
    /// by their own bounds (the frame is bit-identical either way). `false` runs its whole
    /// setup in every tile its bound touches (kept to compare against, and by the bench).
    pub expand_calls: bool,
    /// Most argument words (plus a fixed charge per call) the expansion of one frame may
    /// record; an instance whose expansion would exceed it is rendered per tile instead.
    pub expand_budget_words: usize,
    /// Fuel of one kernel invocation's setup (`TileCtx::fuel`, `abi::DEFAULT_FUEL`): loop
    /// trips its setup and the setups of the primitives it calls may make. A draw whose
    /// setup runs out in its bound run is drawn nowhere (`abi::ctx` has the rules).
    pub setup_fuel: u64,
    /// Fuel of one draw's pixel part (`TileCtx::pixel_fuel`, `abi::DEFAULT_PIXEL_FUEL`),
    /// shared out over the pixel groups of its bound rectangle, and the least a group gets
    /// (`TileCtx::group_fuel_floor`, `abi::DEFAULT_GROUP_FUEL_FLOOR`).
    pub pixel_fuel: u64,
    pub group_fuel_floor: u64,
    /// Shade the fixed lines (`light`, `ambient`, `surface`, `fog`, `texture`) with the
    /// library shaders they map to (`LanguageShading::from_fixed`) instead of the Rust
    /// pass. Language shader lines, when a scene has any, win either way.
    pub fixed_shading_in_language: bool,
    /// Shading parameters the caller reads from the frame after the render (`render
    /// --param`, test expectations). A frame shaded by language shaders allocates planes
    /// only for the parameters its shaders read and these (`super::live`).
    pub keep_params: Vec<String>,
    /// Samples per pixel, one of `samples::ALLOWED_SAMPLES` (a render treats any other count
    /// as 1; `set_samples` rejects them): each sample renders and shades its own buffers at
    /// its position in the standard pattern, and the pixels' colours resolve from them with
    /// `filter` (`super::samples`).
    pub samples: u32,
    pub filter: super::samples::Filter,
}

/// Default `RenderOptions::expand_budget_words`: 2^25 words (128 MiB of recorded calls).
pub const EXPAND_BUDGET_WORDS: usize = 1 << 25;

impl Default for RenderOptions {
    fn default() -> RenderOptions {
        RenderOptions {
            width: 320,
            height: 240,
            tile_size: 64,
            count_writes: false,
            background: [0.0; 3],
            expand_calls: true,
            expand_budget_words: EXPAND_BUDGET_WORDS,
            setup_fuel: crate::abi::DEFAULT_FUEL,
            pixel_fuel: crate::abi::DEFAULT_PIXEL_FUEL,
            group_fuel_floor: crate::abi::DEFAULT_GROUP_FUEL_FLOOR,
            fixed_shading_in_language: false,
            keep_params: vec![],
            samples: 1,
            filter: super::samples::Filter::Box,
        }
    }
}

/// How a shading parameter is interpolated (the API's view of a [`BindingKind`]).
#[derive(Clone, Debug, PartialEq)]
enum Interp {
    Kind(String),
    Constant,
    /// A shared interpolator and its argument words (`abi::interpolator_arg_words` long).
    Shared {
        name: String,
        args: Vec<u32>,
    },
}

/// A shading parameter: a name with a fixed component count and G-buffer planes.
#[derive(Clone, Debug)]
pub struct ShadingParam {
    pub name: String,
    pub components: u32,
    /// Its planes are `first_plane .. first_plane + components`.
    pub first_plane: u32,
    interp: Interp,
    current: Vec<f32>,
}

/// The values recorded at one sequence point.
#[derive(Clone, Debug)]
struct SeqPoint {
    /// Per parameter index of the primitive: the encoded element, if one was current.
    per_seq: Vec<Option<Vec<u32>>>,
    /// Per shading parameter: its value (shading parameters defined later are missing).
    shading: Vec<Vec<f32>>,
}

/// The primitive between `begin` and `end`.
#[derive(Debug)]
struct Block {
    /// `None` when `begin` named no primitive: calls are accepted quietly and `end` drops it.
    func: Option<FuncId>,
    per_prim: HashMap<usize, Vec<u32>>,
    per_seq_current: HashMap<usize, Vec<u32>>,
    seq_points: Vec<SeqPoint>,
    /// W0703 (no `vertex` parameter) was reported for this block.
    warned_no_vertex: bool,
}

/// A primitive ready to render: which function, its key, its argument block.
#[derive(Clone, Debug)]
pub struct Instance {
    pub func: FuncId,
    /// The key without `count_writes` (the renderer sets that from its options).
    pub key: VariantKey,
    pub n_seq: u32,
    pub args: Vec<u32>,
}

/// The API state: current transform, shading parameters, the open primitive, the instances
/// submitted so far.
pub struct Renderer {
    program: Arc<Program>,
    pub options: RenderOptions,
    /// Model stack, camera, viewport, clip planes, culling (the geometry pipeline's state).
    pub geometry: GeometryState,
    /// Lights, materials, fog, texture: what the deferred shading pass does.
    pub shading_setup: ShadingSetup,
    /// Language shaders: surface bindings, lights and the atmosphere (when any is given,
    /// they shade the frame instead of `shading_setup`).
    pub language: LanguageShading,
    /// The language shading compiled for the last frame.
    pub(crate) shading_cache: ShadingCache,
    /// Pipeline warnings already reported (each kind once per renderer).
    pipeline_warnings: Vec<Warning>,
    /// `--explain`: per (primitive, pipeline description, clip outcome), how many instances.
    explain: std::collections::BTreeMap<(String, String, ClipOutcome), usize>,
    shading: Vec<ShadingParam>,
    /// `material_interp` calls for names that have no `material` value yet.
    pending_interp: HashMap<String, Interp>,
    block: Option<Block>,
    instances: Vec<Instance>,
    /// The instances' distinct (primitive, key) pairs, kept as instances are added.
    variants: Variants,
    warnings: Vec<ApiIssue>,
    /// The kinds the program's `interpolation` arms name, found at the first
    /// `material_interp` of a per-sequence-point kind (see `warn_unknown_kind`).
    arm_kinds: Option<Vec<String>>,
}

/// The distinct (primitive, key) pairs of the submitted instances in first-use order, and
/// which one each instance has: the renderer compiles one kernel per pair and finds an
/// instance's by index, without comparing, hashing or cloning keys per instance per frame.
/// Keys are compared without `count_writes` (the renderer sets that from its options).
#[derive(Default)]
pub(crate) struct Variants {
    /// (primitive, key), first-use order.
    list: Vec<(FuncId, VariantKey)>,
    /// Per instance, in order: its index into `list`.
    of_instance: Vec<usize>,
    /// `list` inverted (keys with `count_writes` false).
    index: HashMap<(FuncId, VariantKey), usize>,
}

impl Variants {
    /// The distinct (primitive, key) pairs, first-use order.
    pub(crate) fn list(&self) -> &[(FuncId, VariantKey)] {
        &self.list
    }
    /// Per instance: its index into [`Variants::list`].
    pub(crate) fn of_instance(&self) -> &[usize] {
        &self.of_instance
    }
    /// Record the next instance's variant.
    pub(crate) fn add(&mut self, inst: &Instance) {
        // Consecutive instances mostly share their primitive and key: compare with the
        // previous one before hashing.
        let previous = self.of_instance.last().copied();
        let same = previous.filter(|&v| {
            let (func, key) = &self.list[v];
            *func == inst.func && key.trivial_accept == inst.key.trivial_accept && key.bindings == inst.key.bindings
        });
        let v = same.unwrap_or_else(|| {
            let lookup = (
                inst.func,
                VariantKey {
                    count_writes: false,
                    ..inst.key.clone()
                },
            );
            let next = self.list.len();
            *self.index.entry(lookup.clone()).or_insert_with(|| {
                self.list.push(lookup);
                next
            })
        });
        self.of_instance.push(v);
    }
}

impl Renderer {
    pub fn new(program: Arc<Program>) -> Renderer {
        Renderer {
            program,
            options: RenderOptions::default(),
            geometry: GeometryState::new(RenderOptions::default().width, RenderOptions::default().height),
            shading_setup: ShadingSetup::default(),
            language: LanguageShading::default(),
            shading_cache: ShadingCache::default(),
            pipeline_warnings: vec![],
            explain: std::collections::BTreeMap::new(),
            shading: vec![],
            pending_interp: HashMap::new(),
            block: None,
            instances: vec![],
            variants: Variants::default(),
            warnings: vec![],
            arm_kinds: None,
        }
    }

    pub fn program(&self) -> &Arc<Program> {
        &self.program
    }
    pub fn instances(&self) -> &[Instance] {
        &self.instances
    }
    /// The distinct (primitive, key) pairs of the instances, in first-use order (keys with
    /// `count_writes` false), and per instance the index of its pair (every shading
    /// parameter bound: a frame may drop some, `super::live`).
    pub(crate) fn variants(&self) -> &Variants {
        &self.variants
    }
    pub fn shading_params(&self) -> &[ShadingParam] {
        &self.shading
    }
    /// Total G-buffer planes allocated so far.
    pub fn num_planes(&self) -> u32 {
        self.shading.iter().map(|p| p.components).sum()
    }
    pub fn in_primitive(&self) -> bool {
        self.block.is_some()
    }
    /// Warnings queued by the calls so far (drained).
    pub fn take_warnings(&mut self) -> Vec<ApiIssue> {
        std::mem::take(&mut self.warnings)
    }

    // ---- frame settings ----

    pub fn set_image_size(&mut self, width: u32, height: u32) -> Result<(), ApiIssue> {
        if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
            return Err(ApiIssue::error(
                "E0708",
                Target::Values,
                format!("image size {width}x{height} is out of range (1..={MAX_IMAGE_SIDE} per side)"),
            ));
        }
        self.options.width = width;
        self.options.height = height;
        // The viewport follows the image (both sides are positive here).
        let _ = self
            .geometry
            .transforms
            .set_viewport(0.0, 0.0, f64::from(width), f64::from(height));
        Ok(())
    }

    pub fn set_tile_size(&mut self, side: u32) -> Result<(), ApiIssue> {
        if side == 0 || side > MAX_TILE_SIDE {
            return Err(ApiIssue::error(
                "E0708",
                Target::Values,
                format!("tile size {side} is out of range (1..={MAX_TILE_SIDE})"),
            ));
        }
        self.options.tile_size = side;
        Ok(())
    }

    /// Samples per pixel (`runtime::samples`): 1, 2, 4, 8 or 16.
    pub fn set_samples(&mut self, n: u32) -> Result<(), ApiIssue> {
        if super::samples::sample_positions(n).is_none() {
            return Err(ApiIssue::error(
                "E0708",
                Target::Values,
                super::samples::samples_error(n),
            ));
        }
        self.options.samples = n;
        Ok(())
    }

    /// How a multisampled frame's samples resolve to its pixels.
    pub fn set_filter(&mut self, filter: super::samples::Filter) {
        self.options.filter = filter;
    }

    pub fn set_background(&mut self, rgb: [f32; 3]) {
        self.options.background = rgb;
    }

    /// Replace the current transform by a `device_from_object` matrix given directly: the
    /// model stack's top becomes the identity and there is no camera (points, lights and
    /// normals are then in one "world" whose device transform is this matrix).
    pub fn set_transform(&mut self, device_from_object: Mat4) {
        if device_from_object.determinant() == 0.0 || !device_from_object.is_finite() {
            self.warnings.push(ApiIssue::warning(
                "W0702",
                Target::Values,
                "transform is singular or not finite; points will be passed through it as given",
            ));
        }
        let m = device_from_object.as_dmat4();
        // A non-finite matrix is kept as the identity for the model and used as given for
        // the device: its points become NaN and are dropped by the clip codes.
        let _ = self.geometry.transforms.set_model(DMat4::IDENTITY);
        self.geometry.direct = Some(m);
    }

    /// The current `device_from_object` (model, view and viewport composed).
    pub fn transform(&self) -> Mat4 {
        self.geometry.device_from_object().as_mat4()
    }

    fn transform_result(&mut self, r: Result<(), TransformError>) -> Result<(), ApiIssue> {
        r.map_err(|e| ApiIssue::error("E0710", Target::Values, e.to_string()))
    }

    /// Orthographic camera: the camera-space box x in [left, right], y in [bottom, top],
    /// z in [-far, -near] fills the viewport, depth 1 at near and 0 at far.
    pub fn ortho(&mut self, left: f32, right: f32, bottom: f32, top: f32, near: f32, far: f32) {
        let _ = self.ortho_checked(
            [left, right, bottom, top].map(f64::from),
            f64::from(near),
            f64::from(far),
        );
    }

    /// [`Renderer::ortho`] reporting bad parameters.
    pub fn ortho_checked(&mut self, bounds: [f64; 4], near: f64, far: f64) -> Result<(), ApiIssue> {
        let r = self.geometry.transforms.orthographic(bounds, near, far);
        if r.is_ok() {
            self.geometry.direct = None;
        }
        self.transform_result(r)
    }

    /// Perspective camera, vertical field of view in degrees, aspect from the image size.
    pub fn perspective(&mut self, fov_y_degrees: f32, near: f32, far: f32) {
        let _ = self.perspective_checked(f64::from(fov_y_degrees), f64::from(near), f64::from(far));
    }

    /// [`Renderer::perspective`] reporting bad parameters.
    pub fn perspective_checked(&mut self, fov_y_degrees: f64, near: f64, far: f64) -> Result<(), ApiIssue> {
        let aspect = f64::from(self.options.width) / f64::from(self.options.height);
        let r = self
            .geometry
            .transforms
            .perspective(fov_y_degrees.to_radians(), aspect, near, far);
        if r.is_ok() {
            self.geometry.direct = None;
        }
        self.transform_result(r)
    }

    /// Oblique parallel projection along `direction` (camera space, away from the viewer).
    pub fn oblique(&mut self, bounds: [f64; 4], near: f64, far: f64, direction: [f64; 3]) -> Result<(), ApiIssue> {
        let r = self
            .geometry
            .transforms
            .oblique(bounds, near, far, DVec3::from_array(direction));
        if r.is_ok() {
            self.geometry.direct = None;
        }
        self.transform_result(r)
    }

    /// Camera at `eye` looking at `centre` with `up` towards the top of the image.
    pub fn look_at(&mut self, eye: [f64; 3], centre: [f64; 3], up: [f64; 3]) -> Result<(), ApiIssue> {
        let r =
            self.geometry
                .transforms
                .look_at(DVec3::from_array(eye), DVec3::from_array(centre), DVec3::from_array(up));
        if r.is_ok() {
            self.geometry.direct = None;
        }
        self.transform_result(r)
    }

    /// An arbitrary view: `clip_from_world` given directly (row-major in the scene file).
    pub fn view_matrix(&mut self, clip_from_world: DMat4) -> Result<(), ApiIssue> {
        let r = self.geometry.transforms.set_view_matrix(clip_from_world);
        if r.is_ok() {
            self.geometry.direct = None;
        }
        self.transform_result(r)
    }

    /// Save the model matrix.
    pub fn push_transform(&mut self) {
        self.geometry.transforms.push();
    }
    /// Restore the model matrix saved by the matching push.
    pub fn pop_transform(&mut self) -> Result<(), ApiIssue> {
        let r = self.geometry.transforms.pop();
        self.transform_result(r)
    }
    pub fn translate(&mut self, t: [f64; 3]) -> Result<(), ApiIssue> {
        let r = self.geometry.transforms.translate(DVec3::from_array(t));
        self.transform_result(r)
    }
    pub fn rotate(&mut self, degrees: f64, axis: [f64; 3]) -> Result<(), ApiIssue> {
        let r = self
            .geometry
            .transforms
            .rotate_degrees(degrees, DVec3::from_array(axis));
        self.transform_result(r)
    }
    pub fn scale(&mut self, s: [f64; 3]) -> Result<(), ApiIssue> {
        let r = self.geometry.transforms.scale(DVec3::from_array(s));
        self.transform_result(r)
    }
    /// `M = M * m` (m applies to object coordinates first).
    pub fn concat(&mut self, m: DMat4) -> Result<(), ApiIssue> {
        let r = self.geometry.transforms.concat(m);
        self.transform_result(r)
    }
    /// Replace the model matrix.
    pub fn set_model(&mut self, world_from_object: DMat4) -> Result<(), ApiIssue> {
        let r = self.geometry.transforms.set_model(world_from_object);
        self.transform_result(r)
    }

    /// A model clip plane `a x + b y + c z + d >= 0` (kept side) in the current object
    /// coordinates; it is stored in world coordinates (seed 000 4.2.11).
    pub fn clip_plane(&mut self, plane: [f64; 4]) -> Result<(), ApiIssue> {
        let p = DVec4::from_array(plane);
        if !p.is_finite() || p.truncate().length() == 0.0 {
            return Err(ApiIssue::error(
                "E0710",
                Target::Values,
                "a clip plane needs finite coefficients and a non-zero normal (a b c)",
            ));
        }
        let world_from_object = self.geometry.transforms.world_from_object();
        match crate::pipeline::clip::transform_plane(p, &world_from_object) {
            Some(w) => {
                self.geometry.clip_planes.push(w);
                Ok(())
            }
            None => Err(ApiIssue::error(
                "E0710",
                Target::Values,
                "the model transform is singular: the clip plane cannot be placed in world coordinates",
            )),
        }
    }
    /// Remove every model clip plane.
    pub fn clear_clip_planes(&mut self) {
        self.geometry.clip_planes.clear();
    }

    /// Which faces facets drop.
    pub fn set_cull(&mut self, cull: CullMode) {
        self.geometry.cull = cull;
    }

    /// Hand each facet's device-space facing to shading in the reserved `facing` shading
    /// parameter (1 front, -1 back), which selects the front or back material.
    pub fn set_distinguish(&mut self, on: bool) {
        self.geometry.distinguish = on;
        if on && !self.shading.iter().any(|p| p.name == FACING_PARAM) {
            let _ = self.material(FACING_PARAM, &Value(vec![1.0]));
        }
    }

    /// The pipeline chosen for each kind of primitive so far, with counts (`--explain`).
    pub fn explain_lines(&self) -> Vec<String> {
        self.explain
            .iter()
            .map(|((prim, choice, outcome), n)| {
                let outcome = match outcome {
                    ClipOutcome::NotClipped => "transformed, no geometry type: clipping left to its kernel",
                    ClipOutcome::TriviallyRejected => "trivially rejected (no kernel run)",
                    ClipOutcome::TriviallyAccepted => "trivially accepted",
                    ClipOutcome::Clipped => "clipped by the runtime",
                    ClipOutcome::Culled => "culled",
                    ClipOutcome::NonFinite => "dropped (NaN or infinite vertex)",
                };
                format!("{prim} x{n}: {outcome}; {choice}")
            })
            .collect()
    }

    // ---- language shaders ----

    /// Bind surface shader `name` with `args` (by parameter name) to the primitives that
    /// follow: the reserved shading parameter `__surface` takes the binding's number.
    pub fn surface_shader(&mut self, name: &str, args: &[(String, ShaderArg)]) -> Result<(), ApiIssue> {
        let shader = self.shader_use(name, args, ItemKind::Surface)?;
        self.language.surfaces.push(shader);
        let id = self.language.surfaces.len() as f32;
        self.material(SURFACE_PARAM, &Value(vec![id]))
    }

    /// Add a light: light shader `name` with `args`.
    pub fn light_shader(&mut self, name: &str, args: &[(String, ShaderArg)]) -> Result<(), ApiIssue> {
        let shader = self.shader_use(name, args, ItemKind::Light)?;
        self.language.lights.push(shader);
        Ok(())
    }

    /// Set the frame's atmosphere shader.
    pub fn atmosphere_shader(&mut self, name: &str, args: &[(String, ShaderArg)]) -> Result<(), ApiIssue> {
        let shader = self.shader_use(name, args, ItemKind::Atmosphere)?;
        self.language.atmosphere = Some(shader);
        Ok(())
    }

    /// A shader use, its name and argument names checked against the program's shaders.
    fn shader_use(&self, name: &str, args: &[(String, ShaderArg)], kind: ItemKind) -> Result<ShaderUse, ApiIssue> {
        let what = match kind {
            ItemKind::Surface => "surface",
            ItemKind::Light => "light",
            _ => "atmosphere",
        };
        let Some(item) = self
            .program
            .shading_items
            .iter()
            .find(|i| i.kind == kind && i.name.name == name)
        else {
            let shaders = self.program.shading_items.iter().filter(|i| i.kind == kind);
            return Err(ApiIssue::error(
                "E1002",
                Target::Name,
                format!("no {what} shader `{name}` (shaders are `{what} NAME(...)` items of the loaded .prim files)"),
            )
            .suggest(name, shaders.map(|i| i.name.name.as_str())));
        };
        let mut shader = ShaderUse {
            name: name.to_string(),
            ..ShaderUse::default()
        };
        for (i, (arg, value)) in args.iter().enumerate() {
            let Some(param) = item.params.iter().find(|p| &p.name.name == arg) else {
                return Err(ApiIssue::error(
                    "E0702",
                    Target::Arg(i),
                    format!("{what} shader `{name}` has no parameter `{arg}`"),
                )
                .suggest(arg, item.params.iter().map(|p| p.name.name.as_str())));
            };
            let text_param = param.ty.kind == crate::syntax::ast::TypeKind::String;
            match value {
                ShaderArg::Numbers(v) if !text_param => shader.args.push((arg.clone(), v.0.clone())),
                ShaderArg::Text(t) if text_param => shader.text.push((arg.clone(), t.clone())),
                _ => {
                    return Err(ApiIssue::error(
                        "E0703",
                        Target::Values,
                        format!(
                            "parameter `{arg}` of {what} shader `{name}` takes {}",
                            if text_param {
                                "text in quotes (`name=\"file.png\"`)"
                            } else {
                                "numbers"
                            }
                        ),
                    ))
                }
            }
        }
        Ok(shader)
    }

    // ---- shading parameters ----

    /// Set the current value of shading parameter `name`. The first value fixes its
    /// component count and allocates its planes.
    pub fn material(&mut self, name: &str, value: &Value) -> Result<(), ApiIssue> {
        // The shading normal goes to lighting coordinates now, under the current model
        // matrix (as OpenGL's glNormal): shading reads it from the G-buffer in LC.
        if name == NORMAL_PARAM && value.len() == 3 {
            let mut warnings = vec![];
            let normals = self.geometry.lighting_normal_matrix();
            // Under a singular M the normal is zeroed, which shading lights with ambient
            // light only (seed 000 9.4; `pipeline::lighting`).
            let n = if normals.singular {
                geometry::note(&mut warnings, Warning::SingularModel);
                [0.0; 3]
            } else {
                geometry::normal_to_lighting(&normals, [value.0[0], value.0[1], value.0[2]], &mut warnings)
            };
            let lit = Value(n.to_vec());
            self.record_warnings(&warnings);
            return self.material_raw(name, &lit);
        }
        self.material_raw(name, value)
    }

    fn record_warnings(&mut self, warnings: &[Warning]) {
        for &w in warnings {
            if !self.pipeline_warnings.contains(&w) {
                self.pipeline_warnings.push(w);
                self.warnings.push(ApiIssue::warning(
                    "W0704",
                    Target::Values,
                    format!("geometry pipeline: {w}"),
                ));
            }
        }
    }

    fn material_raw(&mut self, name: &str, value: &Value) -> Result<(), ApiIssue> {
        if value.is_empty() || value.len() > MAX_COMPONENTS {
            return Err(ApiIssue::error(
                "E0703",
                Target::Values,
                format!(
                    "shading parameter `{name}` needs 1..={MAX_COMPONENTS} components, got {}",
                    value.len()
                ),
            ));
        }
        if let Some(p) = self.shading.iter_mut().find(|p| p.name == name) {
            if p.components as usize != value.len() {
                return Err(ApiIssue::error(
                    "E0703",
                    Target::Values,
                    format!(
                        "shading parameter `{name}` has {} components (fixed by its first value), got {}",
                        p.components,
                        value.len()
                    ),
                ));
            }
            p.current = value.0.clone();
            return Ok(());
        }
        let first_plane = self.num_planes();
        let interp = self.pending_interp.remove(name).unwrap_or(Interp::Constant);
        self.shading.push(ShadingParam {
            name: name.to_string(),
            components: value.len() as u32,
            first_plane,
            interp,
            current: value.0.clone(),
        });
        Ok(())
    }

    /// Choose how shading parameter `name` is interpolated. `kind` is `constant`, the name
    /// of a shared interpolator (then `args` gives its per-primitive parameters by name), or
    /// any other identifier: a per-sequence-point kind (`linear`, `perspective_linear`, ...).
    pub fn material_interp(&mut self, name: &str, kind: &str, args: &[(String, Value)]) -> Result<(), ApiIssue> {
        let interp = self.resolve_interp(kind, args)?;
        if let Some(p) = self.shading.iter_mut().find(|p| p.name == name) {
            p.interp = interp;
        } else {
            self.pending_interp.insert(name.to_string(), interp);
        }
        Ok(())
    }

    fn resolve_interp(&mut self, kind: &str, args: &[(String, Value)]) -> Result<Interp, ApiIssue> {
        if !is_identifier(kind) {
            return Err(ApiIssue::error(
                "E0707",
                Target::Kind,
                format!("`{kind}` is not an interpolation kind (an identifier)"),
            ));
        }
        let func = self.program.find(kind);
        let shared = func.filter(|&id| self.program.func(id).kind == FuncKind::Interpolator);
        if func.is_some() && shared.is_none() {
            return Err(ApiIssue::error(
                "E0707",
                Target::Kind,
                format!("`{kind}` is a primitive, not an interpolation kind or shared interpolator"),
            ));
        }
        let Some(id) = shared else {
            if let Some((i, (arg, _))) = args.iter().enumerate().next() {
                return Err(ApiIssue::error(
                    "E0707",
                    Target::Arg(i),
                    format!("interpolation kind `{kind}` takes no arguments (`{arg}` given)"),
                ));
            }
            if kind == "constant" {
                return Ok(Interp::Constant);
            }
            self.warn_unknown_kind(kind);
            return Ok(Interp::Kind(kind.to_string()));
        };
        let f = self.program.func(id);
        let mut words = vec![];
        let mut used = vec![false; args.len()];
        for p in &f.params {
            if matches!(p.role, ParamRole::X | ParamRole::Y | ParamRole::Z) {
                continue;
            }
            let ty = &f.local(p.local).ty;
            let want = crate::abi::type_words(ty, 0) as usize;
            let given = args.iter().position(|(n, _)| *n == p.name);
            let encoded = match given {
                Some(i) => {
                    used[i] = true;
                    encode(&args[i].1 .0, ty, p.space, &self.transform())
                        .map_err(|e| ApiIssue::error("E0703", Target::Arg(i), count_message(&p.name, &e)))?
                }
                None => match &p.default {
                    Some(d) => encode_default(d, ty, p.space, &self.transform()),
                    None => {
                        self.warnings.push(ApiIssue::warning(
                            "W0701",
                            Target::Values,
                            format!(
                                "interpolator `{kind}` argument `{}` has no value and no default: zero",
                                p.name
                            ),
                        ));
                        vec![0; want]
                    }
                },
            };
            let mut encoded = encoded;
            encoded.resize(want, 0);
            words.extend(encoded);
        }
        if let Some(i) = used.iter().position(|u| !u) {
            let settable = f
                .params
                .iter()
                .filter(|p| !matches!(p.role, ParamRole::X | ParamRole::Y | ParamRole::Z));
            return Err(ApiIssue::error(
                "E0707",
                Target::Arg(i),
                format!("interpolator `{kind}` has no parameter `{}`", args[i].0),
            )
            .suggest(&args[i].0, settable.map(|p| p.name.as_str())));
        }
        debug_assert_eq!(words.len() as u32, interpolator_arg_words(&self.program, id));
        Ok(Interp::Shared {
            name: kind.to_string(),
            args: words,
        })
    }

    /// W0705 for a per-sequence-point `kind` no `interpolation` arm of the program names,
    /// when a known kind is close to it: probably a typo, which no arm would handle. A kind
    /// no arm names is otherwise allowed (a primitive written later may understand it), so
    /// without a close one nothing is said.
    fn warn_unknown_kind(&mut self, kind: &str) {
        let program = &self.program;
        let arm_kinds = self.arm_kinds.get_or_insert_with(|| program.arm_kinds());
        if arm_kinds.iter().any(|k| k == kind) {
            return;
        }
        let shared = program.functions.iter().filter(|f| f.kind == FuncKind::Interpolator);
        let known = arm_kinds
            .iter()
            .map(String::as_str)
            .chain(["constant"])
            .chain(shared.map(|f| f.name.as_str()));
        let issue = ApiIssue::warning(
            "W0705",
            Target::Kind,
            format!("no `interpolation` arm of the loaded primitives names the kind `{kind}`"),
        )
        .suggest(kind, known);
        if issue.help.is_some() {
            self.warnings.push(issue);
        }
    }

    // ---- primitives ----

    /// Open a primitive. An unknown name is an error, but the block is still opened (and
    /// dropped at `end`) so the calls inside it do not each report it again.
    pub fn begin(&mut self, prim: &str) -> Result<(), ApiIssue> {
        if self.block.is_some() {
            return Err(ApiIssue::error(
                "E0705",
                Target::Call,
                "`begin` inside a primitive: the previous `begin` has no `end`",
            ));
        }
        let func = self.program.find(prim);
        let is_prim = func.is_some_and(|id| self.program.func(id).kind == FuncKind::Primitive);
        self.block = Some(Block {
            func: func.filter(|_| is_prim),
            per_prim: HashMap::new(),
            per_seq_current: HashMap::new(),
            seq_points: vec![],
            warned_no_vertex: false,
        });
        match func {
            None => {
                let prims = self.program.functions.iter().filter(|f| f.kind == FuncKind::Primitive);
                Err(
                    ApiIssue::error("E0701", Target::Name, format!("unknown primitive `{prim}`"))
                        .suggest(prim, prims.map(|f| f.name.as_str())),
                )
            }
            Some(_) if !is_prim => Err(ApiIssue::error(
                "E0701",
                Target::Name,
                format!("`{prim}` is a shared interpolator, not a primitive"),
            )),
            Some(_) => Ok(()),
        }
    }

    /// Open a block with no primitive (the scene reader uses it for a malformed `begin`
    /// line so that the rest of the block is skipped quietly).
    pub fn begin_discarded(&mut self) {
        if self.block.is_none() {
            self.block = Some(Block {
                func: None,
                per_prim: HashMap::new(),
                per_seq_current: HashMap::new(),
                seq_points: vec![],
                warned_no_vertex: false,
            });
        }
    }

    fn open_block(&mut self, call: &str) -> Result<&mut Block, ApiIssue> {
        self.block
            .as_mut()
            .ok_or_else(|| ApiIssue::error("E0704", Target::Call, format!("`{call}` outside `begin` ... `end`")))
    }

    /// Set a rasterisation parameter of the open primitive: a per-primitive parameter, or the
    /// current value of a per-sequence-point one (recorded at the next sequence points).
    pub fn rast_param(&mut self, name: &str, value: &Value) -> Result<(), ApiIssue> {
        // Points, normals and vectors are recorded in object coordinates; `end` transforms
        // them (after clipping, for facets).
        let device_from_object = Mat4::IDENTITY;
        let program = self.program.clone();
        let block = self.open_block("rast_param")?;
        let Some(id) = block.func else {
            return Ok(());
        };
        let f = program.func(id);
        let Some(index) = f.params.iter().position(|p| p.name == name) else {
            // Only the parameters `rast_param` may set are suggested.
            let settable = f
                .params
                .iter()
                .filter(|p| matches!(p.role, ParamRole::PerPrimitive | ParamRole::PerSequencePoint));
            return Err(ApiIssue::error(
                "E0702",
                Target::Name,
                format!("primitive `{}` has no parameter `{name}`", f.name),
            )
            .suggest(name, settable.map(|p| p.name.as_str())));
        };
        let p = &f.params[index];
        let ty = &f.local(p.local).ty;
        match p.role {
            ParamRole::X | ParamRole::Y | ParamRole::Z => {
                return Err(ApiIssue::error(
                    "E0706",
                    Target::Name,
                    format!("`{name}` is bound by the renderer at every pixel; it cannot be set"),
                ))
            }
            ParamRole::InterpData => {
                return Err(ApiIssue::error(
                    "E0706",
                    Target::Name,
                    format!("`{name}` is interpolation data: it is filled from `material` values at sequence points"),
                ))
            }
            ParamRole::PerPrimitive | ParamRole::PerSequencePoint => {}
        }
        let elem_ty = if ty.per_seq { ty.element() } else { ty.clone() };
        let words = encode(&value.0, &elem_ty, p.space, &device_from_object)
            .map_err(|e| ApiIssue::error("E0703", Target::Values, count_message(name, &e)))?;
        if ty.per_seq {
            block.per_seq_current.insert(index, words);
        } else {
            block.per_prim.insert(index, words);
        }
        Ok(())
    }

    /// Record the current per-sequence-point and shading values as the next sequence point.
    pub fn sequence_point(&mut self) -> Result<(), ApiIssue> {
        let shading: Vec<Vec<f32>> = self.shading.iter().map(|p| p.current.clone()).collect();
        let program = self.program.clone();
        let block = self.open_block("sequence_point")?;
        let Some(id) = block.func else {
            return Ok(());
        };
        let n_params = program.func(id).params.len();
        let per_seq = (0..n_params).map(|i| block.per_seq_current.get(&i).cloned()).collect();
        block.seq_points.push(SeqPoint { per_seq, shading });
        Ok(())
    }

    /// `vertex(x, y, z, w)`: set the `vertex` parameter and make a sequence point. For a
    /// primitive without a `vertex` parameter (screen_triangle takes its corners as one
    /// per-primitive array) the position is dropped with a warning, once per primitive, and
    /// the call is just a sequence point.
    pub fn vertex(&mut self, x: f32, y: f32, z: f32, w: f32) -> Result<(), ApiIssue> {
        let block = self.open_block("vertex")?;
        let Some(id) = block.func else {
            return Ok(());
        };
        let warn = !block.warned_no_vertex;
        let has_vertex = self.program.func(id).params.iter().any(|p| p.name == "vertex");
        if has_vertex {
            self.rast_param("vertex", &Value(vec![x, y, z, w]))?;
        } else if warn {
            if let Some(b) = self.block.as_mut() {
                b.warned_no_vertex = true;
            }
            self.warnings.push(ApiIssue::warning(
                "W0703",
                Target::Call,
                format!(
                    "primitive `{}` has no `vertex` parameter: `vertex` only makes a sequence point here",
                    self.program.func(id).name
                ),
            ));
        }
        self.sequence_point()
    }

    /// Close the primitive and build its instance.
    pub fn end(&mut self) -> Result<(), ApiIssue> {
        let block = self
            .block
            .take()
            .ok_or_else(|| ApiIssue::error("E0704", Target::Call, "`end` without `begin`"))?;
        let Some(func) = block.func else {
            return Ok(());
        };
        let instance = self.build_instance(func, &block);
        for inst in self.finish_geometry(instance) {
            self.variants.add(&inst);
            self.instances.push(inst);
        }
        Ok(())
    }

    /// The key of an instance of `func` under the current shading state.
    fn current_key(&self) -> VariantKey {
        VariantKey {
            bindings: self
                .shading
                .iter()
                .map(|p| Binding {
                    kind: match &p.interp {
                        Interp::Kind(k) => BindingKind::Kind(k.clone()),
                        Interp::Constant => BindingKind::Constant,
                        Interp::Shared { name, .. } => BindingKind::Shared(name.clone()),
                    },
                    components: p.components,
                })
                .collect(),
            count_writes: false,
            trivial_accept: false,
        }
    }

    fn build_instance(&mut self, func: FuncId, block: &Block) -> Instance {
        let program = self.program.clone();
        let f = program.func(func);
        let key = self.current_key();
        let layout = ArgLayout::new(&program, func, &key);
        let n_seq = block.seq_points.len() as u32;
        let mut args = vec![0u32; layout.words(n_seq)];
        args[0] = n_seq;
        // Plane table: each binding's planes, binding order.
        let mut at = layout.plane_table as usize;
        for p in &self.shading {
            for c in 0..p.components {
                args[at] = p.first_plane + c;
                at += 1;
            }
        }
        // Binding data: constants' current values, shared interpolators' arguments.
        for (p, offset) in self.shading.iter().zip(&layout.binding_data) {
            let Some(offset) = offset else { continue };
            let words: Vec<u32> = match &p.interp {
                Interp::Constant => p.current.iter().map(|x| x.to_bits()).collect(),
                Interp::Shared { args, .. } => args.clone(),
                Interp::Kind(_) => vec![],
            };
            write_words(&mut args, *offset as usize, &words);
        }
        if let Some(spaces) = layout.spaces {
            self.write_spaces(&mut args, spaces as usize);
        }
        let interp_len = key.interp_components() as usize;
        let seq_base = layout.fixed_words as usize;
        let seq_count = n_seq.max(1) as usize;
        let mut no_seq_points = vec![];
        for (index, (p, slot)) in f.params.iter().zip(&layout.params).enumerate() {
            let ty = &f.local(p.local).ty;
            match (slot, p.role) {
                (ParamSlot::Pixel, _) => {}
                (ParamSlot::Fixed { offset, words }, ParamRole::InterpData) => {
                    let count = (*words as usize).checked_div(interp_len).unwrap_or(0);
                    let mut missing = false;
                    for i in 0..count {
                        let (data, complete) = self.interp_data_at(block, i);
                        missing |= !complete;
                        write_words(&mut args, *offset as usize + i * interp_len, &data);
                    }
                    if missing {
                        self.warnings.push(ApiIssue::warning(
                            "W0701",
                            Target::Call,
                            format!(
                                "`{}` of `{}` takes {count} sequence points' values, {} given (or a shading parameter was defined after one): zero there",
                                p.name,
                                f.name,
                                block.seq_points.len()
                            ),
                        ));
                    }
                }
                (ParamSlot::Fixed { offset, words }, _) => {
                    let data = match block.per_prim.get(&index) {
                        Some(v) => v.clone(),
                        None => match &p.default {
                            Some(d) => encode_default(d, ty, p.space, &Mat4::IDENTITY),
                            None => {
                                self.warnings.push(ApiIssue::warning(
                                    "W0701",
                                    Target::Call,
                                    format!(
                                        "parameter `{}` of `{}` was not set and has no default: zero",
                                        p.name, f.name
                                    ),
                                ));
                                vec![0; *words as usize]
                            }
                        },
                    };
                    write_words(&mut args, *offset as usize, &data[..data.len().min(*words as usize)]);
                }
                (ParamSlot::Seq { seq_offset, words }, role) => {
                    let base = seq_base + seq_count * *seq_offset as usize;
                    let words = *words as usize;
                    if n_seq == 0 {
                        no_seq_points.push(format!("`{}`", p.name));
                        continue;
                    }
                    let mut missing = false;
                    for i in 0..n_seq as usize {
                        let data = if role == ParamRole::InterpData {
                            let (data, complete) = self.interp_data_at(block, i);
                            missing |= !complete;
                            data
                        } else {
                            match block.seq_points[i].per_seq.get(index).cloned().flatten() {
                                Some(v) => v,
                                None => {
                                    missing = true;
                                    vec![0; words]
                                }
                            }
                        };
                        write_words(&mut args, base + i * words, &data[..data.len().min(words)]);
                    }
                    if missing {
                        self.warnings.push(ApiIssue::warning(
                            "W0701",
                            Target::Call,
                            format!(
                                "`{}` of `{}` had no value at some sequence points: zero there",
                                p.name, f.name
                            ),
                        ));
                    }
                }
            }
        }
        if !no_seq_points.is_empty() {
            self.warnings.push(ApiIssue::warning(
                "W0701",
                Target::Call,
                format!(
                    "`{}` has no sequence points: {} get one zero element",
                    f.name,
                    no_seq_points.join(", ")
                ),
            ));
        }
        Instance { func, key, n_seq, args }
    }

    /// Interpolation data of sequence point `i`: every `Kind`-bound shading parameter's value
    /// there, binding order; missing sequence points or values are zero. The flag says
    /// whether everything was there (the caller warns once per parameter).
    fn interp_data_at(&self, block: &Block, i: usize) -> (Vec<u32>, bool) {
        let mut out = vec![];
        let mut complete = true;
        for (s, p) in self.shading.iter().enumerate() {
            if !matches!(p.interp, Interp::Kind(_)) {
                continue;
            }
            match block.seq_points.get(i).and_then(|sp| sp.shading.get(s)) {
                Some(v) => out.extend(v.iter().map(|x| x.to_bits())),
                None => {
                    complete = false;
                    out.extend(std::iter::repeat_n(0, p.components as usize));
                }
            }
        }
        (out, complete)
    }

    /// The six space matrices of the argument block, from the geometry pipeline.
    fn write_spaces(&mut self, args: &mut [u32], at: usize) {
        for (i, m) in self.geometry.abi_spaces().iter().enumerate() {
            let words: Vec<u32> = m.iter().map(|x| x.to_bits()).collect();
            write_words(args, at + 16 * i, &words);
        }
    }

    /// The geometry stage for one instance built with object-space points (see
    /// [`geometry`]): zero or more instances with device-space points and lighting-space
    /// normals and vectors.
    fn finish_geometry(&mut self, mut inst: Instance) -> Vec<Instance> {
        let program = self.program.clone();
        let f = program.func(inst.func);
        let layout = ArgLayout::new(&program, inst.func, &inst.key);
        let n_seq = inst.n_seq.max(1) as usize;
        let mut warnings = vec![];
        let clip_from_object = self.geometry.clip_from_object();
        let device_from_object = self.geometry.device_from_object();
        let normals = self.geometry.lighting_normal_matrix();
        let lighting_from_object = self.geometry.lighting_from_object();
        if normals.singular {
            geometry::note(&mut warnings, Warning::SingularModel);
        }

        let spans_of = |slot: &ParamSlot| param_spans(&layout, n_seq, slot);
        let floats = |args: &[u32], at: usize, n: usize| arg_floats(args, at, n);
        directions_to_lighting(
            f,
            &layout,
            n_seq,
            &mut inst.args,
            &normals,
            &lighting_from_object,
            &mut warnings,
        );
        // The checker made sure a facet or line primitive has `point vertex[]`.
        let vertex_index = match f.geometry {
            Geometry::Facet if inst.n_seq >= 3 => f.params.iter().position(|p| p.name == "vertex"),
            Geometry::Line | Geometry::Point => f.params.iter().position(|p| p.name == "vertex"),
            _ => None,
        };
        let lit = self.shading_setup.lit();
        let name = f.name.clone();

        if vertex_index.is_none() {
            for (p, slot) in f.params.iter().zip(&layout.params) {
                if p.space != ParamSpace::Point {
                    continue;
                }
                for (at, words) in spans_of(slot) {
                    for c in (0..words / 4).map(|k| at + k * 4) {
                        let Ok(v) = <[f32; 4]>::try_from(floats(&inst.args, c, 4)) else {
                            continue;
                        };
                        let object = self.geometry.object_point(v, &mut warnings);
                        if !object.is_finite() {
                            continue;
                        }
                        let device = (device_from_object * object).as_vec4().to_array();
                        write_words(&mut inst.args, c, &device.map(f32::to_bits));
                    }
                }
            }
            let choice = self.geometry.choose(GeometryType::Surface, lit, true);
            self.record(&name, &choice, ClipOutcome::NotClipped, warnings);
            return vec![inst];
        }

        // Facet or line: positions and interpolation data per sequence point.
        let vi = vertex_index.unwrap_or(0);
        let vertex_spans = spans_of(&layout.params[vi]);
        let interp_slot = f
            .params
            .iter()
            .zip(&layout.params)
            .position(|(p, slot)| p.role == ParamRole::InterpData && matches!(slot, ParamSlot::Seq { .. }));
        let interp_spans = interp_slot.map(|i| spans_of(&layout.params[i])).unwrap_or_default();
        let count = inst.n_seq as usize;
        let objects: Vec<DVec4> = (0..count)
            .map(|i| {
                let (at, _) = vertex_spans[i];
                let v = <[f32; 4]>::try_from(floats(&inst.args, at, 4)).unwrap_or([f32::NAN; 4]);
                self.geometry.object_point(v, &mut warnings)
            })
            .collect();
        let positions: Vec<DVec4> = objects.iter().map(|p| clip_from_object * *p).collect();
        let device: Vec<DVec4> = objects.iter().map(|p| device_from_object * *p).collect();
        let attrs: Vec<Vec<f32>> = (0..count)
            .map(|i| {
                interp_spans
                    .get(i)
                    .map(|&(at, n)| floats(&inst.args, at, n))
                    .unwrap_or_default()
            })
            .collect();
        if f.geometry == Geometry::Point {
            let (outcome, kept) = self.geometry.clip_points(&positions, &mut warnings);
            let choice = self.geometry.choose(GeometryType::Point, lit, false);
            self.record(&name, &choice, outcome, warnings);
            return kept
                .into_iter()
                .map(|i| {
                    instance_with_points(
                        &inst,
                        &layout,
                        vi,
                        interp_slot,
                        &[(device[i], attrs[i].as_slice())],
                        true,
                    )
                })
                .collect();
        }
        if f.geometry == Geometry::Line {
            let result = self.geometry.clip_polyline(&positions, &device, &attrs, &mut warnings);
            let choice = self
                .geometry
                .choose(GeometryType::Line, lit, matches!(result.outcome, ClipOutcome::Clipped));
            self.record(&name, &choice, result.outcome, warnings);
            // A polyline whose last point repeats its first (bit for bit, as given) is closed:
            // its last segment joins its first.
            let closing = (count >= 4 && objects[0] == objects[count - 1]).then_some(count - 2);
            return line_instances(&inst, &layout, vi, interp_slot, &result.segments, closing);
        }
        let result = self.geometry.clip_facet(&positions, &device, &attrs, &mut warnings);
        let choice = self
            .geometry
            .choose(GeometryType::Facet, lit, matches!(result.outcome, ClipOutcome::Clipped));
        self.record(&name, &choice, result.outcome, warnings);
        let facing_binding = self.shading.iter().position(|p| p.name == FACING_PARAM);
        let mut out = vec![];
        for (piece, facing) in result.pieces {
            let points: Vec<(DVec4, &[f32])> = piece.iter().map(|(p, d)| (*p, d.as_slice())).collect();
            let mut out_inst = instance_with_points(&inst, &layout, vi, interp_slot, &points, !result.near_crossed);
            if let (Some(b), true) = (facing_binding, self.geometry.distinguish) {
                if let Some(Some(at)) = layout.binding_data.get(b) {
                    let v: f32 = if facing == Facing::Front { 1.0 } else { -1.0 };
                    write_words(&mut out_inst.args, *at as usize, &[v.to_bits()]);
                }
            }
            out.push(out_inst);
        }
        out
    }

    /// Count the instance for `--explain` and report new pipeline warnings (each kind once).
    fn record(
        &mut self,
        prim: &str,
        choice: &crate::pipeline::PipelineChoice,
        outcome: ClipOutcome,
        mut warnings: Vec<Warning>,
    ) {
        for w in &choice.warnings {
            geometry::note(&mut warnings, *w);
        }
        let mut description = choice.clone();
        description.warnings.clear();
        *self
            .explain
            .entry((prim.to_string(), description.to_string(), outcome))
            .or_insert(0) += 1;
        for w in warnings {
            if !self.pipeline_warnings.contains(&w) {
                self.pipeline_warnings.push(w);
                self.warnings.push(ApiIssue::warning(
                    "W0704",
                    Target::Call,
                    format!("geometry pipeline, primitive `{prim}`: {w}"),
                ));
            }
        }
    }
}

fn count_message(name: &str, e: &EncodeError) -> String {
    match e {
        EncodeError::NotSettable => format!("`{name}` is interpolation data and cannot be set"),
        EncodeError::Count { given, expected } => {
            let expected: Vec<String> = expected.iter().map(|n| n.to_string()).collect();
            format!("`{name}` takes {} components, got {given}", expected.join(" or "))
        }
    }
}

fn is_identifier(s: &str) -> bool {
    let mut chars = s.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}
