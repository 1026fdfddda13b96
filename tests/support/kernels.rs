//! Test support for the runtime: a hand-built `ir::Program` (parameters only; the bodies are
//! never compiled) and hand-written `extern "C"` kernels that follow the ABI, handed to the
//! renderer through the `KernelSource` seam so the runtime is tested without the JIT.
//!
//! Primitives:
//! - `rect(float rect[4]; float depth = 0.5; float color[3]; X, Y, Z)`: fills the pixels whose
//!   centre lies in rect (xmin, ymin, xmax, ymax) where `depth` is nearer than the buffer,
//!   writing depth and `color` into the first three plane-table entries (bound: the rect).
//! - `tri(point vertex[]; interpolation_data interp_data[]; interpolation_data corners[3];
//!   fixed<32,16> scale; int count = 7; X, Y, Z)`: for argument-block tests only.
//! - `spacey(float k; X, Y, Z)` uses spaces: for the space-matrix block.
//! - `faulty(X, Y, Z)`: covers the whole viewport and records ERR_INDEX at site 0.
//! - interpolator `cyl(float cylinder_start = 0, cylinder_end = 1; X, Y, Z)`.
#![allow(dead_code)]

use std::sync::Arc;

use primflow::abi::{ArgLayout, ErrorSlot, KernelFn, TileCtx, VariantKey, ERR_INDEX, MODE_BOUND};
use primflow::abi::{Kernel, KernelError};
use primflow::diag::{SourceMap, Span};
use primflow::ir::{
    ConstValue, Elem, Exprs, FixedFormat, FuncId, FuncKind, Function, Local, LocalId, LocalKind, Param, ParamRole,
    ParamSpace, Program, Scalar, SiteId, Stmts, Type, Variability,
};
use primflow::runtime::{KernelSource, Renderer};

pub fn float_array(dims: &[u32]) -> Type {
    Type::array(Elem::Scalar(Scalar::Float), dims.to_vec())
}

pub fn per_seq(mut ty: Type) -> Type {
    ty.per_seq = true;
    ty
}

struct FnBuilder {
    f: Function,
}

impl FnBuilder {
    fn new(name: &str, kind: FuncKind) -> FnBuilder {
        FnBuilder {
            f: Function {
                name: name.into(),
                kind,
                geometry: primflow::ir::Geometry::Surface,
                span: Span::default(),
                params: vec![],
                locals: vec![],
                setup: vec![],
                pixel: vec![],
                loops: 0,
                stmts: Stmts::new(),
                exprs: Exprs::new(),
                uses_spaces: false,
            },
        }
    }
    fn param(
        mut self,
        name: &str,
        role: ParamRole,
        ty: Type,
        space: ParamSpace,
        default: Option<Vec<ConstValue>>,
    ) -> Self {
        let i = self.f.params.len() as u32;
        let var = if matches!(role, ParamRole::X | ParamRole::Y | ParamRole::Z) {
            Variability::Varying
        } else {
            Variability::Uniform
        };
        self.f.locals.push(Local {
            name: name.into(),
            ty,
            var,
            kind: LocalKind::Param(i),
            span: Span::default(),
        });
        self.f.params.push(Param {
            local: LocalId(i),
            name: name.into(),
            role,
            space,
            default,
            span: Span::default(),
        });
        self
    }
    fn pixel_params(self) -> Self {
        self.param("X", ParamRole::X, Type::float(), ParamSpace::None, None)
            .param("Y", ParamRole::Y, Type::float(), ParamSpace::None, None)
            .param("Z", ParamRole::Z, Type::float(), ParamSpace::None, None)
    }
}

