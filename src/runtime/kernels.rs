//! Where the renderer gets its kernels: the seam between the runtime and the JIT.
//!
//! The renderer asks a [`KernelSource`] for one kernel per (primitive, variant key) before it
//! renders. The [`Jit`] is the real source. Tests (and later the benchmark's hand-written
//! kernels) implement the trait themselves to hand in `extern "C"` Rust functions that follow
//! the same ABI (`abi::KernelFn`). The contract a source must keep: the returned kernel's
//! `layout` is `ArgLayout::new(program, func, key)` and its `entry` stays callable for as long
//! as the source is alive; the renderer checks the layout and borrows the source for the whole
//! render. A kernel of a primitive that `abi::expands` must also honour `MODE_EXPAND`: hand
//! its calls to `TileCtx::expand` instead of making them (`abi::call_primitive` does both).
//! A source whose kernels get faster code later (a tiered [`Jit`]) says so through
//! [`KernelSource::tier_up`], so the renderer can leave its background compiler a core.

use std::sync::Arc;

use crate::abi::{Kernel, KernelError, TierUpWatch, VariantKey};
use crate::ir::FuncId;
use crate::jit::Jit;

/// Something that turns (primitive, key) into a callable kernel.
pub trait KernelSource {
    fn kernel(&mut self, func: FuncId, key: &VariantKey) -> Result<Arc<Kernel>, KernelError>;

    /// The background compiler that will upgrade the kernels handed out, if any: while it
    /// has a compile pending the renderer runs on one thread fewer than its pool has
    /// (`super::tiergate`). None for a source whose kernels are final.
    fn tier_up(&self) -> Option<TierUpWatch> {
        None
    }
}

impl KernelSource for Jit {
    fn kernel(&mut self, func: FuncId, key: &VariantKey) -> Result<Arc<Kernel>, KernelError> {
        Jit::kernel(self, func, key)
    }

    fn tier_up(&self) -> Option<TierUpWatch> {
        self.tier_up_watch()
    }
}
