//! The contract between kernels and the runtime. Kernels come from a kernel source (the
//! JIT, the hand-written kernels, a test's own); the runtime depends on this contract, not
//! on any source.
//!
//! Files: [`ctx`] is the calling convention: the variant key, the per-tile context a kernel
//! reads and writes, its modes and error codes, and the layout of a primitive instance's
//! argument block. [`kernel`] is what a source hands out: a [`Kernel`] (entry point and
//! layout), the [`KernelError`] it reports instead, and the [`TierUpWatch`] on a source's
//! background compiler.

pub mod ctx;
pub mod kernel;

pub use ctx::*;
pub use kernel::*;
