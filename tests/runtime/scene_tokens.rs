//! The scene reader's tokens and suggestions (src/scene/mod.rs): tokens carry byte spans in
//! the file, a `#` ends the line's code, and an unknown command's suggestion is by edit
//! distance.

use primflow::diag::{Diagnostics, SourceMap};
use primflow::scene::{self, edit_distance};

#[test]
fn tokens_carry_byte_spans_and_comments_end_lines() {
    // The second line starts at byte 10.
    let mut sources = SourceMap::new();
    let file = sources.add("tokens.scene", "#23456789\n  begin\tscreen_triangle # a comment");
    let parsed = scene::parse(&sources, file, &mut Diagnostics::new());
    assert_eq!(parsed.commands.len(), 1);
    let got: Vec<_> = parsed.commands[0]
        .tokens
        .iter()
        .map(|t| (t.text.as_str(), t.span.start, t.span.end))
        .collect();
    assert_eq!(got, vec![("begin", 12, 17), ("screen_triangle", 18, 33)]);
}

#[test]
fn edit_distance_suggests_close_commands() {
    assert_eq!(edit_distance("vertex", "vertx"), 1);
    assert_eq!(edit_distance("material", "materail"), 2);
}
