//! primflow: a compiler and JIT runtime for a RenderMan-like procedural primitive language
//! (Olano, Lastra & Leech, "Procedural Primitives in a High Performance, Hardware Accelerated,
//! Z-Buffer Renderer").
//!
//! The stages, in the order [`compile`] runs them:
//! 1. [`syntax`] — logos lexer and lalrpop grammar: source text to an AST with spans.
//! 2. [`check`] — name resolution, types, fixed-point formats, uniform/varying inference;
//!    lowers the AST to the typed [`ir`], inlining helper functions.
//! 3. [`ir::split`] — splits each function into its uniform setup and its pixel part.
//! 4. [`mid`] — the middle end, the passes that need no code generator: a function's body
//!    as lowered (array copies forwarded, constant-trip loops unrolled), and per function,
//!    variant key and tier a plan of every analysis the lowering consults (where locals
//!    live, range analysis, dead setup code, row and carried terms, unswitching, the
//!    block-culling guards).
//! 5. [`jit`] — lowers a function from its plan, specialised for a [`abi::VariantKey`], and
//!    compiles it with Cranelift into a kernel over groups of pixels.
//! 6. [`runtime`] — tiles, depth buffer, G-buffer, shading, the primitive API; [`scene`]
//!    reads the text scene format into API calls.
//!
//! Beside the stages: [`accuracy`] measures error against an f64 reference renderer versus
//! time for each accuracy knob (`primflow accuracy`); [`ops`] holds the operator enums the
//! AST and the IR share; [`workload`] the deterministic scenes that bench, accuracy and the
//! tests draw.
//!
//! Using it from Rust (`examples/api.rs` is a complete program):
//!
//! ```text
//! let registry = runtime::Registry::load(&mut sources, &[], &[], &mut diags)?; // the embedded library
//! let mut renderer = runtime::Renderer::new(registry.program.clone());
//! renderer.set_image_size(160, 120)?;  // ... the scene format's calls (docs/scene.md)
//! let mut jit = jit::Jit::new(renderer.program().clone())?;
//! let frame = renderer.render(&mut jit).frame;
//! ```
//!
//! The default feature `cli` adds the `primflow` binary and the modules only it needs
//! ([`cli`], [`bench`], [`accuracy`], [`fuzz`]) with their dependencies; build with
//! `default-features = false` for the compiler and renderer alone.

pub mod abi;
#[cfg(feature = "cli")]
pub mod accuracy;
#[cfg(feature = "cli")]
pub mod bench;
pub mod check;
#[cfg(feature = "cli")]
pub mod cli;
pub mod diag;
#[cfg(feature = "cli")]
pub mod fuzz;
pub mod handwritten;
pub mod ir;
pub mod jit;
pub mod limits;
pub mod link;
pub mod mid;
pub mod ops;
pub mod pipeline;
pub mod runtime;
pub mod scene;
pub mod syntax;
pub mod testing;
pub mod trace;
// The benchmark workloads (`Workload`, `GlScene`) are read by `bench` only.
#[cfg_attr(not(feature = "cli"), allow(dead_code))]
pub mod workload;

use diag::{Diagnostics, FileId, SourceMap};

/// Parse and check the given files of `sources` as one program (all primitives, shared
/// interpolators and helpers share one namespace). Diagnostics go to `diags`; the program
/// is returned only if there were no errors.
pub fn compile(sources: &SourceMap, files: &[FileId], diags: &mut Diagnostics) -> Option<ir::Program> {
    let modules: Vec<_> = files
        .iter()
        .map(|&f| syntax::parse(f, sources.text(f), diags))
        .collect();
    if diags.has_errors() {
        return None;
    }
    let modules: Vec<&syntax::ast::Module> = modules.iter().collect();
    let program = check::check(&modules, diags);
    if diags.has_errors() {
        None
    } else {
        Some(program)
    }
}
