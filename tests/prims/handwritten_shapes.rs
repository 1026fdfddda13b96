//! The hand-written sphere (scalar, SSE4.1, AVX2) and NURB surface (scalar, AVX2) kernels
//! against their JIT twins on the same scenes: depth, shading-parameter planes and write
//! counts bit for bit.
//! Scenes cover the cases the prims treat specially — a sphere cut by the hither plane, one
//! grazing the viewport edge, one around the eye plane (no bound: evaluated everywhere), a
//! turned model matrix; two NURB patches sharing an edge, with a normal and a linear
//! parameter, and patches crossing the hither plane (the polygon's clip path).

use crate::support;
use support::*;

use std::sync::Arc;

use primflow::handwritten::{Flavor, Handwritten};
use primflow::ir::Program;
use primflow::jit::Jit;
use primflow::runtime::{Frame, Renderer, Value};

fn frames_equal(a: &Frame, b: &Frame, what: &str) {
    let depth_diff = a
        .depth_values()
        .iter()
        .zip(&b.depth_values())
        .filter(|(x, y)| x != y)
        .count();
    assert_eq!(depth_diff, 0, "{what}: depth differs in {depth_diff} pixels");
    assert_eq!(
        a.write_count_values(),
        b.write_count_values(),
        "{what}: write counts differ"
    );
    assert_eq!(a.num_planes(), b.num_planes());
    for (p, (pa, pb)) in a.all_plane_values().iter().zip(&b.all_plane_values()).enumerate() {
        let differing = pa.iter().zip(pb).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
        assert_eq!(differing, 0, "{what}: plane {p} differs in {differing} pixels");
    }
}

/// The hand-written forms of each shape.
const SPHERE_FLAVORS: [Flavor; 3] = [Flavor::Scalar, Flavor::Sse, Flavor::Avx2];
const NURB_FLAVORS: [Flavor; 2] = [Flavor::Scalar, Flavor::Avx2];

/// Render `r` with the JIT and the hand-written `flavors`; assert they agree (and that
/// none reports anything) and return the JIT's frame.
fn jit_and_handwritten_agree(program: &Arc<Program>, r: &Renderer, flavors: &[Flavor], what: &str) -> Frame {
    let mut jit_source = Jit::new(program.clone()).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let out = pool.install(|| r.render(&mut jit_source));
    assert!(out.diags.items.is_empty(), "{what}: {:?}", out.diags.items);
    let jit = out.frame;
    for &flavor in flavors {
        let mut hand = Handwritten::new(program.clone(), flavor);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let out = pool.install(|| r.render(&mut hand));
        assert!(out.diags.items.is_empty(), "{what}: {:?}", out.diags.items);
        frames_equal(&jit, &out.frame, &format!("{what}, {}", flavor.describe()));
    }
    jit
}

fn written(frame: &Frame) -> usize {
    frame.write_count_values().unwrap().iter().filter(|&&c| c > 0).count()
}

fn sphere(r: &mut Renderer, center: [f32; 3], radius: f32) {
    r.begin("sphere").unwrap();
    r.rast_param("center", &Value(center.to_vec())).unwrap();
    r.rast_param("radius", &Value(vec![radius])).unwrap();
    r.end().unwrap();
}

/// Several overlapping spheres, one cut by the hither plane, one grazing the right edge of
/// the viewport, one around the eye plane (no bounded silhouette), one behind the eye,
/// under a turned model matrix so the normal matrix is not the identity.
fn sphere_scene(program: &Arc<Program>, normal: bool) -> Renderer {
    let mut r = renderer(program, 96, 72, true);
    r.perspective_checked(60.0, 1.0, 40.0).unwrap();
    if normal {
        r.material_interp("N", "implicit", &[]).unwrap();
        r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
    }
    r.rotate(25.0, [0.2, 1.0, 0.1]).unwrap();
    let mut rng = Lcg(7);
    for _ in 0..6 {
        let c = [
            rng.range(-3.0, 3.0) as f32,
            rng.range(-2.0, 2.0) as f32,
            rng.range(-12.0, -6.0) as f32,
        ];
        sphere(&mut r, c, rng.range(0.8, 2.0) as f32);
    }
    sphere(&mut r, [0.0, 0.0, -1.2], 0.8); // cut by the hither plane (near = 1)
    sphere(&mut r, [0.0, 0.0, -0.3], 1.0); // reaches the eye plane: evaluated everywhere
    sphere(&mut r, [0.0, 0.0, 6.0], 1.0); // behind the eye
    r.rotate(-25.0, [0.2, 1.0, 0.1]).unwrap();
    // Its silhouette's rightmost point just inside / at the right edge of the view.
    let half_width = (30f64.to_radians()).tan() * 10.0;
    sphere(&mut r, [(half_width + 0.9) as f32, 0.5, -10.0], 1.0);
    sphere(&mut r, [-(half_width + 1.0) as f32, -0.5, -10.0], 1.0);
    assert!(r.take_warnings().is_empty());
    r
}

