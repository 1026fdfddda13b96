//! The one rule for "did you mean" (`diag::did_you_mean`): a case-only difference, else
//! the nearest candidate within a third of the name's length in edits (swaps of neighbours
//! count once), ties to the alphabetically first; short names get no guesses.

use primflow::diag::did_you_mean;

fn suggest(name: &str, candidates: &[&str]) -> Option<String> {
    did_you_mean(name, candidates.iter().copied())
}

#[test]
fn close_names_are_suggested() {
    let builtins = ["length", "normalize", "len", "max", "min"];
    assert_eq!(suggest("lenght", &builtins).as_deref(), Some("did you mean `length`?"));
    assert_eq!(
        suggest("nomalize", &builtins).as_deref(),
        Some("did you mean `normalize`?")
    );
    assert_eq!(suggest("mzz", &builtins), None, "two edits are too many for 3 letters");
    assert_eq!(
        suggest("pi", &["PI"]).as_deref(),
        Some("did you mean `PI`?"),
        "case only"
    );
    assert_eq!(
        suggest("materail", &["material", "material_interp"]).as_deref(),
        Some("did you mean `material`?")
    );
}

#[test]
fn short_far_or_identical_names_get_nothing() {
    assert_eq!(suggest("a", &["b", "X"]), None, "one letter is no typo of another");
    assert_eq!(suggest("ab", &["ac"]), None);
    assert_eq!(suggest("colour", &["depth", "radius"]), None);
    assert_eq!(
        suggest("radius", &["radius"]),
        None,
        "the name itself is not a suggestion"
    );
    assert_eq!(suggest("x", &[]), None);
    let huge = "a".repeat(1 << 20);
    assert_eq!(
        suggest(&huge, &[huge.as_str(), "a"]),
        None,
        "no quadratic work on huge names"
    );
    assert_eq!(suggest("abcd", &[huge.as_str()]), None);
}

#[test]
fn ties_go_to_the_alphabetically_first() {
    assert_eq!(suggest("cat", &["cot", "bat"]).as_deref(), Some("did you mean `bat`?"));
    assert_eq!(suggest("cat", &["bat", "cot"]).as_deref(), Some("did you mean `bat`?"));
}
