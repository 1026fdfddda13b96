//! A generator of valid primitive programs, for the differential tests and `primflow fuzz`.
//!
//! [`program_source`] writes, from a seed, a program of two helpers, a callee primitive and
//! primitive `gen`: float, int and fixed-point locals, a local array indexed by computed ints
//! (some out of range), uniform and varying `if`s, counted and open `while` and `for` loops
//! with `break` and `continue` (some endless: fuel), early `return`s, helper calls (one with
//! a loop and an early `return`), a primitive call in the setup, Z assigned on some paths,
//! interpolation arms, component access and `noise`/`cellnoise`. The same seed always
//! gives the same text. Nearly every program checks (a few trip a rule the generator does
//! not model); none is meant to be rejected.

use crate::workload::Lcg;

/// Writes one primitive's source.
struct Gen {
    rng: Lcg,
    out: String,
    indent: usize,
    /// Loop counters in scope (readable ints).
    counters: Vec<String>,
    next_counter: usize,
    loop_depth: usize,
}

const FLOATS: &[&str] = &["f0", "f1", "f2", "p0", "p1", "X", "Y", "Z"];
const INTS: &[&str] = &["i0", "i1", "n0", "n1"];
const FCONSTS: &[&str] = &["0.5", "-1.25", "3.0", "0.001", "16.0", "0.0", "-0.0", "2.5"];

impl Gen {
    fn pick(&mut self, n: usize) -> usize {
        (self.rng.next() * n as f64) as usize % n.max(1)
    }

    fn chance(&mut self, p: f64) -> bool {
        self.rng.next() < p
    }

    fn fexpr(&mut self, d: u32) -> String {
        if d == 0 || self.chance(0.3) {
            return match self.pick(6) {
                0 => FCONSTS[self.pick(FCONSTS.len())].to_string(),
                1 => format!("la[{}]", self.index(d.saturating_sub(1))),
                2 => format!("fa[{}]", self.index(d.saturating_sub(1))),
                3 => format!("float({})", ["i0", "n1", "fx0", "fx1"][self.pick(4)]),
                4 if self.chance(0.3) => format!("la.{}", ["x", "y", "z", "w"][self.pick(4)]),
                _ => FLOATS[self.pick(FLOATS.len())].to_string(),
            };
        }
        let d = d - 1;
        match self.pick(14) {
            0 => format!("({} + {})", self.fexpr(d), self.fexpr(d)),
            1 => format!("({} - {})", self.fexpr(d), self.fexpr(d)),
            2 => format!("({} * {})", self.fexpr(d), self.fexpr(d)),
            3 => format!("({} / {})", self.fexpr(d), self.fexpr(d)),
            4 => format!("({} % {})", self.fexpr(d), self.fexpr(d)),
            5 => format!("sqrt(abs({}))", self.fexpr(d)),
            6 => format!(
                "{}({}, {})",
                ["min", "max", "step", "pow"][self.pick(4)],
                self.fexpr(d),
                self.fexpr(d)
            ),
            7 => format!(
                "{}({})",
                ["floor", "sin", "round", "sign", "exp"][self.pick(5)],
                self.fexpr(d)
            ),
            8 => format!("clamp({}, {}, {})", self.fexpr(d), self.fexpr(d), self.fexpr(d)),
            9 => format!("({} ? {} : {})", self.bexpr(d), self.fexpr(d), self.fexpr(d)),
            10 => format!("scale({}, {})", self.fexpr(d), self.fexpr(d)),
            11 => format!("climb({}, {})", self.fexpr(d), self.iexpr(d)),
            12 if self.chance(0.5) => format!("(fx0 * {})", self.fexpr(d)),
            12 => format!(
                "{}({}, {})",
                ["noise", "cellnoise"][self.pick(2)],
                self.fexpr(d),
                self.fexpr(d)
            ),
            _ => format!("-({})", self.fexpr(d)),
        }
    }

    fn iexpr(&mut self, d: u32) -> String {
        if d == 0 || self.chance(0.35) {
            let n = self.counters.len();
            return match self.pick(4) {
                0 => ["-1", "0", "1", "2", "3", "5"][self.pick(6)].to_string(),
                1 if n > 0 => {
                    let k = self.pick(n);
                    self.counters[k].clone()
                }
                _ => INTS[self.pick(INTS.len())].to_string(),
            };
        }
        let d = d - 1;
        match self.pick(8) {
            0 => format!("({} + {})", self.iexpr(d), self.iexpr(d)),
            1 => format!("({} - {})", self.iexpr(d), self.iexpr(d)),
            2 => format!("({} * {})", self.iexpr(d), self.iexpr(d)),
            3 => format!("({} / {})", self.iexpr(d), self.iexpr(d)),
            4 => format!("({} % {})", self.iexpr(d), self.iexpr(d)),
            5 => format!("int({})", self.fexpr(d)),
            6 => format!("ia[{}]", self.index(d)),
            _ => format!(
                "({} < {} ? {} : {})",
                self.iexpr(d),
                self.iexpr(d),
                self.iexpr(d),
                self.iexpr(d)
            ),
        }
    }

    /// An index: never a constant of the checker's (a constant out of range is E0207).
    fn index(&mut self, d: u32) -> String {
        format!("n0 * 0 + {}", self.iexpr(d))
    }

