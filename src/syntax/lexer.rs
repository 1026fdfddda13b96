//! The logos lexer. [`lex`] hands the lalrpop parser a file's `(start, Tok, end)` triples as
//! it pulls them, reporting bad characters and malformed numbers (E0001, E0002) as it goes
//! and skipping them, so the parser only ever sees valid tokens.

use logos::Logos;

use crate::diag::{Diagnostic, Diagnostics, FileId, Span};

#[derive(Logos, Clone, Debug, PartialEq)]
#[logos(skip r"[ \t\r\n\f]+")]
#[logos(skip(r"//[^\n]*", allow_greedy = true))]
#[logos(skip r"/\*([^*]|\*+[^*/])*\*+/")]
pub enum Tok {
    #[token("primitive")]
    Primitive,
    #[token("interpolator")]
    Interpolator,
    #[token("uniform")]
    Uniform,
    #[token("varying")]
    Varying,
    #[token("inout")]
    Inout,
    #[token("float")]
    Float,
    #[token("int")]
    Int,
    #[token("bool")]
    Bool,
    #[token("fixed")]
    Fixed,
    // Figure 6 writes `Point`.
    #[token("point")]
    #[token("Point")]
    Point,
    #[token("vector")]
    Vector,
    #[token("normal")]
    Normal,
    #[token("color")]
    Color,
    #[token("matrix")]
    Matrix,
    // The paper uses both spellings.
    #[token("interpolation_data")]
    #[token("interpolator_data")]
    InterpolationData,
    #[token("string")]
    String,
    #[token("void")]
    Void,
    #[token("if")]
    If,
    #[token("else")]
    Else,
    #[token("for")]
    For,
    #[token("while")]
    While,
    #[token("break")]
    Break,
    #[token("continue")]
    Continue,
    #[token("return")]
    Return,
    #[token("interpolation")]
    Interpolation,
    // The paper's prose calls it `interpolation_return` once.
    #[token("interpolator_return")]
    #[token("interpolation_return")]
    InterpolatorReturn,
    #[token("default")]
    Default,
    #[token("bound")]
    Bound,
    #[token("illuminance")]
    Illuminance,
    #[token("true")]
    True,
    #[token("false")]
    False,

    #[regex(r"[A-Za-z_][A-Za-z0-9_]*", |lex| lex.slice().to_string())]
    Ident(std::string::String),
    #[regex(r"[0-9]+", |lex| lex.slice().parse::<i64>().ok())]
    IntLit(i64),
    #[regex(r"([0-9]+\.[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?[fF]?", parse_float)]
    #[regex(r"[0-9]+[eE][+-]?[0-9]+[fF]?", parse_float)]
    #[regex(r"[0-9]+[fF]", parse_float)]
    FloatLit(f64),
    #[regex(r#""[^"\n]*""#, |lex| { let s = lex.slice(); s[1..s.len() - 1].to_string() })]
    StrLit(std::string::String),

    #[token("(")]
    LParen,
    #[token(")")]
    RParen,
    #[token("{")]
    LBrace,
    #[token("}")]
    RBrace,
    #[token("[")]
    LBracket,
    #[token("]")]
    RBracket,
    #[token(";")]
    Semi,
    #[token(",")]
    Comma,
    #[token(":")]
    Colon,
    // Component access `p.x`; `.5` and `1.` stay number literals (logos takes the longest
    // match).
    #[token(".")]
    Dot,
    #[token("?")]
    Question,
    #[token("<")]
    Lt,
    #[token(">")]
    Gt,
    #[token("<=")]
    Le,
    #[token(">=")]
    Ge,
    #[token("==")]
    EqEq,
    #[token("!=")]
    Ne,
    #[token("=")]
    Assign,
    #[token("+=")]
    PlusAssign,
    #[token("-=")]
    MinusAssign,
    #[token("*=")]
    StarAssign,
    #[token("/=")]
    SlashAssign,
    #[token("++")]
    PlusPlus,
    #[token("--")]
    MinusMinus,
    #[token("+")]
    Plus,
    #[token("-")]
    Minus,
    #[token("*")]
    Star,
    #[token("/")]
    Slash,
    #[token("%")]
    Percent,
    #[token("&&")]
    AndAnd,
    #[token("||")]
    OrOr,
    #[token("!")]
    Bang,
}

fn parse_float(lex: &mut logos::Lexer<Tok>) -> Option<f64> {
    lex.slice().trim_end_matches(['f', 'F']).parse::<f64>().ok()
}

impl std::fmt::Display for Tok {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Tok::Ident(s) => write!(f, "identifier `{s}`"),
            Tok::IntLit(i) => write!(f, "integer `{i}`"),
            Tok::FloatLit(x) => write!(f, "number `{x}`"),
            Tok::StrLit(s) => write!(f, "string \"{s}\""),
            other => write!(f, "`{}`", token_text(other)),
        }
    }
}