/// The test program. `sources` gets a fake `faulty.prim` so that site 0 has a location.
pub fn program(sources: &mut SourceMap) -> Arc<Program> {
    let text = "primitive faulty(varying float X, Y; inout varying float Z) {\n    float a[2];\n    Z = a[5];\n}\n";
    let file = sources.add("faulty.prim", text);
    let site_start = text.find("a[5]").unwrap();
    let rect = FnBuilder::new("rect", FuncKind::Primitive)
        .param(
            "rect",
            ParamRole::PerPrimitive,
            float_array(&[4]),
            ParamSpace::None,
            None,
        )
        .param(
            "depth",
            ParamRole::PerPrimitive,
            Type::float(),
            ParamSpace::None,
            Some(vec![ConstValue::Float(0.5)]),
        )
        .param(
            "color",
            ParamRole::PerPrimitive,
            float_array(&[3]),
            ParamSpace::None,
            None,
        )
        .pixel_params();
    let tri = FnBuilder::new("tri", FuncKind::Primitive)
        .param(
            "vertex",
            ParamRole::PerSequencePoint,
            per_seq(float_array(&[4])),
            ParamSpace::Point,
            None,
        )
        .param(
            "interp_data",
            ParamRole::InterpData,
            per_seq(Type::array(Elem::Interp, vec![])),
            ParamSpace::None,
            None,
        )
        .param(
            "corners",
            ParamRole::InterpData,
            Type::array(Elem::Interp, vec![3]),
            ParamSpace::None,
            None,
        )
        .param(
            "scale",
            ParamRole::PerPrimitive,
            Type::scalar(Scalar::Fixed(FixedFormat { bits: 32, frac: 16 })),
            ParamSpace::None,
            None,
        )
        .param(
            "count",
            ParamRole::PerPrimitive,
            Type::int(),
            ParamSpace::None,
            Some(vec![ConstValue::Int(7)]),
        )
        .pixel_params();
    let mut spacey = FnBuilder::new("spacey", FuncKind::Primitive)
        .param("k", ParamRole::PerPrimitive, Type::float(), ParamSpace::None, None)
        .pixel_params();
    spacey.f.uses_spaces = true;
    let faulty = FnBuilder::new("faulty", FuncKind::Primitive).pixel_params();
    let cyl = FnBuilder::new("cyl", FuncKind::Interpolator)
        .param(
            "cylinder_start",
            ParamRole::PerPrimitive,
            Type::float(),
            ParamSpace::None,
            Some(vec![ConstValue::Float(0.0)]),
        )
        .param(
            "cylinder_end",
            ParamRole::PerPrimitive,
            Type::float(),
            ParamSpace::None,
            Some(vec![ConstValue::Float(1.0)]),
        )
        .pixel_params();
    Arc::new(Program {
        functions: vec![rect.f, tri.f, spacey.f, faulty.f, cyl.f],
        sites: vec![Span::new(file, site_start, site_start + 4)],
        ..Program::default()
    })
}

/// The `rect` kernel; `OFF` is the word offset of its `rect` parameter (depth and color
/// follow), `COUNT` whether the key counts writes.
unsafe extern "C" fn rect_kernel<const OFF: usize, const COUNT: bool>(ctx: *mut TileCtx, args: *const u32) {
    // SAFETY (test kernel): the runtime passes a valid ctx and an args block of the layout's
    // length; OFF + 8 words lie inside it for the `rect` primitive.
    let ctx = unsafe { &mut *ctx };
    let word = |i: usize| unsafe { *args.add(i) };
    let f = |i: usize| f32::from_bits(word(i));
    let rect = [f(OFF), f(OFF + 1), f(OFF + 2), f(OFF + 3)];
    let depth = super::raw_depth(f64::from(f(OFF + 4)));
    let color = [f(OFF + 5), f(OFF + 6), f(OFF + 7)];
    if ctx.mode == MODE_BOUND {
        if rect.iter().any(|v| v.is_nan()) {
            return;
        }
        if ctx.bound_set == 0 {
            ctx.bound = rect;
            ctx.bound_set = 1;
        } else {
            ctx.bound = [
                ctx.bound[0].min(rect[0]),
                ctx.bound[1].min(rect[1]),
                ctx.bound[2].max(rect[2]),
                ctx.bound[3].max(rect[3]),
            ];
        }
        return;
    }
    for py in ctx.y0..ctx.y1 {
        for px in ctx.x0..ctx.x1 {
            let (cx, cy) = (px as f32 + 0.5, py as f32 + 0.5);
            if !(cx >= rect[0] && cx <= rect[2] && cy >= rect[1] && cy <= rect[3]) {
                continue;
            }
            let idx = (py - ctx.y0) as usize * ctx.stride as usize + (px - ctx.x0) as usize;
            // SAFETY: idx < stride * rows, the length of every tile buffer.
            unsafe {
                if depth <= *ctx.depth.add(idx) {
                    continue;
                }
                *ctx.depth.add(idx) = depth;
                for (c, value) in color.iter().enumerate() {
                    let plane = word(1 + c);
                    if plane < ctx.num_planes {
                        *ctx.gbuf.add(plane as usize * ctx.plane_stride as usize + idx) = *value;
                    }
                }
                if COUNT {
                    *ctx.write_count.add(idx) += 1;
                }
            }
        }
    }
}

