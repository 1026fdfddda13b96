//! A readable text dump of the IR (`primflow check --emit ir`, snapshot tests).
//!
//! Each function prints its kind and name, its parameters with role and space, its locals
//! with type and final variability, then the `setup:` and `pixel:` statement lists.
//! Locals are written `name%id`; statements and loops that run per pixel are marked
//! `varying`; constants print with their type when it is not plain float/int/bool
//! (`0.5:fixed<32,16>`); a primitive call names its callee (`call screen_triangle#8(...)`)
//! when the function is printed with its program ([`Function::display_in`], as a
//! [`Program`] prints its functions), only its id otherwise (`call primitive#8(...)`). The
//! output is deterministic, so it can be kept as a golden file.

use std::fmt::{self, Write};

use super::{
    ArmKind, Builtin, ConstValue, Elem, ExprId, ExprKind, FuncKind, Function, Geometry, LocalKind, Program, Scalar,
    Space, StmtId, StmtKind, Type, Variability,
};

impl fmt::Display for Program {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, func) in self.functions.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{}", func.display_in(self))?;
        }
        Ok(())
    }
}

/// A function printed with the names of the primitives it calls (see [`Function::display_in`]).
pub struct InProgram<'a> {
    func: &'a Function,
    program: &'a Program,
}

impl fmt::Display for InProgram<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.func.write(f, Some(self.program))
    }
}

impl Function {
    /// This function of `program` as text, a primitive call naming its callee
    /// (`call screen_triangle#8(...)`; printed alone, a function knows only the callee's id).
    pub fn display_in<'a>(&'a self, program: &'a Program) -> InProgram<'a> {
        InProgram { func: self, program }
    }
}

impl fmt::Display for Function {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.write(f, None)
    }
}

impl Function {
    fn write(&self, f: &mut fmt::Formatter<'_>, program: Option<&Program>) -> fmt::Result {
        let kind = match self.kind {
            FuncKind::Primitive => "primitive",
            FuncKind::Interpolator => "interpolator",
        };
        write!(f, "{kind} ")?;
        if self.geometry != Geometry::Surface {
            write!(f, "{} ", self.geometry.name())?;
        }
        write!(f, "{}", self.name)?;
        if self.uses_spaces {
            write!(f, " (uses spaces)")?;
        }
        writeln!(f)?;
        for p in &self.params {
            let l = self.local(p.local);
            write!(
                f,
                "  param {}%{}: {} {} role={:?} space={:?}",
                p.name,
                p.local.0,
                var_name(l.var),
                type_str(&l.ty),
                p.role,
                p.space
            )?;
            if let Some(d) = &p.default {
                let vals: Vec<String> = d.iter().map(|c| const_str(*c, scalar(&l.ty))).collect();
                write!(f, " default={{{}}}", vals.join(", "))?;
            }
            writeln!(f)?;
        }
        for (i, l) in self.locals.iter().enumerate() {
            if matches!(l.kind, LocalKind::Param(_)) {
                continue;
            }
            let kind = if l.kind == LocalKind::Temp { " (temp)" } else { "" };
            writeln!(
                f,
                "  local {}%{i}: {} {}{kind}",
                l.name,
                var_name(l.var),
                type_str(&l.ty)
            )?;
        }
        let p = Printer { func: self, program };
        writeln!(f, "  setup:")?;
        let mut s = String::new();
        p.block(&mut s, &self.setup, 2)?;
        f.write_str(&s)?;
        writeln!(f, "  pixel:")?;
        let mut s = String::new();
        p.block(&mut s, &self.pixel, 2)?;
        f.write_str(&s)
    }
}

fn var_name(v: Variability) -> &'static str {
    match v {
        Variability::Uniform => "uniform",
        Variability::Varying => "varying",
    }
}

fn scalar(ty: &Type) -> Option<Scalar> {
    match ty.elem {
        Elem::Scalar(s) => Some(s),
        Elem::Interp => None,
    }
}

