//! The built-in math functions: name lookup, arity and argument types.
//!
//! Every argument is converted to float (ints and fixed values included). Component-wise
//! built-ins take scalars or aggregates of one shape; a scalar argument next to an
//! aggregate one is expanded to an explicit list, so in the IR all arguments of a
//! component-wise built-in have the same shape. `transform`, `len` and the space names are
//! handled by the lowering itself (they need the AST or parameter roles).

use crate::diag::Span;
use crate::ir::noise::noise_dims;
use crate::ir::tree::{Tree, TreeKind};
use crate::ir::{Builtin, Elem, Scalar, Type, Variability};

use super::types::{self, convert, type_name};

type BuiltinError = (Span, String, String);

/// Lower a call of built-in `name`; `Ok(None)` if there is no such built-in.
pub fn lower(name: &str, args: Vec<Tree>, span: Span) -> Result<Option<Tree>, BuiltinError> {
    use Builtin::*;
    let (func, arity): (Builtin, &[usize]) = match name {
        "sqrt" => (Sqrt, &[1]),
        "abs" => (Abs, &[1]),
        "floor" => (Floor, &[1]),
        "ceil" => (Ceil, &[1]),
        "round" => (Round, &[1]),
        "sin" => (Sin, &[1]),
        "cos" => (Cos, &[1]),
        "tan" => (Tan, &[1]),
        "asin" => (Asin, &[1]),
        "acos" => (Acos, &[1]),
        "atan" => (if args.len() == 2 { Atan2 } else { Atan }, &[1, 2]),
        "exp" => (Exp, &[1]),
        "log" => (Log, &[1]),
        "sign" => (Sign, &[1]),
        "pow" => (Pow, &[2]),
        "min" => (Min, &[2]),
        "max" => (Max, &[2]),
        "step" => (Step, &[2]),
        "clamp" => (Clamp, &[3]),
        "mix" => (Mix, &[3]),
        "smoothstep" => (Smoothstep, &[3]),
        "dot" => (Dot, &[2]),
        "cross" => (Cross, &[2]),
        "length" => (Length, &[1]),
        "normalize" => (Normalize, &[1]),
        "distance" => (Distance, &[2]),
        "faceforward" => (Faceforward, &[2, 3]),
        "reflect" => (Reflect, &[2]),
        "refract" => (Refract, &[3]),
        "noise" => (Noise, &[1, 2]),
        "cellnoise" => (CellNoise, &[1, 2]),
        // Only in shaders: the caller refuses them elsewhere.
        "Dx" => (Dx, &[1]),
        "Dy" => (Dy, &[1]),
        "filterwidth" => (FilterWidth, &[1]),
        // Only in linked shader groups (`crate::link`): the caller refuses it elsewhere.
        "__gbuffer" => (GBuffer, &[3]),
        _ => return Ok(None),
    };
    if !arity.contains(&args.len()) {
        let want = arity.iter().map(|n| n.to_string()).collect::<Vec<_>>().join(" or ");
        return Err((
            span,
            format!("`{name}` takes {want} arguments, found {}", args.len()),
            "wrong number of arguments".into(),
        ));
    }
    let mut floats = vec![];
    for a in args {
        let number = matches!(a.ty.elem, Elem::Scalar(s) if types::is_number(s)) && !a.ty.per_seq;
        if !number {
            return Err((
                a.span,
                format!("`{name}` takes numbers, found {}", type_name(&a.ty)),
                "not a number or an array of numbers".into(),
            ));
        }
        floats.push(convert(a, Scalar::Float));
    }
    let float = |dims: Vec<u32>| Type::array(Elem::Scalar(Scalar::Float), dims);
    let ty = match func {
        Dot | Distance => {
            let d = &floats[0].ty.dims;
            if d.len() != 1 || floats[1].ty.dims != *d {
                return Err(shape_error(name, &floats, span, "two vectors of the same length"));
            }
            Type::float()
        }
        Cross => {
            if floats[0].ty.dims != [3] || floats[1].ty.dims != [3] {
                return Err(shape_error(name, &floats, span, "two float[3] vectors"));
            }
            float(vec![3])
        }
        Faceforward | Reflect => {
            if floats.iter().any(|a| a.ty.dims != [3]) {
                return Err(shape_error(name, &floats, span, "float[3] vectors"));
            }
            float(vec![3])
        }
        Refract => {
            if floats[0].ty.dims != [3] || floats[1].ty.dims != [3] || !floats[2].ty.dims.is_empty() {
                return Err(shape_error(name, &floats, span, "two float[3] vectors and a float"));
            }
            float(vec![3])
        }
        Noise | CellNoise => {
            let shapes: Vec<&[u32]> = floats.iter().map(|a| a.ty.dims.as_slice()).collect();
            if noise_dims(&shapes).is_none() {
                return Err(shape_error(
                    name,
                    &floats,
                    span,
                    "(float), (float, float), (point) or (point, float)",
                ));
            }
            Type::float()
        }
        GBuffer => {
            if floats.iter().any(|a| !a.ty.dims.is_empty()) {
                return Err(shape_error(name, &floats, span, "(plane, X, Y)"));
            }
            Type::float()
        }
        Length | Normalize => {
            if floats[0].ty.dims.len() != 1 {
                return Err(shape_error(name, &floats, span, "a vector (1-D array)"));
            }
            if func == Length {
                Type::float()
            } else {
                floats[0].ty.clone()
            }
        }
        _ => {
            // Component-wise: one common shape, scalars expanded.
            let shape = floats
                .iter()
                .find(|a| !a.ty.dims.is_empty())
                .map(|a| a.ty.dims.clone())
                .unwrap_or_default();
            if floats.iter().any(|a| !a.ty.dims.is_empty() && a.ty.dims != shape) {
                return Err(shape_error(name, &floats, span, "arguments of one shape (or scalars)"));
            }
            floats = floats
                .into_iter()
                .map(|a| if a.ty.dims.is_empty() { expand(a, &shape) } else { a })
                .collect();
            float(shape)
        }
    };
    Ok(Some(Tree::new(
        TreeKind::Builtin { func, args: floats },
        ty,
        Variability::Uniform,
        span,
    )))
}

fn shape_error(name: &str, args: &[Tree], span: Span, want: &str) -> BuiltinError {
    let found = args.iter().map(|a| type_name(&a.ty)).collect::<Vec<_>>().join(", ");
    (
        span,
        format!("`{name}` takes {want}, found {found}"),
        "argument shapes do not fit".into(),
    )
}

/// A float scalar repeated over an array of `dims` (see [`TreeKind::Splat`]).
fn expand(v: Tree, dims: &[u32]) -> Tree {
    if dims.is_empty() {
        return v;
    }
    let span = v.span;
    Tree::new(
        TreeKind::Splat(Box::new(v)),
        Type::array(Elem::Scalar(Scalar::Float), dims.to_vec()),
        Variability::Uniform,
        span,
    )
}