#[test]
fn sphere_jit_and_handwritten_agree_bit_for_bit() {
    let program = library();
    for normal in [true, false] {
        let r = sphere_scene(&program, normal);
        let frame = jit_and_handwritten_agree(&program, &r, &SPHERE_FLAVORS, &format!("spheres, normal {normal}"));
        let covered = written(&frame);
        assert!(covered > 3000, "only {covered} pixels covered");
        // The sphere around the eye plane covers part of the view near the centre, in front
        // of everything else; the hither-cut one shows its far side elsewhere.
        assert!(frame.write_count_values().unwrap().iter().any(|&c| c >= 2));
        // Pixels on the right and left columns come from the grazing spheres.
        assert!((0..72).any(|y| frame.written(95, y)));
        assert!((0..72).any(|y| frame.written(0, y)));
        if normal {
            // Unit normals wherever something was drawn.
            for y in 0..72 {
                for x in 0..96 {
                    if frame.written(x, y) {
                        let n = frame.param_at("N", x, y).unwrap();
                        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                        assert!((len - 1.0).abs() < 1e-5, "normal length {len} at ({x}, {y})");
                    }
                }
            }
        }
    }
}

/// The benchmark's sphere workload, small: the key and scene `primflow bench` times.
#[test]
fn sphere_bench_workload_agrees() {
    let program = library();
    let mut r = renderer(&program, 128, 128, true);
    r.perspective(50.0, 1.0, 100.0);
    r.material_interp("N", "implicit", &[]).unwrap();
    r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
    for i in 0..20 {
        let (x, y) = ((i % 5) as f32 * 2.2 - 4.4, (i / 5) as f32 * 2.0 - 3.0);
        sphere(&mut r, [x, y, -8.0 - (i % 3) as f32 * 0.7], 1.2 + 0.015 * i as f32);
    }
    let frame = jit_and_handwritten_agree(&program, &r, &SPHERE_FLAVORS, "bench spheres");
    assert!(written(&frame) > 128 * 128 / 2);
}

/// The SSE kernel's own paths (and the other forms beside it): a viewport of several tiles
/// that is not whole groups wide, so groups are ragged at both ends of a bound and of the
/// tile; spheres narrower than a group; one whose surface passes through the eye (the
/// eye's power `a` is zero: the prim's `z_other = -1` arm); small far spheres; hither cuts;
/// with and without write counts and the normal.
#[test]
fn sse_sphere_paths_agree_bit_for_bit() {
    let program = library();
    for (normal, count_writes) in [(true, false), (false, true), (true, true)] {
        let (w, h) = (203u32, 141u32);
        let mut r = renderer(&program, w, h, count_writes);
        r.perspective_checked(55.0, 1.0, 60.0).unwrap();
        if normal {
            r.material_interp("N", "implicit", &[]).unwrap();
            r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
        }
        let mut rng = Lcg(if normal { 31 } else { 32 });
        for k in 0..40 {
            let radius = match k % 4 {
                0 => 0.02, // a pixel or two: narrower than a group
                1 => 0.15,
                2 => 0.6,
                _ => 1.5,
            };
            let c = [
                rng.range(-4.0, 4.0) as f32,
                rng.range(-3.0, 3.0) as f32,
                rng.range(-14.0, -2.5) as f32,
            ];
            sphere(&mut r, c, radius);
        }
        sphere(&mut r, [0.0, 0.0, -30.0], 1e-3); // small and far: depths a few ulps apart
        sphere(&mut r, [0.4, -0.3, -1.1], 0.5); // cut by the hither plane
        sphere(&mut r, [0.0, 0.0, -2.0], 2.0); // the eye on its surface: a == 0
        assert!(r.take_warnings().is_empty());
        let frame = jit_and_handwritten_agree(
            &program,
            &r,
            &SPHERE_FLAVORS,
            &format!("SSE paths, normal {normal}, counts {count_writes}"),
        );
        let covered = frame.depth_values().iter().filter(|&&d| d != 0).count();
        assert!(covered > (w * h / 2) as usize, "only {covered} pixels drawn");
        if count_writes {
            // Overlapping spheres drawn in submission order: some pixels written twice.
            assert!(frame.write_count_values().unwrap().iter().any(|&c| c >= 2));
        }
    }
}

