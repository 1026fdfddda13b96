//! Hand-written Rust kernels of library primitives, behind the same ABI as the JIT's
//! (`abi::KernelFn`), for the benchmark (JIT vs hand-written, side by side) and for tests
//! that check a JIT kernel and its hand-written twin produce the same buffers.
//!
//! A [`Handwritten`] is a [`KernelSource`]: hand it to `Renderer::render` instead of the
//! JIT. It serves screen_triangle and polygon (whose fan calls the hand-written
//! screen_triangle of the same [`Flavor`]) for keys whose bindings are `perspective_linear`
//! components followed by `linear` ones (the shapes the benchmark uses), for the shapes in
//! the table below, sphere (scalar, SSE4.1 and AVX2 forms) and NURB surface (scalar and
//! AVX2 forms; see their modules for the keys). Other keys and forms are an error, never a silent fallback.

pub mod nurb;
pub mod polygon;
pub mod screen_triangle;
pub mod sphere;

use std::sync::Arc;

use crate::abi::{ArgLayout, BindingKind, Kernel, KernelError, KernelFn, ParamSlot, VariantKey};
use crate::ir::{FuncId, Program};
use crate::runtime::KernelSource;

/// Which form of the hand-written kernels to serve.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Flavor {
    /// Portable scalar Rust.
    Scalar,
    /// std::arch SSE4.1, 4 lanes (the JIT's width), VEX-encoded when the CPU has AVX (as
    /// the JIT's code is); the scalar form without SSE4.1.
    Sse,
    /// std::arch AVX2 (8 lanes) when the CPU has it; the scalar form otherwise.
    Avx2,
}

impl Flavor {
    /// What actually runs on this CPU.
    pub fn describe(self) -> &'static str {
        match self.isa() {
            isa::SSE41_VEX => "SSE4.1 (4 lanes, VEX)",
            isa::SSE41 => "SSE4.1 (4 lanes)",
            isa::AVX2 => "AVX2 (8 lanes)",
            _ => match self {
                Flavor::Scalar => "scalar",
                Flavor::Sse => "scalar (no SSE4.1 on this CPU)",
                Flavor::Avx2 => "scalar (no AVX2 on this CPU)",
            },
        }
    }

    /// The kernel form that runs for this flavour on this CPU (an [`isa`] constant).
    fn isa(self) -> u8 {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            match self {
                Flavor::Sse if has!("sse4.1") && has!("avx") => isa::SSE41_VEX,
                Flavor::Sse if has!("sse4.1") => isa::SSE41,
                Flavor::Avx2 if has!("avx2") => isa::AVX2,
                _ => isa::SCALAR,
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            isa::SCALAR
        }
    }
}

/// Kernel forms, as const-generic parameters (`polygon::kernel` picks its triangle by one).
pub mod isa {
    pub const SCALAR: u8 = 0;
    pub const SSE41: u8 = 1;
    pub const SSE41_VEX: u8 = 2;
    pub const AVX2: u8 = 3;
}

/// The screen_triangle kernel of one key shape, write counting and form (`isa::*`; a form
/// not built for this architecture is the scalar one).
pub(crate) fn screen_triangle_kernel<const P: usize, const L: usize, const T: usize>(count: bool, isa: u8) -> KernelFn {
    use screen_triangle as st;
    #[cfg(target_arch = "x86_64")]
    match (isa, count) {
        (isa::SSE41, false) => return st::sse41::<P, L, T, false>,
        (isa::SSE41, true) => return st::sse41::<P, L, T, true>,
        (isa::SSE41_VEX, false) => return st::sse41_vex::<P, L, T, false>,
        (isa::SSE41_VEX, true) => return st::sse41_vex::<P, L, T, true>,
        (isa::AVX2, false) => return st::avx2::<P, L, T, false>,
        (isa::AVX2, true) => return st::avx2::<P, L, T, true>,
        _ => {}
    }
    let _ = isa;
    if count {
        st::scalar::<P, L, T, true>
    } else {
        st::scalar::<P, L, T, false>
    }
}

/// The polygon kernel of one key shape, write counting, form and `clipping()` value.
fn polygon_kernel<const P: usize, const L: usize, const T: usize>(count: bool, isa: u8, clip: bool) -> KernelFn {
    use polygon::kernel as k;
    macro_rules! forms {
        ($($isa:path),*) => {
            match (isa, count, clip) {
                $(
                    ($isa, false, false) => k::<P, L, T, false, { $isa }, false>,
                    ($isa, false, true) => k::<P, L, T, false, { $isa }, true>,
                    ($isa, true, false) => k::<P, L, T, true, { $isa }, false>,
                    ($isa, true, true) => k::<P, L, T, true, { $isa }, true>,
                )*
                (_, false, false) => k::<P, L, T, false, { isa::SCALAR }, false>,
                (_, false, true) => k::<P, L, T, false, { isa::SCALAR }, true>,
                (_, true, false) => k::<P, L, T, true, { isa::SCALAR }, false>,
                (_, true, true) => k::<P, L, T, true, { isa::SCALAR }, true>,
            }
        };
    }
    #[cfg(target_arch = "x86_64")]
    {
        forms!(isa::SSE41, isa::SSE41_VEX, isa::AVX2)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        forms!()
    }
}

/// The hand-written kernels of one [`Flavor`], as a [`KernelSource`].
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

