//! The `# expect:` lines `primflow test` reads from a scene (src/testing/mod.rs): every kind
//! parses with its line, and a malformed line says which and why.

use std::path::Path;

use primflow::testing::{parse_expectations, Check, Expectation};

#[test]
fn parses_every_kind_with_lines() {
    let text = "image 8 8\n# expect: covered 1 2\n#expect: depth 1 2 0.5 tol=1e-3\n\
                # expect: param Cs 1 2 1 0 0\n# expect: writes-exactly 1 0 0 4 4\n# expect: diag W0701\n";
    let (e, errors) = parse_expectations(text, Path::new("."));
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(e.len(), 5);
    assert_eq!(
        e[0],
        Expectation {
            line: 2,
            check: Check::Covered { x: 1, y: 2 }
        }
    );
    assert_eq!(
        e[1].check,
        Check::Depth {
            x: 1,
            y: 2,
            value: 0.5,
            tol: 1e-3
        }
    );
    assert_eq!(e[4].line, 6);
}

#[test]
fn malformed_lines_say_which_and_why() {
    let text = "# expect: depth 1 2\n# expect: covered -1 0\n# expect: sparkle\n# expect: coverage 3 fuzz=2\n# expect: diag X1\n";
    let (e, errors) = parse_expectations(text, Path::new("."));
    assert!(e.is_empty());
    assert_eq!(errors.len(), 5);
    let lines: Vec<usize> = errors.iter().map(|(line, _)| *line).collect();
    assert_eq!(lines, [1, 2, 3, 4, 5]);
    assert!(errors[0].1.starts_with("expected `depth X Y VALUE"), "{}", errors[0].1);
    assert!(errors[1].1.contains("`-1` is not a valid pixel coordinate"));
    assert!(errors[2].1.contains("unknown expectation `sparkle`"));
    assert!(errors[3].1.contains("unknown option `fuzz=`"));
    assert!(errors[4].1.contains("not a diagnostic code"));
}
