//! Shared helpers for the JIT tests: build small IR programs by hand and run kernels on a
//! real `TileCtx` backed by `Vec` buffers.
#![allow(dead_code)]

use primflow::abi::Kernel;
use primflow::abi::{
    Binding, BindingKind, ErrorSlot, TileCtx, VariantKey, DEFAULT_FUEL, DEFAULT_GROUP_FUEL_FLOOR, DEFAULT_PIXEL_FUEL,
    MODE_RENDER,
};
use primflow::diag::Span;
use primflow::ir::tree::intern_body;
pub use primflow::ir::tree::{Tree, TreeKind};
use primflow::ir::*;

pub const W: usize = 16;
pub const H: usize = 8;

pub fn float() -> Type {
    Type::float()
}
pub fn fixed(bits: u8, frac: u8) -> Type {
    Type::scalar(Scalar::Fixed(FixedFormat { bits, frac }))
}

/// A function under construction: its parameters, locals and loops in `f`, its body as
/// trees in `setup` and `pixel` until [`Fb::finish`] moves them into `f`'s arenas.
pub struct Fb {
    pub f: Function,
    pub setup: Vec<Stmt<Tree>>,
    pub pixel: Vec<Stmt<Tree>>,
}

impl Fb {
    pub fn new(name: &str, kind: FuncKind) -> Fb {
        Fb {
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
            setup: vec![],
            pixel: vec![],
        }
    }
    /// The function, its body in its arenas (numbered as the checker numbers it).
    pub fn finish(self) -> Function {
        let mut f = self.f;
        let body = intern_body(self.setup, self.pixel);
        (f.setup, f.pixel, f.stmts, f.exprs) = (body.setup, body.pixel, body.stmts, body.exprs);
        f
    }
    fn add_local(&mut self, name: &str, ty: Type, var: Variability, kind: LocalKind) -> LocalId {
        self.f.locals.push(Local {
            name: name.into(),
            ty,
            var,
            kind,
            span: Span::default(),
        });
        LocalId(self.f.locals.len() as u32 - 1)
    }
    /// Parameters must be added before locals (parameter i is LocalId(i)).
    pub fn param(&mut self, name: &str, ty: Type, role: ParamRole) -> Tree {
        let var = match role {
            ParamRole::X | ParamRole::Y | ParamRole::Z => Variability::Varying,
            _ => Variability::Uniform,
        };
        let i = self.f.params.len() as u32;
        let id = self.add_local(name, ty.clone(), var, LocalKind::Param(i));
        self.f.params.push(Param {
            local: id,
            name: name.into(),
            role,
            space: ParamSpace::None,
            default: None,
            span: Span::default(),
        });
        local(id, ty, var)
    }
    /// The X, Y, Z parameters as floats.
    pub fn xyz(&mut self) -> (Tree, Tree, Tree) {
        (
            self.param("X", float(), ParamRole::X),
            self.param("Y", float(), ParamRole::Y),
            self.param("Z", float(), ParamRole::Z),
        )
    }
    pub fn local(&mut self, name: &str, ty: Type, var: Variability) -> Tree {
        let id = self.add_local(name, ty.clone(), var, LocalKind::Var);
        local(id, ty, var)
    }
    pub fn new_loop(&mut self) -> LoopId {
        self.f.loops += 1;
        LoopId(self.f.loops - 1)
    }
}

