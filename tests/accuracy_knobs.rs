//! `primflow accuracy`: each knob's error moves the right way when the knob is turned, and
//! the f64 reference renderer agrees with analytic answers.

use glam::DVec3;
use primflow::accuracy::knobs::{icosphere, jittered_mesh, standard_patch, tessellation_for};
use primflow::accuracy::reference::{self, cover};
use primflow::accuracy::scene::{Camera, Interp, Item, ParamSpec, Scene, Triangle};
use primflow::accuracy::{run, AccuracyOptions, KnobReport, Row};

fn knob(name: &str) -> KnobReport {
    let opts = AccuracyOptions {
        filter: Some(name.into()),
        quick: true,
        runs: 1,
        progress: false,
    };
    let report = run(&opts).unwrap_or_else(|e| panic!("accuracy run `{name}` failed: {e}"));
    assert_eq!(report.knobs.len(), 1);
    report.knobs.into_iter().next().unwrap()
}

fn rows<'a>(k: &'a KnobReport, metric: &str) -> Vec<&'a Row> {
    k.rows.iter().filter(|r| r.metric == metric).collect()
}

fn row<'a>(k: &'a KnobReport, setting: &str, metric: &str) -> &'a Row {
    k.rows
        .iter()
        .find(|r| r.setting.starts_with(setting) && r.metric == metric)
        .unwrap_or_else(|| panic!("no row {setting} / {metric}"))
}

#[test]
fn more_sphere_triangles_never_increase_silhouette_error() {
    let k = knob("sphere");
    let silhouette = rows(&k, "silhouette");
    assert!(silhouette.len() >= 5);
    for pair in silhouette.windows(2) {
        // Noise: a pixel flips with sub-pixel changes; 0.05 px is far below a pixel.
        assert!(
            pair[1].max <= pair[0].max + 0.05,
            "{} ({}) after {} ({})",
            pair[1].setting,
            pair[1].max,
            pair[0].setting,
            pair[0].max
        );
    }
    // 20 triangles: the icosahedron is far inside the silhouette; 20 480: well under a pixel.
    assert!(silhouette[0].max > 5.0, "{}", silhouette[0].max);
    assert!(silhouette.last().unwrap().max < 0.25);
    let normal = rows(&k, "normal");
    assert!(normal.last().unwrap().mean < normal[0].mean / 50.0);
}

#[test]
fn finer_nurb_tolerance_never_increases_geometric_error() {
    let k = knob("nurb");
    let geometric = rows(&k, "geometric");
    assert_eq!(geometric.len(), 6);
    let tolerances = [8.0, 4.0, 2.0, 1.0, 0.5, 0.25];
    for (r, tol) in geometric.iter().zip(tolerances) {
        // The tessellation meets its tolerance on the rendered pixels too (plus the f32 of
        // the kernels and a little sampling slack).
        assert!(r.max <= tol * 1.1 + 0.02, "{}: {} px", r.setting, r.max);
    }
    for pair in geometric.windows(2) {
        assert!(
            pair[1].max <= pair[0].max + 0.02,
            "{} then {}",
            pair[0].max,
            pair[1].max
        );
    }
}

#[test]
fn perspective_linear_is_right_and_linear_is_far_off_on_a_grazing_plane() {
    let k = knob("interpolation");
    let persp = row(&k, "perspective_linear", "uv");
    let linear = row(&k, "linear, 2 tris", "uv");
    assert!(persp.mean < 1e-4, "perspective_linear mean uv error {}", persp.mean);
    assert!(
        linear.max > 0.5 && linear.mean > 0.1,
        "linear {} / {}",
        linear.max,
        linear.mean
    );
    // Where perspective_linear's uv error is largest (the horizon rows, where uv changes
    // fastest) it moves the texture by a small fraction of a pixel.
    assert!(row(&k, "perspective_linear", "uv displacement").max < 0.1);
    // Cutting the plane finer helps linear interpolation, but never reaches perspective.
    let finer = row(&k, "linear, 512", "uv");
    assert!(finer.mean < linear.mean / 5.0 && finer.mean > persp.mean * 10.0);
    assert_eq!(k.most_accurate, "perspective_linear, 2 tris");
}

#[test]
fn exact_rasteriser_is_watertight_and_reduced_arithmetic_is_measured_against_it() {
    let k = knob("arithmetic");
    for metric in ["coverage differs", "cracks", "overdraw"] {
        assert_eq!(row(&k, "f64", metric).max, 0.0, "{metric}");
        // The library's integer edge functions never crack or overdraw on shared edges.
        if metric != "coverage differs" {
            assert_eq!(row(&k, "int", metric).max, 0.0, "{metric}");
        }
    }
    // Snapping to 1/16 pixel moves edges: some pixels differ from the exact rasteriser.
    assert!(row(&k, "int", "coverage differs").max > 0.0);
}

#[test]
fn lighting_in_lc_equals_wc_and_dc_is_wrong() {
    let k = knob("lighting");
    let lc = row(&k, "LC", "colour");
    let wc = row(&k, "WC", "colour");
    let dc = row(&k, "DC", "colour");
    assert!((lc.mean - wc.mean).abs() < 1e-5, "LC {} WC {}", lc.mean, wc.mean);
    assert!(lc.mean < 1e-3);
    assert!(dc.mean > 100.0 * lc.mean, "DC {} LC {}", dc.mean, lc.mean);
}