fn scalar_str(s: Scalar) -> String {
    match s {
        Scalar::Float => "float".into(),
        Scalar::Int => "int".into(),
        Scalar::Bool => "bool".into(),
        Scalar::Fixed(fx) => format!("fixed<{},{}>", fx.bits, fx.frac),
    }
}

fn type_str(ty: &Type) -> String {
    let mut s = match ty.elem {
        Elem::Scalar(sc) => scalar_str(sc),
        Elem::Interp => "interpolation_data".into(),
    };
    if ty.per_seq {
        s.push_str("[]");
    }
    for d in &ty.dims {
        write!(s, "[{d}]").expect("writing to a String");
    }
    s
}

fn const_str(c: ConstValue, s: Option<Scalar>) -> String {
    match c {
        ConstValue::Float(v) => format!("{v:?}"),
        ConstValue::Int(v) => v.to_string(),
        ConstValue::Bool(b) => b.to_string(),
        ConstValue::Fixed(raw) => match s {
            Some(Scalar::Fixed(fx)) => {
                let raw = if fx.is_unsigned() {
                    raw as u32 as f64
                } else {
                    raw as f64
                };
                format!("{:?}:fixed<{},{}>", raw / fx.scale(), fx.bits, fx.frac)
            }
            _ => format!("{raw}:fixed"),
        },
    }
}

fn space_str(s: Space) -> &'static str {
    match s {
        Space::Object => "object",
        Space::World => "world",
        Space::Lighting => "lighting",
        Space::Device => "device",
    }
}

struct Printer<'f> {
    func: &'f Function,
    /// The program `func` belongs to, when known: primitive calls print the callee's name.
    program: Option<&'f Program>,
}