pub fn e(kind: TreeKind, ty: Type, var: Variability) -> Tree {
    Tree::new(kind, ty, var, Span::default())
}
pub fn s(kind: StmtKind<Tree>) -> Stmt<Tree> {
    Stmt {
        kind,
        span: Span::default(),
    }
}
pub fn local(id: LocalId, ty: Type, var: Variability) -> Tree {
    e(TreeKind::Local(id), ty, var)
}
pub fn fc(x: f32) -> Tree {
    e(TreeKind::Const(ConstValue::Float(x)), float(), Variability::Uniform)
}
pub fn ic(i: i32) -> Tree {
    e(TreeKind::Const(ConstValue::Int(i)), Type::int(), Variability::Uniform)
}
pub fn bc(b: bool) -> Tree {
    e(TreeKind::Const(ConstValue::Bool(b)), Type::bool(), Variability::Uniform)
}
pub fn bin(op: BinOp, a: Tree, b: Tree) -> Tree {
    let var = a.var.join(b.var);
    let shape = if a.ty.dims.is_empty() && a.ty.elem != Elem::Interp {
        b.ty.clone()
    } else {
        a.ty.clone()
    };
    let ty = match op {
        BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne | BinOp::And | BinOp::Or => Type {
            elem: Elem::Scalar(Scalar::Bool),
            ..shape
        },
        _ => shape,
    };
    e(
        TreeKind::Binary {
            op,
            lhs: Box::new(a),
            rhs: Box::new(b),
        },
        ty,
        var,
    )
}
pub fn conv(x: Tree, to: Scalar) -> Tree {
    let ty = Type {
        elem: Elem::Scalar(to),
        ..x.ty.clone()
    };
    let var = x.var;
    e(TreeKind::Convert(Box::new(x)), ty, var)
}
pub fn index(base: Tree, i: Tree, site: u32) -> Tree {
    let ty = base.ty.element();
    let var = base.var.join(i.var);
    e(
        TreeKind::Index {
            base: Box::new(base),
            index: Box::new(i),
            site: SiteId(site),
        },
        ty,
        var,
    )
}
pub fn list(items: Vec<Tree>) -> Tree {
    let var = items.iter().fold(Variability::Uniform, |v, i| v.join(i.var));
    let mut dims = vec![items.len() as u32];
    dims.extend(items[0].ty.dims.clone());
    let ty = Type::array(items[0].ty.elem, dims);
    e(TreeKind::List(items), ty, var)
}
pub fn select(c: Tree, a: Tree, b: Tree) -> Tree {
    let var = c.var.join(a.var).join(b.var);
    let ty = a.ty.clone();
    e(
        TreeKind::Select {
            cond: Box::new(c),
            then: Box::new(a),
            otherwise: Box::new(b),
        },
        ty,
        var,
    )
}
pub fn assign(target: &Tree, value: Tree) -> Stmt<Tree> {
    let TreeKind::Local(l) = target.kind else {
        panic!("assign to a local")
    };
    s(StmtKind::Assign {
        place: Place {
            local: l,
            indices: vec![],
            span: Span::default(),
        },
        value,
    })
}
pub fn assign_at(target: &Tree, i: Tree, site: u32, value: Tree) -> Stmt<Tree> {
    let TreeKind::Local(l) = target.kind else {
        panic!("assign to a local")
    };
    s(StmtKind::Assign {
        place: Place {
            local: l,
            indices: vec![(i, SiteId(site))],
            span: Span::default(),
        },
        value,
    })
}
pub fn if_(cond: Tree, then: Vec<Stmt<Tree>>, otherwise: Vec<Stmt<Tree>>) -> Stmt<Tree> {
    s(StmtKind::If { cond, then, otherwise })
}
pub fn while_(id: LoopId, cond: Tree, body: Vec<Stmt<Tree>>, site: u32) -> Stmt<Tree> {
    let varying = cond.var.is_varying();
    s(StmtKind::Loop {
        id,
        cond: Some(cond),
        body,
        step: vec![],
        varying,
        site: SiteId(site),
    })
}
pub fn ret() -> Stmt<Tree> {
    s(StmtKind::Return)
}
pub fn interp_return(x: Tree) -> Stmt<Tree> {
    s(StmtKind::InterpolatorReturn(Some(x)))
}
/// `interpolation { kind: body }`: one named arm (`interpolator_return(e)` of a primitive
/// stands in one, see `primflow::ir::valid`).
pub fn arm(kind: &str, body: Vec<Stmt<Tree>>) -> Stmt<Tree> {
    s(StmtKind::Interpolation {
        arms: vec![InterpArm {
            kind: ArmKind::Named(kind.into()),
            body,
            span: Span::default(),
        }],
    })
}
pub fn bound(r: [Tree; 4]) -> Stmt<Tree> {
    s(StmtKind::Bound(r))
}

/// The program of `funcs` (each [`Fb::finish`]ed: its expressions numbered).
pub fn program(funcs: Vec<Function>, sites: usize) -> Program {
    Program {
        functions: funcs,
        sites: vec![Span::default(); sites],
        ..Program::default()
    }
}

pub fn kind_key(kinds: &[(&str, u32)]) -> VariantKey {
    VariantKey {
        bindings: kinds
            .iter()
            .map(|(k, n)| Binding {
                kind: BindingKind::Kind(k.to_string()),
                components: *n,
            })
            .collect(),
        count_writes: false,
        trivial_accept: false,
    }
}

pub fn fw(x: f32) -> u32 {
    x.to_bits()
}

