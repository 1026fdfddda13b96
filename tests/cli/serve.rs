//! `primflow serve`: the built binary on a free port, driven over HTTP (the page, `/state`,
//! the images decoded, a pixel's trace, edits that break and fix a primitive, a scene deleted
//! and saved again, paths outside refused with 403), and the page in a real headless
//! Chromium: its script shows the rendered image, a new image after an edit, and the
//! diagnostic of an edit that breaks a source.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use serde_json::Value;

/// The server process, killed when the test ends (passing or not), and its directory.
struct Serve {
    child: Child,
    port: u16,
    dir: PathBuf,
    /// Its stdout and stderr lines (stderr's prefixed `err: `), for failure messages.
    lines: Receiver<String>,
}

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// A primitive filling the pixels left of `edge` at depth 0.5, and a scene drawing it red.
fn halfplane(edge: u32) -> String {
    format!(
        "primitive halfplane(varying float X, Y; inout varying fixed<32,32> Z) {{\n    if (X > {edge}) return;\n    Z = 0.5;\n    interpolator_return;\n}}\n"
    )
}
const SCENE: &str = "image 16 4\nprims my\nmaterial_interp Cs constant\nmaterial Cs 1 0 0\nbegin halfplane\nend\n";
/// `halfplane` with a syntax error at 2:9 (the `=`).
const BROKEN: &str = "primitive halfplane(varying float X, Y) {\n  float = ;\n}\n";

