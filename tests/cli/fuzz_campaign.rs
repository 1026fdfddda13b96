//! `primflow fuzz`: the CI smoke of the campaign (a few hundred inputs of every class end
//! with no finding), and the campaign's own check that it sees what it claims to see: an
//! injected panic, abort and hang each become one finding at the right input, and the
//! inputs after them still run.

use std::process::Command;

const EXE: &str = env!("CARGO_BIN_EXE_primflow");

/// The count in `class`'s row, column `kind`, of the report `out`.
fn count(out: &str, class: &str, kind: &str) -> u64 {
    let mut lines = out.lines();
    let header: Vec<&str> = lines.next().expect("header").split_whitespace().collect();
    let col = header.iter().position(|h| *h == kind).expect("column");
    let row = out
        .lines()
        .find(|l| l.split_whitespace().next() == Some(class))
        .expect("row");
    row.split_whitespace().nth(col).expect("cell").parse().expect("count")
}

#[test]
fn a_mixed_campaign_ends_without_findings_and_reaches_every_class() {
    let out = Command::new(EXE)
        .args(["fuzz", "--inputs", "1500", "--seed", "7", "--jobs", "2"])
        .output()
        .expect("runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        text.contains("1500 inputs (seed 7)") && text.contains(": 0 findings"),
        "{text}"
    );
    for class in ["source", "deep", "prim", "scene", "valid"] {
        assert!(count(&text, class, "accepted") > 0, "{class}: {text}");
    }
    // Every input ran once: accepted + rejected over the classes is the input count.
    let total: u64 = ["source", "deep", "prim", "scene", "valid"]
        .iter()
        .map(|c| count(&text, c, "accepted") + count(&text, c, "rejected"))
        .sum();
    assert_eq!(total, 1500, "{text}");
    assert!(count(&text, "source", "rejected") > 400, "{text}");
    // Generated valid programs are meant to check: nearly all do.
    assert!(count(&text, "valid", "accepted") >= 135, "{text}");
}

#[test]
fn an_injected_panic_abort_and_hang_are_each_one_finding() {
    let out = Command::new(EXE)
        .args([
            "fuzz",
            "--inputs",
            "12",
            "--class",
            "source",
            "--jobs",
            "1",
            "--timeout",
            "2",
        ])
        .env("PRIMFLOW_FUZZ_INJECT", "panic:3,abort:5,hang:7")
        .output()
        .expect("runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains(": 3 findings"), "{text}");
    assert_eq!(count(&text, "source", "panic"), 1, "{text}");
    assert_eq!(count(&text, "source", "signal"), 1, "{text}");
    assert_eq!(count(&text, "source", "hang"), 1, "{text}");
    assert_eq!(
        count(&text, "source", "accepted") + count(&text, "source", "rejected"),
        9,
        "{text}"
    );
    for (i, kind) in [(3, "panic"), (5, "signal"), (7, "hang")] {
        assert!(text.contains(&format!("finding: input {i} (source) {kind}")), "{text}");
        assert!(
            text.contains(&format!(
                "replay: primflow fuzz --seed 1 --start {i} --inputs 1 --class source"
            )),
            "{text}"
        );
    }
}