/// A tile of pixels with its depth, G-buffer, write-count and error-count buffers: the one
/// way the JIT tests build a `TileCtx`. [`Tile::new`] is a W x H (16x8) tile at the screen
/// origin of a 64x32 viewport; [`Tile::sized`] and [`Tile::at`] give other sizes and places.
pub struct Tile {
    pub depth: Vec<u32>,
    pub gbuf: Vec<f32>,
    pub counts: Vec<u32>,
    pub planes: usize,
    /// Width and height in pixels; rows are `w` apart, planes `w * h`.
    pub w: usize,
    pub h: usize,
    pub x0: i32,
    pub y0: i32,
    /// `TileCtx::width` and `height`: the viewport the kernel clamps its bound to.
    pub viewport: (u32, u32),
    /// `TileCtx::pixel_fuel` and `group_fuel_floor` of the runs.
    pub pixel_fuel: u64,
    pub group_fuel_floor: u64,
    /// The run-time error counts of every run on this tile, setup and pixel code alike
    /// (`TileCtx::setup_counts`, `pixel_counts`): room for programs of up to
    /// `ERROR_SLOTS` slots (`abi::count_slots`).
    pub errors: Vec<u64>,
}

/// Error count slots a [`Tile`] has room for.
pub const ERROR_SLOTS: usize = 1 << 16;

impl Tile {
    pub fn new(planes: usize) -> Tile {
        Tile {
            viewport: (64, 32),
            ..Tile::sized(W, H, planes)
        }
    }
    /// A `w` x `h` tile at the origin of a 4096 x 4096 viewport, every buffer zero.
    pub fn sized(w: usize, h: usize, planes: usize) -> Tile {
        Tile {
            depth: vec![0; w * h],
            gbuf: vec![0.0; w * h * planes.max(1)],
            counts: vec![0; w * h],
            planes,
            w,
            h,
            x0: 0,
            y0: 0,
            viewport: (4096, 4096),
            pixel_fuel: DEFAULT_PIXEL_FUEL,
            group_fuel_floor: DEFAULT_GROUP_FUEL_FLOOR,
            errors: vec![0; ERROR_SLOTS],
        }
    }
    /// The same tile with its top-left pixel at (x0, y0).
    pub fn at(self, x0: i32, y0: i32) -> Tile {
        Tile { x0, y0, ..self }
    }
    /// The count of `slot` (of a program with `sites` sites) over the runs so far.
    pub fn error_count(&self, slot: ErrorSlot, sites: usize) -> u64 {
        self.errors[slot.index(sites)]
    }
    pub fn ctx(&mut self, mode: u32, fuel: u64) -> TileCtx {
        TileCtx {
            x0: self.x0,
            y0: self.y0,
            x1: self.x0 + self.w as i32,
            y1: self.y0 + self.h as i32,
            stride: self.w as u32,
            depth: self.depth.as_mut_ptr(),
            gbuf: self.gbuf.as_mut_ptr(),
            plane_stride: (self.w * self.h) as u32,
            num_planes: self.planes as u32,
            write_count: self.counts.as_mut_ptr(),
            fuel,
            pixel_fuel: self.pixel_fuel,
            group_fuel_floor: self.group_fuel_floor,
            setup_counts: self.errors.as_mut_ptr(),
            pixel_counts: self.errors.as_mut_ptr(),
            ..TileCtx::new(mode, self.viewport.0, self.viewport.1)
        }
    }
    /// Run `k` in render mode with the given args; returns the context afterwards.
    pub fn render(&mut self, k: &Kernel, args: &[u32]) -> TileCtx {
        self.run(k, args, MODE_RENDER, DEFAULT_FUEL)
    }
    pub fn run(&mut self, k: &Kernel, args: &[u32], mode: u32, fuel: u64) -> TileCtx {
        let n_seq = args.first().copied().unwrap_or(1);
        assert!(
            args.len() >= k.layout.words(n_seq),
            "args block too short for the layout"
        );
        let mut ctx = self.ctx(mode, fuel);
        // SAFETY: ctx points at this tile's live buffers, sized stride*rows (and planes);
        // args is at least the layout's length.
        unsafe { (k.entry)(&mut ctx, args.as_ptr()) };
        ctx
    }
    pub fn depth_at(&self, x: usize, y: usize) -> u32 {
        self.depth[y * self.w + x]
    }
    pub fn plane_at(&self, p: usize, x: usize, y: usize) -> f32 {
        self.gbuf[(p * self.h + y) * self.w + x]
    }
}
