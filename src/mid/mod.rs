//! The middle end: the passes between the checked [`crate::ir`] and the JIT's lowering to
//! CLIF that need no code generator. Each reads IR and answers with a table the lowering
//! consults; none imports Cranelift or [`crate::jit`].
//!
//! - [`unroll`]: IR -> IR, unrolls uniform loops with a compile-time trip count.
//! - [`bounds`]: value bounds of float locals, and the guard facts that narrow them.
//! - [`dead`]: tier 0, the setup locals live code reads.
//! - [`init`]: the stack arrays some read may reach before they are assigned.
//! - [`flat`]: tier 0, whether pixel code may be lowered without a group's early exits.

pub mod bounds;
pub mod dead;
pub mod flat;
pub mod init;
pub mod unroll;