/// The source text of a fixed token, for messages.
pub fn token_text(t: &Tok) -> &'static str {
    use Tok::*;
    match t {
        Primitive => "primitive",
        Interpolator => "interpolator",
        Uniform => "uniform",
        Varying => "varying",
        Inout => "inout",
        Float => "float",
        Int => "int",
        Bool => "bool",
        Fixed => "fixed",
        Point => "point",
        Vector => "vector",
        Normal => "normal",
        Color => "color",
        Matrix => "matrix",
        InterpolationData => "interpolation_data",
        String => "string",
        Void => "void",
        If => "if",
        Else => "else",
        For => "for",
        While => "while",
        Break => "break",
        Continue => "continue",
        Return => "return",
        Interpolation => "interpolation",
        InterpolatorReturn => "interpolator_return",
        Default => "default",
        Bound => "bound",
        Illuminance => "illuminance",
        True => "true",
        False => "false",
        Ident(_) => "identifier",
        IntLit(_) => "integer",
        FloatLit(_) => "number",
        StrLit(_) => "string",
        LParen => "(",
        RParen => ")",
        LBrace => "{",
        RBrace => "}",
        LBracket => "[",
        RBracket => "]",
        Semi => ";",
        Comma => ",",
        Colon => ":",
        Dot => ".",
        Question => "?",
        Lt => "<",
        Gt => ">",
        Le => "<=",
        Ge => ">=",
        EqEq => "==",
        Ne => "!=",
        Assign => "=",
        PlusAssign => "+=",
        MinusAssign => "-=",
        StarAssign => "*=",
        SlashAssign => "/=",
        PlusPlus => "++",
        MinusMinus => "--",
        Plus => "+",
        Minus => "-",
        Star => "*",
        Slash => "/",
        Percent => "%",
        AndAnd => "&&",
        OrOr => "||",
        Bang => "!",
    }
}

/// Never produced: lexical errors are reported by [`lex`] and the bad text skipped.
#[derive(Clone, Debug, PartialEq)]
pub struct LexError;

/// The tokens of a file, as the parser pulls them: bad characters and numbers out of range
/// are reported to `diags` and skipped (a number out of range reads as 0). Streaming rather
/// than a token vector: the library's vectors were ~0.5 MB of fresh pages per process.
pub fn lex<'t, 'd>(file: FileId, text: &'t str, diags: &'d mut Diagnostics) -> Lexer<'t, 'd> {
    Lexer {
        file,
        text,
        inner: Tok::lexer(text),
        bad: None,
        diags,
        done: false,
    }
}

/// See [`lex`].
pub struct Lexer<'t, 'd> {
    file: FileId,
    text: &'t str,
    inner: logos::Lexer<'t, Tok>,
    /// A run of bad characters not yet reported: runs are merged into one diagnostic.
    bad: Option<(usize, usize)>,
    diags: &'d mut Diagnostics,
    done: bool,
}

impl Lexer<'_, '_> {
    /// Report the pending run of bad characters, if any.
    fn flush(&mut self) {
        if let Some((s, e)) = self.bad.take() {
            let what = &self.text[s..e];
            let d = if what.starts_with('"') {
                Diagnostic::error("E0003", "unterminated string literal")
                    .primary(Span::new(self.file, s, e), "no closing `\"` on this line")
            } else {
                Diagnostic::error(
                    "E0001",
                    format!(
                        "unexpected character{} `{}`",
                        if e - s > 1 { "s" } else { "" },
                        what.escape_debug()
                    ),
                )
                .primary(Span::new(self.file, s, e), "not part of the language")
            };
            self.diags.push(d);
        }
    }
}

impl Iterator for Lexer<'_, '_> {
    type Item = (usize, Tok, usize);

    fn next(&mut self) -> Option<(usize, Tok, usize)> {
        while !self.done {
            let Some(tok) = self.inner.next() else {
                self.done = true;
                break;
            };
            let span = self.inner.span();
            match tok {
                // A `/*` the skip rule did not consume has no `*/`: the rest is an open comment.
                Ok(Tok::Slash) if self.text[span.end..].starts_with('*') => {
                    self.flush();
                    self.diags
                        .push(Diagnostic::error("E0003", "unterminated block comment").primary(
                            Span::new(self.file, span.start, span.end + 1),
                            "this comment is never closed",
                        ));
                    self.done = true;
                }
                Ok(t) => {
                    self.flush();
                    return Some((span.start, t, span.end));
                }
                Err(()) => {
                    let slice = self.inner.slice();
                    if slice.chars().all(|c| c.is_ascii_digit())
                        || slice.contains(['.', 'e', 'E']) && slice.starts_with(|c: char| c.is_ascii_digit())
                    {
                        self.flush();
                        self.diags.push(
                            Diagnostic::error("E0002", "number literal out of range")
                                .primary(Span::new(self.file, span.start, span.end), "does not fit in 64 bits"),
                        );
                        return Some((span.start, Tok::IntLit(0), span.end));
                    }
                    match &mut self.bad {
                        Some((_, e)) if *e == span.start => *e = span.end,
                        _ => {
                            self.flush();
                            self.bad = Some((span.start, span.end));
                        }
                    }
                }
            }
        }
        self.flush();
        None
    }
}
