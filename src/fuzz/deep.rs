//! Deep and huge programs: the shapes that once overflowed a stack, exploded a compile or
//! went quadratic, at sizes on both sides of the documented limits (docs/language.md,
//! "Limits").
//!
//! Each shape wraps its body in a primitive that checks when the body does, so a shape
//! under the limits reaches the JIT; past them the answer must be a located error.

use crate::workload::Lcg;

/// Shapes [`source`] draws from.
const SHAPES: usize = 11;

/// A deep or huge program drawn by `rng`: its shape and a size between 1 and ~20,000.
pub fn source(rng: &mut Lcg) -> String {
    let shape = (rng.next() * SHAPES as f64) as usize % SHAPES;
    // Log-uniform sizes: most small, some near and past the limits.
    let n = (2f64.powf(rng.range(0.0, 14.3))) as usize;
    let prim =
        |body: &str| format!("primitive deep(float a, b; varying float X, Y; inout varying float Z)\n{{\n{body}\n}}\n");
    match shape {
        // A long sum and a long product of X.
        0 => prim(&format!("    Z = {};", vec!["a"; n.max(1)].join(" + "))),
        1 => prim(&format!("    Z = {};", vec!["X"; n.max(1)].join(" * "))),
        // Nested parentheses, casts and calls.
        2 => prim(&format!("    Z = {}X{};", "(".repeat(n), ")".repeat(n))),
        3 => prim(&format!("    Z = {}X{};", "float(".repeat(n), ")".repeat(n))),
        4 => prim(&format!("    Z = {}X{};", "abs(".repeat(n), ")".repeat(n))),
        // Nested blocks and ifs.
        5 => prim(&format!("    {}Z = X;{}", "{ ".repeat(n), " }".repeat(n))),
        6 => prim(&format!("    {}Z = X;", "if (X > a) ".repeat(n))),
        // A chain of helpers calling each other.
        7 => {
            let mut s = String::from("float h0(float v) { return v + 1; }\n");
            for k in 1..=n {
                s.push_str(&format!("float h{k}(float v) {{ return h{}(v) * 0.5; }}\n", k - 1));
            }
            s + &prim(&format!("    Z = h{n}(X);"))
        }
        // A diagnostic far along one line, and many identical errors.
        8 => format!("{}@\n", " ".repeat(n * 8)),
        9 => prim(&"    Z = undefined_name;\n".repeat(n)),
        // A long name.
        _ => {
            let name = "v".repeat(n.min(40_000));
            prim(&format!("    float {name} = X;\n    Z = {name} * a;"))
        }
    }
}