macro_rules! rect_table {
    ($($n:literal)*) => {
        fn rect_entry(off: u32, count: bool) -> Option<KernelFn> {
            match (off, count) {
                $(($n, false) => Some(rect_kernel::<$n, false>), ($n, true) => Some(rect_kernel::<$n, true>),)*
                _ => None,
            }
        }
    };
}
rect_table!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32);

/// Covers the viewport (no bound recorded: the JIT would union the viewport) and fails in
/// its render runs: an index error at site 0, recorded and counted as pixel code's.
unsafe extern "C" fn faulty_kernel(ctx: *mut TileCtx, _args: *const u32) {
    // SAFETY (test kernel): ctx is valid for the call.
    let ctx = unsafe { &mut *ctx };
    if ctx.mode == MODE_BOUND {
        ctx.bound = [0.0, 0.0, ctx.width as f32, ctx.height as f32];
        ctx.bound_set = 1;
        return;
    }
    if ctx.error == 0 {
        ctx.error = ERR_INDEX;
        ctx.error_site = 0;
    }
    // An index slot's position does not depend on the program's site count.
    let at = ErrorSlot::Index(SiteId(0)).index(0);
    // SAFETY: the runtime's count arrays hold every slot of the program, which has site 0.
    unsafe { *ctx.pixel_counts.add(at) += 1 };
}

/// The test kernel source: `rect` and `faulty`; anything else fails to "compile".
pub struct TestKernels {
    pub program: Arc<Program>,
    pub requests: Vec<(FuncId, VariantKey)>,
}

impl TestKernels {
    pub fn new(program: Arc<Program>) -> TestKernels {
        TestKernels {
            program,
            requests: vec![],
        }
    }
}

impl KernelSource for TestKernels {
    fn kernel(&mut self, func: FuncId, key: &VariantKey) -> Result<Arc<Kernel>, KernelError> {
        self.requests.push((func, key.clone()));
        let layout = ArgLayout::new(&self.program, func, key);
        let name = self.program.func(func).name.as_str();
        let entry = match name {
            "rect" => {
                let primflow::abi::ParamSlot::Fixed { offset, .. } = layout.params[0] else {
                    unreachable!("rect is per-primitive")
                };
                rect_entry(offset, key.count_writes)
            }
            "faulty" => Some(faulty_kernel as KernelFn),
            _ => None,
        };
        let entry = entry.ok_or_else(|| KernelError {
            message: format!("no test kernel for `{name}`"),
        })?;
        Ok(Arc::new(Kernel {
            func,
            key: key.clone(),
            entry,
            layout,
            compile_micros: 1,
            warnings: vec![],
        }))
    }
}

/// Submit a `rect` instance.
pub fn rect(r: &mut Renderer, xy: [f32; 4], depth: f32, color: [f32; 3]) {
    r.begin("rect").unwrap();
    r.rast_param("rect", &xy.into()).unwrap();
    r.rast_param("depth", &depth.into()).unwrap();
    r.rast_param("color", &color.into()).unwrap();
    r.end().unwrap();
}

pub fn floats(words: &[u32]) -> Vec<f32> {
    words.iter().map(|&w| f32::from_bits(w)).collect()
}
