//! The runtime: the primitive registry, the primitive API that builds instances, and the
//! tiled renderer with its depth buffer and G-buffer.
//!
//! Where it sits: the [`scene`](crate::scene) reader turns a scene file into calls on the
//! [`Renderer`]; the renderer asks a [`KernelSource`] (normally the [`Jit`](crate::jit::Jit))
//! for one kernel per (primitive, variant key) and runs the kernels over screen tiles through
//! the ABI of [`abi`](crate::abi). The parts:
//! - [`registry`]: loads and compiles the `.prim` library into an `ir::Program`.
//! - [`value`]: API values and their encoding into argument words.
//! - [`api`]: `begin` / `rast_param` / `material` / `material_interp` / `sequence_point` /
//!   `vertex` / `end`, the current transform, instances and their argument blocks.
//! - [`live`]: dead-parameter elimination: the planes a language-shaded frame keeps, and
//!   the instances re-laid out without the bindings it drops.
//! - [`frame`]: the [`Frame`]'s buffers (depth, G-buffer planes, colours), their layout, the
//!   shading pass over them and its images.
//! - [`render`]: the render loop: compiling, binning, parallel tile rendering.
//! - `expand`: runs a primitive that only calls primitives once and bins its calls instead.
//! - `errors`: where kernel runs count their run-time errors, and the W0801 warnings.
//! - [`pool`]: render thread pools, each thread on a core of its own.
//! - `tiergate`: leaves a tiered JIT's background compiler a thread while it compiles.
//! - [`geometry`]: the geometry pipeline at `end`: clip codes, trivial reject / accept,
//!   clipping, culling, points to device and normals to lighting coordinates.
//! - [`shading`]: the deferred shading pass (Phong, fog, texture), one monomorphised
//!   instance per effect set.
//! - [`texture`]: image textures for shaders' `texture()`: PNG loading, mip chains,
//!   bilinear / trilinear filtering, wrap modes, and the kernels' entry `primflow_texture`.
//! - [`transform`]: `ortho` / `perspective` device_from_object matrices (kept for callers
//!   that build a device transform themselves).
//! - [`kernels`]: the [`KernelSource`] seam between renderer and JIT.

pub mod api;
pub(crate) mod errors;
#[doc(hidden)]
pub mod expand;
pub mod frame;
pub mod geometry;
mod instances;
pub mod kernels;
pub mod live;
pub mod pool;
pub mod registry;
pub mod render;
pub mod samples;
pub mod shading;
pub mod texture;
#[doc(hidden)]
pub mod tiergate;
pub mod transform;
pub mod value;

pub use api::{
    ApiIssue, Instance, RenderOptions, Renderer, ShadingParam, Target, EXPAND_BUDGET_WORDS, MAX_FRAME_BYTES,
    MAX_IMAGE_SIDE, RENDER_THREAD_STACK,
};
pub use frame::{Frame, ParamPlanes};
pub use kernels::KernelSource;
pub use pool::render_pool;
pub use registry::{Registry, LIBRARY, PRIMS_ENV};
pub use render::{describe_key, KernelReport, RenderOutput, RenderReport, RenderStats};
pub use value::Value;