/// A 4 x 4 bicubic patch with corner (x0, y0) in object space.
fn nurb_patch(r: &mut Renderer, net: &[[f64; 3]], tolerance: f32, with_data: bool) {
    r.begin("nurb_surface").unwrap();
    r.rast_param("tolerance", &Value(vec![tolerance])).unwrap();
    for (k, p) in net.iter().enumerate() {
        r.rast_param("weight", &Value(vec![if k == 5 { 2.5 } else { 1.0 }]))
            .unwrap();
        if with_data {
            r.material("s", &Value(vec![(k % 4) as f32 * 0.25 + (k / 4) as f32]))
                .unwrap();
        }
        r.vertex(p[0] as f32, p[1] as f32, p[2] as f32, 1.0).unwrap();
    }
    r.end().unwrap();
}

#[test]
fn nurb_patches_sharing_an_edge_agree_bit_for_bit() {
    let program = library();
    for (normal, data) in [(true, true), (false, false), (true, false)] {
        let mut r = renderer(&program, 96, 64, true);
        r.perspective_checked(40.0, 1.0, 50.0).unwrap();
        if normal {
            r.material_interp("N", "implicit", &[]).unwrap();
            r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
        }
        if data {
            r.material_interp("s", "linear", &[]).unwrap();
        }
        let [left, right] = shared_column_patches();
        // Crack-free needs the same tolerance on both sides of the shared edge.
        nurb_patch(&mut r, &left, 0.25, data);
        nurb_patch(&mut r, &right, 0.25, data);
        assert!(r.take_warnings().is_empty());
        let frame = jit_and_handwritten_agree(
            &program,
            &r,
            &NURB_FLAVORS,
            &format!("two patches, normal {normal}, data {data}"),
        );
        let counts = frame.write_count_values().unwrap();
        assert!(written(&frame) > 1500, "only {} pixels", written(&frame));
        // The shared edge is crack-free and written once (the patches do not overlap).
        assert!(counts.iter().all(|&c| c <= 1), "a pixel written twice");
    }
}

#[test]
fn nurb_patches_crossing_the_hither_plane_agree_bit_for_bit() {
    let program = library();
    let mut r = renderer(&program, 80, 60, true);
    r.perspective_checked(60.0, 1.0, 50.0).unwrap();
    let mut rng = Lcg(11);
    for p in 0..4 {
        // Tilted towards the eye: the near rows come closer than the hither plane (and the
        // last patch reaches behind the eye, so its net has no finite projection).
        let (cx, cy) = (rng.range(-2.0, 1.0), rng.range(-1.5, 0.5));
        let near = [-1.6, -0.6, -0.4, 0.5][p];
        let mut net = vec![];
        for j in 0..4 {
            for i in 0..4 {
                let z = -6.0 + (6.0 + near) * j as f64 / 3.0 + rng.range(-0.3, 0.3);
                net.push([cx + i as f64 * 0.7, cy + j as f64 * 0.5, z]);
            }
        }
        nurb_patch(&mut r, &net, 0.5, false);
    }
    let frame = jit_and_handwritten_agree(&program, &r, &NURB_FLAVORS, "patches crossing the hither plane");
    assert!(written(&frame) > 500, "only {} pixels", written(&frame));
}

#[test]
fn unsupported_keys_are_refused_not_guessed() {
    let program = library();
    let mut r = renderer(&program, 16, 16, false);
    r.material_interp("N", "implicit", &[]).unwrap();
    r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
    r.material_interp("p", "perspective_linear", &[]).unwrap();
    r.material("p", &Value(vec![0.5])).unwrap();
    sphere(&mut r, [0.0, 0.0, -5.0], 1.0);
    let mut hand = Handwritten::new(program.clone(), Flavor::Scalar);
    let out = r.render(&mut hand);
    assert!(out.diags.has_errors(), "a sphere key with two bindings must be refused");
    assert!(out.frame.depth_values().iter().all(|&d| d == 0));
}