/// Start `primflow serve a.scene --port 0` in a new directory holding the scene and
/// `my/halfplane.prim`, and read the port it printed.
fn start(name: &str) -> Serve {
    let dir = std::env::temp_dir().join(format!("primflow-serve-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("my")).unwrap();
    std::fs::write(dir.join("my/halfplane.prim"), halfplane(4)).unwrap();
    std::fs::write(dir.join("a.scene"), SCENE).unwrap();
    let (child, lines) = crate::support::spawn_with_lines(
        Command::new(env!("CARGO_BIN_EXE_primflow"))
            .args(["serve", "a.scene", "--port", "0", "--threads", "2"])
            .current_dir(&dir)
            .env_remove("PRIMFLOW_PRIMS"),
    );
    let first = lines
        .recv_timeout(Duration::from_secs(30))
        .expect("serve printed nothing");
    let port = first
        .strip_prefix("serving http://127.0.0.1:")
        .and_then(|rest| rest.strip_suffix('/'))
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("first line {first:?} is not `serving http://127.0.0.1:PORT/`"));
    Serve {
        child,
        port,
        dir,
        lines,
    }
}

/// One HTTP/1.1 request: the status, the Content-Type and the body.
fn http(port: u16, method: &str, target: &str, body: &[u8]) -> (u16, String, Vec<u8>) {
    let mut stream = TcpStream::connect(("127.0.0.1", port)).unwrap();
    stream.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    write!(
        stream,
        "{method} {target} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\nContent-Length: {}\r\n\r\n",
        body.len()
    )
    .unwrap();
    stream.write_all(body).unwrap();
    let mut response = vec![];
    stream.read_to_end(&mut response).unwrap();
    let split = response
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("no end of headers");
    let head = String::from_utf8_lossy(&response[..split]).to_string();
    let status = head.split(' ').nth(1).and_then(|s| s.parse().ok()).expect("no status");
    let content_type = head
        .lines()
        .find_map(|l| {
            l.to_ascii_lowercase()
                .strip_prefix("content-type: ")
                .map(str::to_string)
        })
        .unwrap_or_default();
    (status, content_type, response[split + 4..].to_vec())
}

impl Serve {
    fn get(&self, target: &str) -> (u16, String, Vec<u8>) {
        http(self.port, "GET", target, b"")
    }

    fn post(&self, target: &str, body: &str) -> (u16, String) {
        let (status, _, body) = http(self.port, "POST", target, body.as_bytes());
        (status, String::from_utf8_lossy(&body).to_string())
    }

    fn state(&self) -> Value {
        let (status, content_type, body) = self.get("/state");
        assert_eq!((status, content_type.as_str()), (200, "application/json"));
        serde_json::from_slice(&body).unwrap()
    }

    /// `/state` once its generation is past `after`; panics after 30 s.
    fn next_state(&self, after: u64) -> Value {
        let deadline = Instant::now() + Duration::from_secs(30);
        while Instant::now() < deadline {
            let state = self.state();
            if state["generation"].as_u64().unwrap() > after {
                return state;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let log: Vec<String> = self.lines.try_iter().collect();
        panic!("no generation after {after} within 30 s; the server printed {log:#?}");
    }

    /// The PNG at `target`, decoded.
    fn image(&self, target: &str) -> image::DynamicImage {
        let (status, content_type, body) = self.get(target);
        assert_eq!((status, content_type.as_str()), (200, "image/png"), "{target}");
        image::load_from_memory_with_format(&body, image::ImageFormat::Png).unwrap()
    }

    fn red_pixels(&self) -> usize {
        let image = self.image("/image.png").to_rgb8();
        assert_eq!(image.dimensions(), (16, 4));
        (0..16).filter(|&x| image.get_pixel(x, 1).0 == [255, 0, 0]).count()
    }
}

#[test]
fn serve_shows_the_render_rerenders_on_edits_and_refuses_paths_outside() {
    let serve = start("http");

    let (status, content_type, page) = serve.get("/");
    assert_eq!((status, content_type.as_str()), (200, "text/html; charset=utf-8"));
    assert!(String::from_utf8(page).unwrap().contains(r#"<img id="frame""#));

    let state = serve.next_state(0);
    assert_eq!(state["status"], "ok", "{state:#}");
    let g = state["generation"].as_u64().unwrap();
    assert_eq!(state["shown"]["generation"].as_u64(), Some(g));
    assert_eq!(
        (state["shown"]["width"].as_u64(), state["shown"]["height"].as_u64()),
        (Some(16), Some(4))
    );
    assert_eq!(state["shown"]["params"][0]["name"], "Cs");
    assert_eq!(state["files"], serde_json::json!(["a.scene", "./my/halfplane.prim"]));
    for t in ["check", "compile", "render", "total"] {
        assert!(
            state["timings"][t].as_f64().is_some_and(|ms| ms >= 0.0),
            "{t}: {state:#}"
        );
    }

    // The frame: X in 0..4 red at depth 0.5 (raw 0x8000_0000, 16-bit 0x8000), the rest empty.
    assert_eq!(serve.red_pixels(), 4);
    let depth = serve.image("/depth.png").to_luma16();
    assert_eq!((depth.get_pixel(1, 1).0, depth.get_pixel(10, 1).0), ([0x8000], [0]));
    let cs = serve.image("/param.png?name=Cs").to_rgb8();
    assert_eq!((cs.get_pixel(1, 1).0, cs.get_pixel(10, 1).0), ([255, 0, 0], [0, 0, 0]));
    let (status, _, body) = serve.get("/param.png?name=Cz");
    assert_eq!(status, 404);
    assert!(String::from_utf8_lossy(&body).contains("no shading parameter `Cz`"));

    // A click's trace: `primflow trace`'s text.
    let (status, _, trace) = serve.get("/trace?x=1&y=1");
    let trace = String::from_utf8(trace).unwrap();
    assert_eq!(status, 200, "{trace}");
    assert!(trace.contains("instance 0: halfplane (scene a.scene:5:1"), "{trace}");
    assert!(trace.contains("./my/halfplane.prim:3:5  Z = 0.5;"), "{trace}");
    assert!(trace.contains("agrees with the rendered frame"), "{trace}");
    let (status, _, body) = serve.get("/trace?x=16&y=0");
    assert_eq!(status, 400);
    assert!(String::from_utf8_lossy(&body).contains("outside the 16x4 image"));

    // The editor reads a source.
    let (status, _, text) = serve.get("/file?path=.%2Fmy%2Fhalfplane.prim");
    assert_eq!((status, String::from_utf8(text).unwrap()), (200, halfplane(4)));

    // An edit that breaks the primitive: a diagnostic at its line, the last image kept.
    let (status, body) = serve.post("/file?path=my/halfplane.prim", BROKEN);
    assert_eq!((status, body.as_str()), (200, "saved my/halfplane.prim"));
    assert_eq!(
        std::fs::read_to_string(serve.dir.join("my/halfplane.prim")).unwrap(),
        BROKEN
    );
    let state = serve.next_state(g);
    assert_eq!(state["status"], "errors", "{state:#}");
    let d = &state["diagnostics"][0];
    assert_eq!(
        (&d["severity"], &d["code"], &d["location"], &d["line"], &d["col"]),
        (
            &"error".into(),
            &"E0011".into(),
            &"./my/halfplane.prim:2:9".into(),
            &2.into(),
            &9.into()
        ),
        "{state:#}"
    );
    assert_eq!(d["message"], "unexpected `=`");
    assert!(d["rendered"].as_str().unwrap().contains("2 │   float = ;"), "{d:#}");
    assert_eq!(state["shown"]["generation"].as_u64(), Some(g));
    assert_eq!(serve.red_pixels(), 4);

    // Fixed from the page: a new generation with the new edge.
    let g = state["generation"].as_u64().unwrap();
    let saved = Instant::now();
    assert_eq!(serve.post("/file?path=my/halfplane.prim", &halfplane(10)).0, 200);
    let state = serve.next_state(g);
    eprintln!("an edit rendered in {:.0} ms", saved.elapsed().as_secs_f64() * 1e3);
    assert_eq!(state["status"], "ok", "{state:#}");
    assert_eq!(
        state["diagnostics"].as_array().map(Vec::len),
        Some(2),
        "W0004, W0803: {state:#}"
    );
    assert_eq!(serve.red_pixels(), 10);

    // Saved by an editor (the file watcher): rendered again.
    let g = state["generation"].as_u64().unwrap();
    std::fs::write(serve.dir.join("my/halfplane.prim"), halfplane(2)).unwrap();
    assert_eq!(serve.next_state(g)["status"], "ok");
    assert_eq!(serve.red_pixels(), 2);

    // Paths outside the scene's and the primitive directories, or not sources: 403, and
    // nothing read or written.
    let outside = std::env::temp_dir().join(format!("primflow-serve-outside-{}.prim", std::process::id()));
    std::fs::write(&outside, "secret").unwrap();
    std::os::unix::fs::symlink(&outside, serve.dir.join("my/link.prim")).unwrap();
    let outside_path = outside.display().to_string();
    for path in [
        "../../etc/passwd",
        "/etc/passwd",
        "%2Fetc%2Fpasswd",
        "..%2F..%2Fetc%2Fpasswd",
        "../x.prim",
        "my/../../x.prim",
        outside_path.as_str(),
        "my/link.prim",
        "a.png",
        "my",
        "",
    ] {
        let (status, _, body) = serve.get(&format!("/file?path={path}"));
        assert_eq!(status, 403, "GET {path}: {}", String::from_utf8_lossy(&body));
        let (status, body) = serve.post(&format!("/file?path={path}"), "written");
        assert_eq!(status, 403, "POST {path}: {body}");
        assert!(body.starts_with("refused: "), "{body}");
    }
    assert_eq!(std::fs::read_to_string(&outside).unwrap(), "secret");
    assert!(!serve.dir.join("../x.prim").exists());
    std::fs::remove_file(&outside).unwrap();
    // An absolute path inside is allowed.
    let absolute = std::fs::canonicalize(serve.dir.join("a.scene")).unwrap();
    let (status, _, text) = serve.get(&format!("/file?path={}", absolute.display()));
    assert_eq!((status, String::from_utf8(text).unwrap()), (200, SCENE.to_string()));

    // The scene deleted: reported, the server goes on; saved from the page: rendered.
    let g = serve.state()["generation"].as_u64().unwrap();
    std::fs::remove_file(serve.dir.join("a.scene")).unwrap();
    let mut state = serve.next_state(g);
    while state["status"] != "missing" {
        state = serve.next_state(state["generation"].as_u64().unwrap());
    }
    assert!(
        state["message"].as_str().unwrap().contains("the scene does not exist"),
        "{state:#}"
    );
    assert_eq!(serve.get("/file?path=a.scene").0, 404);
    assert_eq!(serve.post("/file?path=a.scene", SCENE).0, 200);
    let state = serve.next_state(state["generation"].as_u64().unwrap());
    assert_eq!(state["status"], "ok", "{state:#}");
    assert_eq!(serve.red_pixels(), 2);

    assert_eq!(serve.get("/nothing").0, 404);
    assert_eq!(http(serve.port, "PUT", "/file?path=a.scene", b"x").0, 405);
}

/// The page as headless Chromium leaves it after running its script for a while.
fn browser_dom(port: u16, profile: &Path) -> String {
    let output = Command::new("chromium")
        .args([
            "--headless",
            "--disable-gpu",
            "--no-sandbox",
            "--virtual-time-budget=2000",
            &format!("--user-data-dir={}", profile.display()),
            "--dump-dom",
            &format!("http://127.0.0.1:{port}/"),
        ])
        .stdin(Stdio::null())
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "cannot run `chromium` ({e}): this test needs Debian's chromium package \
                 (`apt-get install -y chromium`; .ci/run installs it)"
            )
        });
    assert!(
        output.status.success(),
        "chromium failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8(output.stdout).unwrap()
}

#[test]
fn serve_page_in_headless_chromium_shows_the_image_and_diagnostics() {
    let serve = start("browser");
    let profile = serve.dir.join("chromium-profile");
    let first = serve.next_state(0);
    assert_eq!(first["status"], "ok", "{first:#}");

    // The script fetched /state and showed the image, which the browser decoded (its size
    // is set when it has loaded).
    let dom = browser_dom(serve.port, &profile);
    assert!(
        dom.contains(r#"<img id="frame" alt="the render" src="/image.png?gen=1" data-size="16x4" data-generation="1""#),
        "{dom}"
    );
    assert!(
        dom.contains(r#"<span id="status" class="ok">render 1: ok</span>"#),
        "{dom}"
    );
    assert!(
        dom.contains(r#"<option value="param:Cs">parameter Cs</option>"#),
        "{dom}"
    );

    // An edit: the new image.
    assert_eq!(serve.post("/file?path=my/halfplane.prim", &halfplane(10)).0, 200);
    assert_eq!(serve.next_state(1)["status"], "ok");
    let dom = browser_dom(serve.port, &profile);
    assert!(
        dom.contains(r#"src="/image.png?gen=2" data-size="16x4" data-generation="2""#),
        "{dom}"
    );

    // An edit that breaks the primitive: its diagnostic, the image of generation 2 kept.
    assert_eq!(serve.post("/file?path=my/halfplane.prim", BROKEN).0, 200);
    assert_eq!(serve.next_state(2)["status"], "errors");
    let dom = browser_dom(serve.port, &profile);
    assert!(
        dom.contains(r#"<a>./my/halfplane.prim:2:9</a>: error[E0011]: unexpected `=`"#),
        "{dom}"
    );
    assert!(
        dom.contains(r#"<span id="status" class="errors">render 3: errors</span>"#),
        "{dom}"
    );
    assert!(dom.contains(r#"src="/image.png?gen=2""#), "{dom}");
}
