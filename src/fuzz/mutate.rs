//! Mutators over source text: primitives and scenes from the library, the tests and the
//! corpus, changed the ways that reach what hand-written tests rarely do.
//!
//! - [`literals`]: number literals replaced by array-edge, huge, tiny and signed values,
//!   comparison and arithmetic operators swapped. The text stays well formed, so most
//!   mutants check and reach the JIT: huge and negative array sizes and indices, loops that
//!   never end or never run, NaN and infinite coordinates.
//! - [`splice`]: spans of characters replaced by tokens of the language (or of a scene), so
//!   the parser and the checker see malformed and half-formed programs.
//!
//! Both are pure functions of their arguments: the same input and edits give the same text.

/// Replacements for an int literal.
pub const INTS: &[&str] = &[
    "0",
    "1",
    "-1",
    "2",
    "3",
    "4",
    "15",
    "16",
    "17",
    "127",
    "128",
    "129",
    "1279",
    "1280",
    "65536",
    "2147483647",
];
/// Replacements for a float literal.
pub const FLOATS: &[&str] = &["0.0", "-0.0", "1e-30", "1e30", "3.4e38", "-1.0", "0.5", "1.0e-45"];
/// Operator swaps: (found, replacement).
pub const SWAPS: &[(&str, &str)] = &[
    ("+", "-"),
    ("-", "+"),
    ("*", "/"),
    ("/", "*"),
    ("<", "<="),
    ("<=", "<"),
    (">", ">="),
    (">=", ">"),
    ("&&", "||"),
    ("||", "&&"),
    ("==", "!="),
];

/// Tokens [`splice`] inserts into primitive sources.
pub const PRIM_TOKENS: &[&str] = &[
    "X",
    "Y",
    "Z",
    "uniform ",
    "varying ",
    "inout ",
    "return;",
    "break;",
    "continue;",
    "{",
    "}",
    "(",
    ")",
    "[",
    "]",
    "[]",
    "0",
    "1.5",
    "-",
    "*",
    "/",
    "%",
    "==",
    "&&",
    "!",
    "?",
    ":",
    ";",
    ",",
    "=",
    "+=",
    "int ",
    "float ",
    "fixed<32,16> ",
    "fixed<0,40> ",
    "point ",
    "matrix ",
    "interpolation_data ",
    "interpolator_return(X);",
    "interpolator_return;",
    "interpolation { linear: default: }",
    "bound(X, Y, 1, 2);",
    "len(",
    "transform(",
    "\"world\"",
    "screen_triangle(",
    "polygon(",
    "sqrt(",
    "atan(",
    "PI",
    "true",
    "while (X > 0) ",
    "if (Y) ",
    "for (;;) ",
    "float h(float v) { return h(v); }",
    ".x",
    ".w",
    ".rgb",
    ".xyzw",
    ".xr",
    "noise(",
    "cellnoise(",
    "reflect(",
    "refract(",
    "faceforward(",
];

/// Tokens [`splice`] inserts into scenes.
pub const SCENE_TOKENS: &[&str] = &[
    "\n",
    " ",
    "0",
    "-1",
    "1e30",
    "-1e30",
    "nan",
    "inf",
    "1e-30",
    "65536",
    "\"",
    "#",
    "image ",
    "tile ",
    "camera ",
    "perspective ",
    "look_at ",
    "triangle ",
    "polygon ",
    "sphere ",
    "push\n",
    "pop\n",
    "translate ",
    "scale 0 0 0\n",
    "rotate ",
    "light ",
    "fog ",
    "surface front ",
    "param ",
    "prims ",
    "color ",
];

/// What a mutable token of [`literals`] is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    Int,
    Float,
    Operator,
}

/// The number literals and operators of `src` outside `//` and `#` comments: (start, end,
/// kind).
pub fn tokens(src: &str) -> Vec<(usize, usize, Kind)> {
    let b = src.as_bytes();
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut out = vec![];
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") || b[i] == b'#' {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i].is_ascii_digit() && (i == 0 || !ident(b[i - 1])) {
            let start = i;
            while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.' || b[i] == b'e') {
                i += 1;
            }
            let float = src[start..i].contains(['.', 'e']);
            out.push((start, i, if float { Kind::Float } else { Kind::Int }));
        } else if let Some((op, _)) = SWAPS
            .iter()
            .filter(|(op, _)| b[i..].starts_with(op.as_bytes()))
            .max_by_key(|(op, _)| op.len())
        {
            // Not part of a longer operator (`+=`, `->`, `<<`).
            let end = i + op.len();
            let next = b.get(end).copied().unwrap_or(b' ');
            if !b"=<>&|".contains(&next) {
                out.push((i, end, Kind::Operator));
            }
            i = end;
        } else {
            i += 1;
        }
    }
    out
}

/// `src` with the tokens picked by `edits` (token index, replacement index; both taken
/// modulo their ranges) replaced; `src` itself when it has no such token.
pub fn literals(src: &str, edits: &[(usize, usize)]) -> String {
    let toks = tokens(src);
    if toks.is_empty() {
        return src.to_string();
    }
    let mut picked: Vec<(usize, usize, String)> = edits
        .iter()
        .map(|&(t, r)| {
            let (start, end, kind) = toks[t % toks.len()];
            let new = match kind {
                Kind::Int => INTS[r % INTS.len()].to_string(),
                Kind::Float => FLOATS[r % FLOATS.len()].to_string(),
                Kind::Operator => {
                    let old = &src[start..end];
                    SWAPS
                        .iter()
                        .find(|(a, _)| *a == old)
                        .map_or(old, |(_, b)| b)
                        .to_string()
                }
            };
            (start, end, new)
        })
        .collect();
    picked.sort_by_key(|p| std::cmp::Reverse(p.0));
    picked.dedup_by_key(|p| p.0);
    let mut out = src.to_string();
    for (start, end, new) in picked {
        out.replace_range(start..end, &new);
    }
    out
}

/// `text` with, per edit (position, characters removed, token), up to 11 characters at the
/// position replaced by the token (positions and tokens taken modulo their ranges).
pub fn splice(text: &str, tokens: &[&str], edits: &[(usize, usize, usize)]) -> String {
    let mut s: Vec<char> = text.chars().collect();
    for &(at, del, tok) in edits {
        let at = at % (s.len() + 1);
        let end = (at + del % 12).min(s.len());
        let insert: Vec<char> = tokens[tok % tokens.len()].chars().collect();
        s.splice(at..end, insert);
    }
    s.into_iter().collect()
}
