//! The operators of the language, one enum each for the AST and the IR: the parser builds
//! them from the source's symbols, the checker types them and keeps them in the IR as they
//! are, the back end lowers them. There is no conversion between an AST and an IR operator
//! (`syntax::ast` and `ir` re-export these).

/// Unary operators: `-` (numbers, component-wise) and `!` (`Bool`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnaryOp {
    Neg,
    Not,
}

impl UnaryOp {
    /// The operator as written in the source (the printers of the AST and the IR use it).
    pub fn symbol(self) -> &'static str {
        match self {
            UnaryOp::Neg => "-",
            UnaryOp::Not => "!",
        }
    }
}

/// Component-wise binary operators. Comparisons give `Bool` of the operands' shape;
/// `And`/`Or` take and give `Bool` (both sides are always evaluated: expressions are pure).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BinOp {
    Add,
    Sub,
    Mul,
    Div,
    Rem,
    Lt,
    Le,
    Gt,
    Ge,
    Eq,
    Ne,
    And,
    Or,
}

impl BinOp {
    /// The operator as written in the source (the printers of the AST and the IR use it).
    pub fn symbol(self) -> &'static str {
        match self {
            BinOp::Add => "+",
            BinOp::Sub => "-",
            BinOp::Mul => "*",
            BinOp::Div => "/",
            BinOp::Rem => "%",
            BinOp::Lt => "<",
            BinOp::Le => "<=",
            BinOp::Gt => ">",
            BinOp::Ge => ">=",
            BinOp::Eq => "==",
            BinOp::Ne => "!=",
            BinOp::And => "&&",
            BinOp::Or => "||",
        }
    }
}