#[test]
fn fewer_depth_bits_mean_more_z_fighting() {
    let k = knob("depth");
    let fight = |s: &str| row(&k, s, "z-fighting").max;
    assert!(fight("fixed<16,16>") > 10.0 * fight("fixed<32,32>").max(1.0));
    assert!(fight("fixed<24,24>") >= fight("fixed<32,32>"));
    assert!(fight("fixed<16,16>") >= fight("fixed<24,24>"));
    assert!(fight("f16-like") > fight("fixed<24,24>"));
}

#[test]
fn reference_interpolation_matches_ray_plane_intersection() {
    // A plane y = 0 in a perspective view, two triangles with (x, z) as parameters: the
    // reference's perspective-correct values must be the world coordinates where the pixel
    // ray meets the plane.
    let camera = Camera::perspective(
        64,
        48,
        DVec3::new(0.0, 0.5, 0.0),
        DVec3::new(0.0, 0.0, -4.0),
        DVec3::Y,
        60.0,
        0.1,
        100.0,
    )
    .unwrap();
    let params = vec![ParamSpec {
        name: "xz".into(),
        components: 2,
        interp: Interp::Perspective,
    }];
    let mut scene = Scene::new(64, 48, params);
    let corners = [(-3.0, -1.0), (3.0, -1.0), (3.0, -30.0), (-3.0, -30.0)];
    for t in [[0, 1, 2], [0, 2, 3]] {
        scene.items.push(Item::Triangle(Triangle {
            vertices: t.map(|i| camera.screen(DVec3::new(corners[i].0, 0.0, corners[i].1))),
            values: t.map(|i| vec![corners[i].0, corners[i].1]),
        }));
    }
    let frame = reference::render(&scene);
    let mut checked = 0;
    for i in 0..frame.count.len() {
        if frame.count[i] == 0 {
            continue;
        }
        let (x, y) = ((i % 64) as f64 + 0.5, (i / 64) as f64 + 0.5);
        let dir = camera.ray(x, y);
        let t = -camera.eye.y / dir.y;
        let hit = camera.eye + dir * t;
        let (first, _) = frame.param("xz").unwrap();
        assert!((frame.planes[first][i] - hit.x).abs() < 1e-9 * (1.0 + hit.x.abs()));
        assert!((frame.planes[first + 1][i] - hit.z).abs() < 1e-9 * hit.z.abs());
        assert!((frame.depth[i] - camera.depth(hit)).abs() < 1e-12);
        checked += 1;
    }
    assert!(checked > 500, "{checked}");
}

#[test]
fn reference_covers_shared_edges_through_pixel_centres_exactly_once() {
    // A fan of 16 triangles around a pixel centre with every vertex on a pixel centre, so
    // many pixel centres lie exactly on edges: the top-left rule gives each to one triangle.
    let params = vec![ParamSpec {
        name: "id".into(),
        components: 1,
        interp: Interp::Constant,
    }];
    let mut scene = Scene::new(32, 32, params);
    let ring: Vec<[f64; 2]> = (0..16)
        .map(|k| {
            let a = k as f64 / 16.0 * std::f64::consts::TAU;
            [
                (16.0 + 12.0 * a.cos()).round() + 0.5,
                (16.0 + 12.0 * a.sin()).round() + 0.5,
            ]
        })
        .collect();
    for k in 0..16 {
        let (a, b) = (ring[k], ring[(k + 1) % 16]);
        scene.items.push(Item::Triangle(Triangle {
            vertices: [[16.5, 16.5, 0.5, 1.0], [a[0], a[1], 0.5, 1.0], [b[0], b[1], 0.5, 1.0]],
            values: [vec![k as f64], vec![k as f64], vec![k as f64]],
        }));
    }
    let frame = reference::render(&scene);
    assert!(frame.count.iter().all(|&c| c <= 1), "a pixel was covered twice");
    // The centre pixel is on all 16 edges and belongs to exactly one triangle.
    assert_eq!(frame.count[16 * 32 + 16], 1);
    // A single triangle's own test agrees with its orientation reversed.
    let v = [[1.5, 1.5, 0.0, 1.0], [9.5, 1.5, 0.0, 1.0], [1.5, 7.5, 0.0, 1.0]];
    let r = [v[0], v[2], v[1]];
    for (x, y) in [(1.5, 1.5), (5.5, 1.5), (1.5, 4.5), (3.5, 3.5), (9.5, 1.5)] {
        assert_eq!(cover(&v, x, y).is_some(), cover(&r, x, y).is_some(), "({x}, {y})");
    }
}

#[test]
fn jittered_mesh_is_covered_once_by_the_reference() {
    let scene = jittered_mesh(64, 6, 3);
    assert_eq!(scene.items.len(), 72);
    let frame = reference::render(&scene);
    // Inside the margin every pixel is covered exactly once.
    for y in 5..59 {
        for x in 5..59 {
            assert_eq!(frame.count[y * 64 + x], 1, "({x}, {y})");
        }
    }
}

#[test]
fn icosphere_and_tessellation_sizes() {
    for level in 0..4 {
        let m = icosphere(level);
        assert_eq!(m.triangles.len(), 20 * 4usize.pow(level));
        assert!(m.positions.iter().all(|p| (p.length() - 1.0).abs() < 1e-12));
    }
    let camera = Camera::perspective(
        128,
        128,
        DVec3::new(0.3, 3.2, 2.0),
        DVec3::new(0.0, 0.1, 0.0),
        DVec3::Y,
        45.0,
        0.1,
        100.0,
    )
    .unwrap();
    let patch = standard_patch();
    let n: Vec<usize> = [8.0, 2.0, 0.5]
        .iter()
        .map(|&t| tessellation_for(&camera, &patch, t))
        .collect();
    assert!(n[0] < n[1] && n[1] < n[2], "{n:?}");
}
