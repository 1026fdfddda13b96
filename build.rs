// Generates the parser from grammar/primflow.lalrpop into OUT_DIR/primflow.rs, and the
// embedded primitive library (every prims/*.prim, sorted by name) into OUT_DIR/library.rs.
use std::fmt::Write;

fn main() {
    let out = std::env::var("OUT_DIR").expect("cargo sets OUT_DIR");
    lalrpop::Configuration::new()
        .set_in_dir("grammar")
        .set_out_dir(&out)
        .emit_rerun_directives(true)
        .process()
        .expect("grammar/primflow.lalrpop failed to generate");

    // A directory given to rerun-if-changed is scanned whole: adding, removing or editing a
    // library file rebuilds the crate with it.
    println!("cargo:rerun-if-changed=prims");
    let dir = std::path::Path::new(&std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets it")).join("prims");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .expect("prims/ is readable")
        .map(|e| {
            e.expect("prims/ entry")
                .file_name()
                .into_string()
                .expect("UTF-8 file name")
        })
        .filter(|n| n.ends_with(".prim"))
        .collect();
    names.sort();
    let mut code = String::from("pub static LIBRARY: &[(&str, &str)] = &[\n");
    for name in names {
        let path = dir.join(&name);
        writeln!(code, "    ({name:?}, include_str!({:?})),", path.display().to_string()).unwrap();
    }
    code.push_str("];\n");
    std::fs::write(std::path::Path::new(&out).join("library.rs"), code).expect("OUT_DIR is writable");
}