impl Printer<'_> {
    fn block(&self, out: &mut String, stmts: &[StmtId], depth: usize) -> fmt::Result {
        for &s in stmts {
            self.stmt(out, s, depth)?;
        }
        Ok(())
    }

    fn stmt(&self, out: &mut String, s: StmtId, depth: usize) -> fmt::Result {
        let pad = "  ".repeat(depth);
        match &self.func.stmts[s] {
            StmtKind::Assign { place, value } => {
                write!(out, "{pad}{}", self.local_name(place.local))?;
                for (i, _) in &place.indices {
                    write!(out, "[{}]", self.expr(*i))?;
                }
                writeln!(out, " = {}", self.expr(*value))
            }
            StmtKind::If { cond, then, otherwise } => {
                let v = if self.func.exprs[*cond].var.is_varying() {
                    "varying "
                } else {
                    ""
                };
                writeln!(out, "{pad}if {v}{} {{", self.expr(*cond))?;
                self.block(out, then, depth + 1)?;
                if !otherwise.is_empty() {
                    writeln!(out, "{pad}}} else {{")?;
                    self.block(out, otherwise, depth + 1)?;
                }
                writeln!(out, "{pad}}}")
            }
            StmtKind::Loop {
                id,
                cond,
                body,
                step,
                varying,
                ..
            } => {
                let v = if *varying { " varying" } else { "" };
                match cond {
                    Some(c) => writeln!(out, "{pad}loop#{}{v} while {} {{", id.0, self.expr(*c))?,
                    None => writeln!(out, "{pad}loop#{}{v} {{", id.0)?,
                }
                self.block(out, body, depth + 1)?;
                if !step.is_empty() {
                    writeln!(out, "{pad}}} step {{")?;
                    self.block(out, step, depth + 1)?;
                }
                writeln!(out, "{pad}}}")
            }
            StmtKind::Break(l) => writeln!(out, "{pad}break #{}", l.0),
            StmtKind::Continue(l) => writeln!(out, "{pad}continue #{}", l.0),
            StmtKind::Return => writeln!(out, "{pad}return"),
            StmtKind::Interpolation { arms } => {
                writeln!(out, "{pad}interpolation {{")?;
                for a in arms {
                    match &a.kind {
                        ArmKind::Named(k) => writeln!(out, "{pad}  {k}:")?,
                        ArmKind::Default => writeln!(out, "{pad}  default:")?,
                    }
                    self.block(out, &a.body, depth + 2)?;
                }
                writeln!(out, "{pad}}}")
            }
            StmtKind::InterpolatorReturn(Some(e)) => writeln!(out, "{pad}interpolator_return({})", self.expr(*e)),
            StmtKind::InterpolatorReturn(None) => writeln!(out, "{pad}interpolator_return"),
            StmtKind::Bound(args) => {
                let a: Vec<String> = args.iter().map(|e| self.expr(*e)).collect();
                writeln!(out, "{pad}bound({})", a.join(", "))
            }
            StmtKind::CallPrimitive { callee, args, site } => {
                let a: Vec<String> = args.iter().map(|e| self.expr(*e)).collect();
                let name = self
                    .program
                    .and_then(|p| p.functions.get(callee.0 as usize))
                    .map_or("primitive", |c| c.name.as_str());
                writeln!(out, "{pad}call {name}#{}({}) @site{}", callee.0, a.join(", "), site.0)
            }
        }
    }

    fn local_name(&self, l: super::LocalId) -> String {
        match self.func.locals.get(l.0 as usize) {
            Some(loc) => format!("{}%{}", loc.name, l.0),
            None => format!("?%{}", l.0),
        }
    }

    fn expr(&self, id: ExprId) -> String {
        let e = &self.func.exprs[id];
        match &e.kind {
            ExprKind::Const(c) => const_str(*c, scalar(&e.ty)),
            ExprKind::Local(l) => self.local_name(*l),
            ExprKind::Index { base, index, .. } => format!("{}[{}]", self.expr(*base), self.expr(*index)),
            ExprKind::Unary { op, expr } => format!("{}{}", op.symbol(), self.expr(*expr)),
            ExprKind::Binary { op, lhs, rhs } => {
                format!("({} {} {})", self.expr(*lhs), op.symbol(), self.expr(*rhs))
            }
            ExprKind::Convert(x) => {
                let to = match e.ty.elem {
                    Elem::Scalar(s) => scalar_str(s),
                    Elem::Interp => "interp".into(),
                };
                format!("{to}({})", self.expr(*x))
            }
            ExprKind::Select { cond, then, otherwise } => {
                format!(
                    "({} ? {} : {})",
                    self.expr(*cond),
                    self.expr(*then),
                    self.expr(*otherwise)
                )
            }
            ExprKind::Builtin { func, args } => {
                let a: Vec<String> = args.iter().map(|x| self.expr(*x)).collect();
                let name = match func {
                    Builtin::TransformPoint { from, to } => {
                        format!("transform[{}->{}]", space_str(*from), space_str(*to))
                    }
                    Builtin::TransformVector { from, to } => {
                        format!("vtransform[{}->{}]", space_str(*from), space_str(*to))
                    }
                    Builtin::TransformNormal { from, to } => {
                        format!("ntransform[{}->{}]", space_str(*from), space_str(*to))
                    }
                    other => format!("{other:?}").to_lowercase(),
                };
                format!("{name}({})", a.join(", "))
            }
            ExprKind::List(items) => {
                let a: Vec<String> = items.iter().map(|x| self.expr(*x)).collect();
                format!("{{{}}}", a.join(", "))
            }
            ExprKind::Splat(x) => format!("splat{:?}({})", e.ty.dims, self.expr(*x)),
            ExprKind::MatMul { lhs, rhs } => format!("matmul({}, {})", self.expr(*lhs), self.expr(*rhs)),
            ExprKind::SeqCount => "seq_count".into(),
            ExprKind::ClipFlag => "clipping()".into(),
        }
    }
}
