//! Hand-written Rust kernels of library primitives, behind the same ABI as the JIT's
//! (`abi::KernelFn`), for the benchmark (JIT vs hand-written, side by side) and for tests
//! that check a JIT kernel and its hand-written twin produce the same buffers.
//!
//! A [`Handwritten`] is a [`KernelSource`]: hand it to `Renderer::render` instead of the
//! JIT. It serves keys whose bindings are `perspective_linear` components followed by
//! `linear` ones (the shapes the benchmark uses), for up to 16 of each; other keys are an
//! error, never a silent fallback.

pub mod nurb;
pub mod screen_triangle;
pub mod sphere;

use std::sync::Arc;

use crate::abi::{ArgLayout, BindingKind, KernelFn, ParamSlot, VariantKey};
use crate::ir::{FuncId, Program};
use crate::jit::{JitError, Kernel};
use crate::runtime::KernelSource;

/// Which form of the hand-written kernels to serve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flavor {
    /// Portable scalar Rust.
    Scalar,
    /// std::arch AVX2 (8 lanes) when the CPU has it; the scalar form otherwise.
    Simd,
}

impl Flavor {
    /// What actually runs on this CPU.
    pub fn describe(self) -> &'static str {
        match self {
            Flavor::Scalar => "scalar",
            Flavor::Simd if has_avx2() => "AVX2 (8 lanes)",
            Flavor::Simd => "scalar (no AVX2 on this CPU)",
        }
    }
}

fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// A shape file's kernel lookup: the entry for a key under a layout, or why there is none.
type EntryFor = fn(&ArgLayout, &VariantKey, bool) -> Result<KernelFn, String>;

pub struct Handwritten {
    program: Arc<Program>,
    flavor: Flavor,
}

impl Handwritten {
    pub fn new(program: Arc<Program>, flavor: Flavor) -> Handwritten {
        Handwritten { program, flavor }
    }
}

/// (perspective_linear components, linear components) of a key the kernels serve.
fn key_shape(key: &VariantKey) -> Option<(usize, usize)> {
    let mut p = 0;
    let mut l = 0;
    for b in &key.bindings {
        match &b.kind {
            BindingKind::Kind(k) if k == "perspective_linear" && l == 0 => p += b.components as usize,
            BindingKind::Kind(k) if k == "linear" => l += b.components as usize,
            _ => return None,
        }
    }
    Some((p, l))
}

macro_rules! screen_triangle_table {
    ($(($p:literal, $l:literal)),*) => {
        fn screen_triangle_entry(p: usize, l: usize, count: bool, simd: bool) -> Option<KernelFn> {
            match (p, l, count, simd) {
                $(
                    ($p, $l, false, false) => Some(screen_triangle::scalar::<$p, $l, { $p + $l }, false>),
                    ($p, $l, true, false) => Some(screen_triangle::scalar::<$p, $l, { $p + $l }, true>),
                    #[cfg(target_arch = "x86_64")]
                    ($p, $l, false, true) => Some(screen_triangle::avx2::<$p, $l, { $p + $l }, false>),
                    #[cfg(target_arch = "x86_64")]
                    ($p, $l, true, true) => Some(screen_triangle::avx2::<$p, $l, { $p + $l }, true>),
                )*
                _ => None,
            }
        }
    };
}

screen_triangle_table!(
    (0, 0),
    (1, 0),
    (0, 1),
    (4, 0),
    (0, 4),
    (2, 2),
    (1, 1),
    (3, 0),
    (0, 3),
    (16, 0),
    (0, 16),
    (8, 8),
    (3, 3),
    (4, 4)
);

impl KernelSource for Handwritten {
    fn kernel(&mut self, func: FuncId, key: &VariantKey) -> Result<Arc<Kernel>, JitError> {
        let f = self.program.func(func);
        let err = |m: String| JitError { message: m };
        let shape = match f.name.as_str() {
            "sphere" => Some(sphere::entry_for as EntryFor),
            "nurb_surface" => Some(nurb::entry_for as EntryFor),
            _ => None,
        };
        if let Some(entry_for) = shape {
            let layout = ArgLayout::new(&self.program, func, key);
            let entry = entry_for(&layout, key, self.flavor == Flavor::Simd && has_avx2()).map_err(err)?;
            return Ok(Arc::new(Kernel {
                func,
                key: key.clone(),
                entry,
                layout,
                compile_micros: 0,
                warnings: vec![],
            }));
        }
        if f.name != "screen_triangle" {
            return Err(err(format!("no hand-written kernel for primitive `{}`", f.name)));
        }
        let (p, l) = key_shape(key).ok_or_else(|| {
            err("hand-written screen_triangle serves perspective_linear then linear bindings only".into())
        })?;
        let layout = ArgLayout::new(&self.program, func, key);
        // The kernel reads fixed offsets; refuse if the library's declaration has moved them.
        let t = (p + l) as u32;
        let expected = [
            ParamSlot::Fixed {
                offset: 1 + t,
                words: 12,
            },
            ParamSlot::Fixed {
                offset: 13 + t,
                words: 3 * t,
            },
        ];
        if layout.params.len() != 5 || layout.params[..2] != expected {
            return Err(err(
                "screen_triangle's parameters are not the ones the hand-written kernel reads".into(),
            ));
        }
        let simd = self.flavor == Flavor::Simd && has_avx2();
        let entry = screen_triangle_entry(p, l, key.count_writes, simd).ok_or_else(|| {
            err(format!(
                "no hand-written screen_triangle for {p} perspective + {l} linear components"
            ))
        })?;
        Ok(Arc::new(Kernel {
            func,
            key: key.clone(),
            entry,
            layout,
            compile_micros: 0,
            warnings: vec![],
        }))
    }
}
