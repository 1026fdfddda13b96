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
//! Every call validates its input and returns an [`ApiIssue`] for an error (the call then has
//! no effect, or — for a bad `begin` — opens a block that is discarded at `end`, so one
//! mistake does not cascade). Warnings (zero-filled parameters, ...) are queued and taken
//! with [`Renderer::take_warnings`]. No input panics.

use std::collections::HashMap;
use std::sync::Arc;

use glam::Mat4;

use crate::abi::{interpolator_arg_words, ArgLayout, Binding, BindingKind, ParamSlot, VariantKey};
use crate::diag::Severity;
use crate::ir::{FuncId, FuncKind, ParamRole, Program};

use super::transform;
use super::value::{encode, encode_default, EncodeError, Value};

/// Largest image side accepted, in pixels (keeps a typo from allocating gigabytes).
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// Largest tile side accepted.
pub const MAX_TILE_SIDE: u32 = 4096;
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
    /// The i-th `name=value` argument of `material_interp`.
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
}

impl ApiIssue {
    fn error(code: &'static str, target: Target, message: impl Into<String>) -> ApiIssue {
        ApiIssue {
            severity: Severity::Error,
            code,
            message: message.into(),
            target,
        }
    }
    fn warning(code: &'static str, target: Target, message: impl Into<String>) -> ApiIssue {
        ApiIssue {
            severity: Severity::Warning,
            code,
            message: message.into(),
            target,
        }
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
    /// Tile side in pixels (tiles are square; edge tiles are cut by the image).
    pub tile_size: u32,
    /// Compile kernels that count depth writes per pixel (`Frame::write_count_at`).
    pub count_writes: bool,
    pub background: [f32; 3],
}

impl Default for RenderOptions {
    fn default() -> RenderOptions {
        RenderOptions {
            width: 320,
            height: 240,
            tile_size: 64,
            count_writes: false,
            background: [0.0; 3],
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
    device_from_object: Mat4,
    shading: Vec<ShadingParam>,
    /// `material_interp` calls for names that have no `material` value yet.
    pending_interp: HashMap<String, Interp>,
    block: Option<Block>,
    instances: Vec<Instance>,
    warnings: Vec<ApiIssue>,
}

impl Renderer {
    pub fn new(program: Arc<Program>) -> Renderer {
        Renderer {
            program,
            options: RenderOptions::default(),
            device_from_object: Mat4::IDENTITY,
            shading: vec![],
            pending_interp: HashMap::new(),
            block: None,
            instances: vec![],
            warnings: vec![],
        }
    }

    pub fn program(&self) -> &Arc<Program> {
        &self.program
    }
    pub fn instances(&self) -> &[Instance] {
        &self.instances
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

    pub fn set_background(&mut self, rgb: [f32; 3]) {
        self.options.background = rgb;
    }

    /// Replace the current `device_from_object` matrix.
    pub fn set_transform(&mut self, device_from_object: Mat4) {
        if device_from_object.determinant() == 0.0 || !device_from_object.is_finite() {
            self.warnings.push(ApiIssue::warning(
                "W0702",
                Target::Values,
                "transform is singular or not finite; points will be passed through it as given",
            ));
        }
        self.device_from_object = device_from_object;
    }

    pub fn transform(&self) -> Mat4 {
        self.device_from_object
    }

    /// `device_from_object` = the orthographic box to viewport mapping
    /// (see [`transform::ortho`]); uses the current image size.
    pub fn ortho(&mut self, left: f32, right: f32, bottom: f32, top: f32, near: f32, far: f32) {
        let (w, h) = (self.options.width, self.options.height);
        self.set_transform(transform::ortho(left, right, bottom, top, near, far, [w, h]));
    }

    /// `device_from_object` = a perspective camera at the origin looking down -z
    /// (see [`transform::perspective`]); uses the current image size.
    pub fn perspective(&mut self, fov_y_degrees: f32, near: f32, far: f32) {
        let (w, h) = (self.options.width, self.options.height);
        self.set_transform(transform::perspective(fov_y_degrees, near, far, w, h));
    }

    // ---- shading parameters ----

    /// Set the current value of shading parameter `name`. The first value fixes its
    /// component count and allocates its planes.
    pub fn material(&mut self, name: &str, value: &Value) -> Result<(), ApiIssue> {
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
                Target::Values,
                format!("`{kind}` is not an interpolation kind (an identifier)"),
            ));
        }
        let func = self.program.find(kind);
        let shared = func.filter(|&id| self.program.func(id).kind == FuncKind::Interpolator);
        if func.is_some() && shared.is_none() {
            return Err(ApiIssue::error(
                "E0707",
                Target::Values,
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
            return Ok(if kind == "constant" {
                Interp::Constant
            } else {
                Interp::Kind(kind.to_string())
            });
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
                    encode(&args[i].1 .0, ty, p.space, &self.device_from_object)
                        .map_err(|e| ApiIssue::error("E0703", Target::Arg(i), count_message(&p.name, &e)))?
                }
                None => match &p.default {
                    Some(d) => encode_default(d, ty, p.space, &self.device_from_object),
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
            return Err(ApiIssue::error(
                "E0707",
                Target::Arg(i),
                format!("interpolator `{kind}` has no parameter `{}`", args[i].0),
            ));
        }
        debug_assert_eq!(words.len() as u32, interpolator_arg_words(&self.program, id));
        Ok(Interp::Shared {
            name: kind.to_string(),
            args: words,
        })
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
            None => Err(ApiIssue::error(
                "E0701",
                Target::Name,
                format!("unknown primitive `{prim}`"),
            )),
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
        let device_from_object = self.device_from_object;
        let program = self.program.clone();
        let block = self.open_block("rast_param")?;
        let Some(id) = block.func else {
            return Ok(());
        };
        let f = program.func(id);
        let Some(index) = f.params.iter().position(|p| p.name == name) else {
            return Err(ApiIssue::error(
                "E0702",
                Target::Name,
                format!("primitive `{}` has no parameter `{name}`", f.name),
            ));
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
        self.instances.push(instance);
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
                            Some(d) => encode_default(d, ty, p.space, &self.device_from_object),
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

    /// The six space matrices of the argument block. Until the geometry pipeline lands, the
    /// object, world and lighting spaces coincide.
    fn write_spaces(&mut self, args: &mut [u32], at: usize) {
        let device_from_object = self.device_from_object;
        // The inverse is taken in f64 and rounded once: a camera with a narrow field of view
        // has entries from 1e-5 to 1e9, and an f32 inverse leaves garbage where the true
        // inverse has zeros (a primitive measuring a small far object from the centre of
        // its projection, like the sphere, reads those entries relative to tiny ones).
        let inverse = device_from_object.as_dmat4().inverse();
        let object_from_device = if device_from_object.determinant() != 0.0 && inverse.is_finite() {
            inverse.as_mat4()
        } else {
            self.warnings.push(ApiIssue::warning(
                "W0702",
                Target::Call,
                "the transform is singular: the *_from_device matrices are zero",
            ));
            Mat4::ZERO
        };
        let matrices = [
            device_from_object,
            device_from_object,
            device_from_object,
            object_from_device,
            object_from_device,
            object_from_device,
        ];
        for (i, m) in matrices.iter().enumerate() {
            let words: Vec<u32> = transform::to_rows(m).iter().map(|x| x.to_bits()).collect();
            write_words(args, at + 16 * i, &words);
        }
    }
}

/// Copy `words` into `args` at `at`, ignoring anything past the end (the layout sized `args`,
/// so this only guards against a malformed program).
fn write_words(args: &mut [u32], at: usize, words: &[u32]) {
    if at >= args.len() {
        return;
    }
    let n = words.len().min(args.len() - at);
    args[at..at + n].copy_from_slice(&words[..n]);
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
