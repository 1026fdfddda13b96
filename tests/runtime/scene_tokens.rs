//! The scene reader's tokens and suggestions (src/scene/mod.rs): tokens carry byte spans in
//! the file, a `#` ends the line's code, and every unknown name of a scene (command,
//! choice, primitive, parameter, shader, interpolation kind) gets a "did you mean" help
//! when a known one is close (`diag::did_you_mean`).

use crate::support;
use primflow::diag::{Diagnostics, SourceMap};
use primflow::runtime::Renderer;
use primflow::scene;

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

/// Each line's diagnostic, against the built-in library: its code and location, and its
/// help.
#[test]
fn unknown_scene_names_suggest_the_close_known_one() {
    let text = "\
imgae 8 8
cull bak
begin sphre
end
begin sphere
rast_param raduis 1
end
material_interp N implict
material_interp uv cylindrical_interpolation cylinder_strat=0
shader plastik
shader plastic roughnes=0.1
lightsource pointlight intensty=1
material_interp Cs lnear
begin zzz
end
";
    let program = support::library();
    let mut sources = SourceMap::new();
    let file = sources.add("typos.scene", text);
    let mut renderer = Renderer::new(program);
    let mut diags = Diagnostics::new();
    scene::load_into(&sources, file, &mut renderer, &mut diags);
    let got: Vec<String> = diags
        .items
        .iter()
        .zip(diags.codes_at(&sources))
        .map(|(d, at)| format!("{at} {}", d.help.as_deref().unwrap_or("-")))
        .collect();
    let want = [
        "E0601@1:1 did you mean `image`?",
        "E0604@2:6 did you mean `back`?",
        "E0701@3:7 did you mean `sphere`?",
        "E0702@6:12 did you mean `radius`?",
        "W0705@8:19 did you mean `implicit`?",
        "E0707@9:46 did you mean `cylinder_start`?",
        "E1002@10:8 did you mean `plastic`?",
        "E0702@11:16 did you mean `roughness`?",
        "E0702@12:24 did you mean `intensity`?",
        // A kind only screen_triangle's arms name.
        "W0705@13:20 did you mean `linear`?",
        // Nothing close: no help.
        "E0701@14:7 -",
    ];
    assert_eq!(got, want, "{}", diags.render(&sources));
}
