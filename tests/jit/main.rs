//! The JIT: kernels compiled from hand-built IR (`support::jit`) and from the library (`support`), run on
//! real tile contexts and checked pixel by pixel against Rust references, at both tiers.
//!
//! One test binary per layer keeps the suite to a handful of links; one module per concern.

mod array_clear;
mod batch;
mod blocks;
mod builtins;
mod calls;
mod dead_setup;
mod deep_programs;
mod disassembly;
mod edges;
mod error_order;
mod eval_generated;
mod eval_oracle;
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
mod large_locals;
mod multiply_by_one;
mod outline;
mod pixel;
mod row_locals;
mod rows;
mod setup;
mod setup_split;
mod splat;
#[path = "../support/mod.rs"]
mod support;
mod tier0;
mod tiers;
mod uniform_operands;
mod unroll;
mod unswitch;
mod value_numbering;