    fn bexpr(&mut self, d: u32) -> String {
        let d = d.saturating_sub(1);
        match self.pick(6) {
            0 => format!("{} < {}", self.fexpr(d), self.fexpr(d)),
            1 => format!("{} >= {}", self.fexpr(d), self.fexpr(d)),
            2 => format!("{} == {}", self.iexpr(d), self.iexpr(d)),
            3 => format!("({} && {})", self.bexpr(d), self.bexpr(d)),
            4 => format!("({} || {})", self.bexpr(d), self.bexpr(d)),
            _ => format!("!({} < {})", self.iexpr(d), self.iexpr(d)),
        }
    }

    fn line(&mut self, text: &str) {
        self.out.push_str(&"    ".repeat(self.indent));
        self.out.push_str(text);
        self.out.push('\n');
    }

    fn block(&mut self, n: usize, d: u32) {
        self.indent += 1;
        for _ in 0..n {
            self.stmt(d);
        }
        self.indent -= 1;
    }

    fn stmt(&mut self, d: u32) {
        let k = self.pick(if d == 0 { 5 } else { 11 });
        match k {
            0 => {
                let s = format!("f{} = {};", self.pick(3), self.fexpr(3));
                self.line(&s)
            }
            1 => {
                let s = format!("i{} = {};", self.pick(2), self.iexpr(3));
                self.line(&s)
            }
            2 => {
                let s = format!("la[{}] = {};", self.index(2), self.fexpr(2));
                self.line(&s)
            }
            3 => {
                let s = format!("fx{} = {};", self.pick(2), self.fexpr(2));
                self.line(&s)
            }
            4 => {
                let s = format!("Z = {};", self.fexpr(2));
                self.line(&s)
            }
            5 | 6 => {
                let s = format!("if ({}) {{", self.bexpr(2));
                self.line(&s);
                let n = 1 + self.pick(3);
                self.block(n, d - 1);
                if self.chance(0.5) {
                    self.line("} else {");
                    let n = 1 + self.pick(2);
                    self.block(n, d - 1);
                }
                self.line("}");
            }
            7 => {
                let c = format!("t{}", self.next_counter);
                self.next_counter += 1;
                let s = format!("for (int {c} = 0; {c} < {}; {c}++) {{", self.iexpr(2));
                self.line(&s);
                self.counters.push(c);
                self.loop_depth += 1;
                let n = 1 + self.pick(3);
                self.block(n, d - 1);
                self.loop_depth -= 1;
                self.counters.pop();
                self.line("}");
            }
            8 => {
                // Often endless at some pixels: a counter bounds it only sometimes.
                let s = format!("while ({}) {{", self.bexpr(2));
                self.line(&s);
                self.loop_depth += 1;
                let n = 1 + self.pick(3);
                self.block(n, d - 1);
                if self.chance(0.7) {
                    self.line("    i1 = i1 + 1;");
                    self.line("    if (i1 > 40) break;");
                }
                self.loop_depth -= 1;
                self.line("}");
            }
            9 if self.loop_depth > 0 => {
                let s = format!("if ({}) {};", self.bexpr(2), ["break", "continue"][self.pick(2)]);
                self.line(&s)
            }
            _ => {
                let s = format!("if ({}) return;", self.bexpr(2));
                self.line(&s)
            }
        }
    }
}

/// The source of program `seed`: helpers, a callee and primitive `gen`.
pub fn program_source(seed: u64) -> String {
    let mut g = Gen {
        rng: Lcg(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0xdead_beef),
        out: String::new(),
        indent: 1,
        counters: vec![],
        next_counter: 0,
        loop_depth: 0,
    };
    let z = if g.chance(0.5) { "float" } else { "fixed<32,32>" };
    let mut head = format!(
        "float scale(float a, b) {{ return a * b + 1; }}\n\
         float climb(float a; int n)\n{{\n    float v = a;\n    for (int k = 0; k < n; k++) {{\n        \
         if (v > 10) return v;\n        v = v * 1.5 + 1;\n    }}\n    return v;\n}}\n\
         primitive callee(float q0, q1; varying float X, Y; inout varying {z} Z)\n{{\n    \
         bound(q0, q1, q0 + 10, q1 + 8);\n    if (X > q0 + 5) return;\n    Z = q1 / 40;\n}}\n\
         primitive gen(float p0, p1, p2, p3; int n0, n1; float fa[5]; int ia[3];\n              \
         varying float X, Y; inout varying {z} Z)\n{{\n"
    );
    if g.chance(0.7) {
        head.push_str("    bound(p0 - 4, p1 - 4, p0 + p2 + 30, p1 + p3 + 20);\n");
    }
    if g.chance(0.3) {
        head.push_str("    callee(p2, p3, X, Y, Z);\n");
    }
    g.out = head;
    g.line("float la[4] = {0.25, 0.5, 0.75, 1.0};");
    g.line("int i0 = n0 + 1, i1 = 0;");
    g.line("fixed<16,8> fx0 = p2, fx1 = 0.5;");
    g.line("float f0 = 0, f1 = 0, f2 = 0;");
    for k in 0..3 {
        let s = format!("f{k} = {};", g.fexpr(2));
        g.line(&s);
    }
    let n = 3 + g.pick(5);
    for _ in 0..n {
        g.stmt(3);
    }
    let s = format!("Z = {};", g.fexpr(2));
    g.line(&s);
    if g.chance(0.6) {
        g.line("interpolation {");
        g.line("    linear:");
        let s = format!("        interpolator_return({});", g.fexpr(2));
        g.line(&s);
        g.line("    default:");
        g.line("        interpolator_return;");
        g.line("}");
    }
    g.out.push_str("}\n");
    g.out
}
