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
