//! `primflow accuracy` through the command line: table, CSV, JSON and plots written; a
//! filter that matches no knob is an error, not a panic.

#[test]
fn accuracy_command_writes_table_csv_json_and_plot() {
    let dir = std::env::temp_dir().join(format!("primflow-accuracy-cli-{}", std::process::id()));
    let (mut out, mut err) = (vec![], vec![]);
    let args = [
        "primflow",
        "accuracy",
        "--quick",
        "--runs",
        "1",
        "--no-progress",
        "--scene",
        "depth",
        "--out",
    ];
    let code = primflow::cli::run(
        args.iter().map(|s| s.to_string()).chain([dir.display().to_string()]),
        &mut out,
        &mut err,
    );
    let text = String::from_utf8_lossy(&out);
    assert_eq!(code, 0, "{}", String::from_utf8_lossy(&err));
    assert!(text.contains("fixed<16,16>") && text.contains("z-fighting"), "{text}");
    let csv = std::fs::read_to_string(dir.join("accuracy.csv")).unwrap();
    assert!(csv.starts_with("knob,setting,metric,unit,max,mean,pixels,median_ms,time_ratio\n"));
    assert_eq!(csv.lines().filter(|l| l.starts_with("depth,")).count(), 10);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("accuracy.json")).unwrap()).unwrap();
    assert_eq!(json["knobs"][0]["name"], "depth");
    let png = std::fs::read(dir.join("depth.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let _ = std::fs::remove_dir_all(&dir);

    let (mut out, mut err) = (vec![], vec![]);
    let code = primflow::cli::run(
        ["primflow", "accuracy", "--quick", "--no-progress", "--scene", "teapot"],
        &mut out,
        &mut err,
    );
    assert_eq!(code, 1);
    assert!(String::from_utf8_lossy(&err).contains("no knob matches `teapot`"));
}

#[test]
fn tick_labels_are_the_round_values_they_stand_for() {
    use primflow::accuracy::plot::tick_label;
    // A log axis computes its decade ticks with rounding error: 1e-5 comes as 9.99..e-6.
    let cases = [
        (9.999999999999999e-6, "1e-5"),
        (1e-8, "1e-8"),
        (2.5e6, "2.5e6"),
        (0.001, "0.001"),
        (0.25, "0.25"),
        (1.0, "1"),
        (300.0, "300"),
        (99999.0, "1e5"),
        (12345.0, "12300"),
        (0.000123, "1.23e-4"),
        (-0.5, "-0.5"),
        (0.0, "0"),
    ];
    for (v, label) in cases {
        assert_eq!(tick_label(v), label, "{v}");
    }
}

/// The docs' saved reference run, plotted again with `--from`: one plot per knob, the table
/// and CSV of the same rows; a file that is not a saved run is an error.
#[test]
fn a_saved_run_is_plotted_again_without_measuring() {
    let saved = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/accuracy/accuracy.json");
    let dir = std::env::temp_dir().join(format!("primflow-accuracy-from-{}", std::process::id()));
    let (mut out, mut err) = (vec![], vec![]);
    let args = ["primflow", "accuracy", "--from", saved, "--out"];
    let code = primflow::cli::run(
        args.iter().map(|s| s.to_string()).chain([dir.display().to_string()]),
        &mut out,
        &mut err,
    );
    assert_eq!(code, 0, "{}", String::from_utf8_lossy(&err));
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(saved).unwrap()).unwrap();
    let knobs = json["knobs"].as_array().unwrap();
    assert!(knobs.len() >= 6);
    for knob in knobs {
        let png = std::fs::read(dir.join(format!("{}.png", knob["name"].as_str().unwrap()))).unwrap();
        assert_eq!(&png[1..4], b"PNG");
    }
    let rows: usize = knobs.iter().map(|k| k["rows"].as_array().unwrap().len()).sum();
    let csv = std::fs::read_to_string(dir.join("accuracy.csv")).unwrap();
    assert_eq!(csv.lines().count(), rows + 1);
    let _ = std::fs::remove_dir_all(&dir);

    let (mut out, mut err) = (vec![], vec![]);
    let code = primflow::cli::run(
        [
            "primflow",
            "accuracy",
            "--from",
            concat!(env!("CARGO_MANIFEST_DIR"), "/README.md"),
        ],
        &mut out,
        &mut err,
    );
    assert_eq!(code, 1);
    assert!(String::from_utf8_lossy(&err).contains("cannot read a saved run"));
}
