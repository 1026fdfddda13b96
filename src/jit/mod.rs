//! The back end: specialises IR functions for a variant key and compiles them with Cranelift.

use std::sync::Arc;

use crate::abi::{ArgLayout, KernelFn, VariantKey};
use crate::ir::{FuncId, Program};

/// A compiled kernel for one (primitive, variant key).
#[derive(Debug)]
pub struct Kernel {
    pub func: FuncId,
    pub key: VariantKey,
    /// Entry point; valid while the [`Jit`] that made it is alive.
    pub entry: KernelFn,
    pub layout: ArgLayout,
    /// Wall time spent building and compiling this kernel (callees excluded), microseconds.
    pub compile_micros: u64,
    /// Things the specialisation noticed (a bound parameter no arm writes, ...).
    pub warnings: Vec<String>,
}

#[derive(Debug, Clone)]
pub struct JitError {
    pub message: String,
}

impl std::fmt::Display for JitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for JitError {}

/// Owns the JIT module (the code memory) and the kernel cache for one program.
pub struct Jit {
    program: Arc<Program>,
}

impl Jit {
    pub fn new(program: Arc<Program>) -> Result<Jit, JitError> {
        Ok(Jit { program })
    }
    pub fn program(&self) -> &Arc<Program> {
        &self.program
    }
    /// The kernel for `func` under `key`, compiled on first use and cached. Primitives it
    /// calls are compiled for the same key.
    pub fn kernel(&mut self, func: FuncId, key: &VariantKey) -> Result<Arc<Kernel>, JitError> {
        let _ = (func, key);
        Err(JitError {
            message: "JIT not implemented yet".into(),
        })
    }
    /// The Cranelift IR text of `func` specialised for `key` (for `check --emit clif`).
    pub fn clif(&self, func: FuncId, key: &VariantKey) -> Result<String, JitError> {
        let _ = (func, key);
        Err(JitError {
            message: "JIT not implemented yet".into(),
        })
    }
    /// The target ISA, the flags it was built with and the vector width kernels use.
    pub fn isa_summary(&self) -> String {
        String::new()
    }
}