/// The key shapes (perspective_linear, linear components) with hand-written kernels; the
/// const generics make each its own monomorphised kernel.
macro_rules! shape_table {
    ($(($p:literal, $l:literal)),*) => {
        fn screen_triangle_entry(p: usize, l: usize, count: bool, isa: u8) -> Option<KernelFn> {
            match (p, l) {
                $(($p, $l) => Some(screen_triangle_kernel::<$p, $l, { $p + $l }>(count, isa)),)*
                _ => None,
            }
        }
        fn polygon_entry(p: usize, l: usize, count: bool, isa: u8, clip: bool) -> Option<KernelFn> {
            match (p, l) {
                $(($p, $l) => Some(polygon_kernel::<$p, $l, { $p + $l }>(count, isa, clip)),)*
                _ => None,
            }
        }
    };
}

shape_table!(
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

fn error(message: String) -> KernelError {
    KernelError { message }
}

/// Whether screen_triangle's arguments under `key` (`t` components) sit where the
/// hand-written kernel reads them: screen_vertex right after the plane table, then
/// interp_data[3].
fn screen_triangle_layout_ok(layout: &ArgLayout, t: u32) -> bool {
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
    layout.params.len() == 5 && layout.params[..2] == expected
}

impl Handwritten {
    fn screen_triangle(&self, func: FuncId, key: &VariantKey) -> Result<KernelFn, KernelError> {
        let (p, l) = key_shape(key).ok_or_else(|| {
            error("hand-written screen_triangle serves perspective_linear then linear bindings only".into())
        })?;
        // The kernel reads fixed offsets; refuse if the library's declaration has moved them.
        if !screen_triangle_layout_ok(&ArgLayout::new(&self.program, func, key), (p + l) as u32) {
            return Err(error(
                "screen_triangle's parameters are not the ones the hand-written kernel reads".into(),
            ));
        }
        screen_triangle_entry(p, l, key.count_writes, self.flavor.isa()).ok_or_else(|| {
            error(format!(
                "no hand-written screen_triangle for {p} perspective + {l} linear components"
            ))
        })
    }

    /// The sphere in this flavour's form (scalar, SSE4.1 legacy or VEX, AVX2); its
    /// `entry_for` checks the layout and the key.
    fn sphere(&self, func: FuncId, key: &VariantKey) -> Result<KernelFn, KernelError> {
        sphere::entry_for(&ArgLayout::new(&self.program, func, key), key, self.flavor.isa()).map_err(error)
    }

    /// A kernel with scalar and AVX2 forms only (NURB surface); `entry_for` checks the
    /// layout and the key, and picks the AVX2 form when told to.
    fn shape(
        &self,
        entry_for: fn(&ArgLayout, &VariantKey, bool) -> Result<KernelFn, String>,
        func: FuncId,
        key: &VariantKey,
    ) -> Result<KernelFn, KernelError> {
        let avx2 = match self.flavor.isa() {
            isa::AVX2 => true,
            // No AVX2 on this CPU: the scalar form, as `describe` says.
            isa::SCALAR if self.flavor != Flavor::Sse => false,
            _ => {
                return Err(error(format!(
                    "no hand-written {} form of `{}`",
                    self.flavor.describe(),
                    self.program.func(func).name
                )))
            }
        };
        entry_for(&ArgLayout::new(&self.program, func, key), key, avx2).map_err(error)
    }

    fn polygon(&self, func: FuncId, key: &VariantKey) -> Result<KernelFn, KernelError> {
        let (p, l) = key_shape(key)
            .ok_or_else(|| error("hand-written polygon serves perspective_linear then linear bindings only".into()))?;
        let t = (p + l) as u32;
        let layout = ArgLayout::new(&self.program, func, key);
        let expected = [
            ParamSlot::Seq {
                seq_offset: 0,
                words: 4,
            },
            ParamSlot::Seq {
                seq_offset: 4,
                words: t,
            },
        ];
        let polygon_ok = layout.params.len() == 5
            && layout.params[..2] == expected
            && layout.fixed_words == 1 + t
            && layout.spaces.is_none();
        // The fan builds screen_triangle's block itself: its layout must be the one the
        // hand-written screen_triangle reads.
        let triangle_ok = self
            .program
            .find("screen_triangle")
            .is_some_and(|id| screen_triangle_layout_ok(&ArgLayout::new(&self.program, id, key), t));
        if !(polygon_ok && triangle_ok) {
            return Err(error(
                "polygon's or screen_triangle's parameters are not the ones the hand-written kernel reads".into(),
            ));
        }
        if p + l > polygon::MAX_COMPONENTS {
            return Err(error(format!(
                "hand-written polygon handles at most {} components",
                polygon::MAX_COMPONENTS
            )));
        }
        polygon_entry(p, l, key.count_writes, self.flavor.isa(), !key.trivial_accept).ok_or_else(|| {
            error(format!(
                "no hand-written polygon for {p} perspective + {l} linear components"
            ))
        })
    }
}

impl KernelSource for Handwritten {
    fn kernel(&mut self, func: FuncId, key: &VariantKey) -> Result<Arc<Kernel>, KernelError> {
        let f = self.program.func(func);
        let entry = match f.name.as_str() {
            "screen_triangle" => self.screen_triangle(func, key)?,
            "polygon" => self.polygon(func, key)?,
            "sphere" => self.sphere(func, key)?,
            "nurb_surface" => self.shape(nurb::entry_for, func, key)?,
            other => return Err(error(format!("no hand-written kernel for primitive `{other}`"))),
        };
        Ok(Arc::new(Kernel {
            func,
            key: key.clone(),
            entry,
            layout: ArgLayout::new(&self.program, func, key),
            compile_micros: 0,
            warnings: vec![],
        }))
    }
}
