//! The JIT: kernels compiled from hand-built IR (`support::jit`) and from the library (`support`), run on
//! real tile contexts and checked pixel by pixel against Rust references, at both tiers; and the
//! pieces beside code generation that the kernels' results rest on: the IR evaluator's scalar
//! semantics (`eval_scalar`), the middle end's constant folding and intervals
//! (`constant_folding`, `intervals`) and the libm functions kernels call (`libm`); and the
//! evaluator's f64 precision, the reference the kernels' f32 shading is measured against
//! (`eval_f64`).
//!
//! One test binary per layer keeps the suite to a handful of links; one module per concern.

mod array_clear;
mod batch;
mod blocks;
mod builtins;
mod calls;
mod compile_panic;
mod constant_folding;
mod dead_setup;
mod deep_programs;
mod disassembly;
mod edges;
mod error_order;
mod eval_f64;
mod eval_generated;
mod eval_oracle;
mod eval_scalar;
mod fixed;
mod float_division;
mod forward;
mod fuel;
mod fuzz;
mod golden;
mod group_state;
mod guard_bounds;
mod index_range;
mod inlined_helpers;
mod inout_helpers;
mod int_affine;
mod int_conversion;
mod intervals;
mod kernel_threads;
mod large_locals;
mod libm;
mod multiply_by_one;
mod outline;
mod pixel;
mod row_locals;
mod rows;
mod setup;
mod setup_split;
mod shading;
mod splat;
#[path = "../support/mod.rs"]
mod support;
mod tier0;
mod tier0_upgrade_word;
mod tiers;
mod uniform_operands;
mod unroll;
mod unswitch;
mod value_numbering;
