//! Component access and the shading built-ins through real kernels, at both tiers with loop
//! unrolling on and off: swizzle reads and single-component writes pinned per pixel against
//! an exact reference; `reflect`, `refract` (total internal reflection included) and
//! `faceforward` against an f64 reference within 1e-5; `noise`/`cellnoise` equal bit for bit
//! to `primflow::ir::noise`, the definition kernels and the evaluator call (the evaluator's
//! agreement with the kernels is `eval_oracle`'s, over tests/check/ok/shading.prim). Then
//! the noises' own properties: pinned values, range, 0.5 on the lattice, a slope bound,
//! cellnoise constant on cells, and NaN, infinite and huge coordinates.

use crate::support;
use crate::support::Lcg;

use primflow::diag::SourceMap;
use primflow::ir::noise::{cellnoise, gradient_noise, noise};
use primflow::runtime::{Renderer, Value};

const SWIZZLE: &str = r#"
primitive swizzles(float rect[4]; point p0; color c0; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    point p = p0;
    p.x = X;
    p.w += 0.5;
    color c = c0;
    c.g += Y;
    c.b = c.r * 2;
    float s[3] = p.zyx;
    vector v = c.bgr;
    float two[2] = v.xx;
    float k = p0.w + c0.g;
    Z = (s[0] + 2 * s[1] + 4 * s[2] + 8 * v.x + 16 * v.y + 32 * v.z + 64 * two[1] + 128 * p.w + 256 * k) / 4096;
}
"#;

/// Render `prim` over a `w` x `h` image with the float parameters given (`rect` covers it).
fn scene(source: (&str, &str), prim: &str, w: u32, h: u32, params: &[(&str, Vec<f32>)]) -> Renderer {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[source]);
    let mut r = Renderer::new(program);
    r.set_image_size(w, h).unwrap();
    r.set_tile_size(8).unwrap();
    r.begin(prim).unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, w as f32, h as f32]))
        .unwrap();
    for (name, v) in params {
        r.rast_param(name, &Value(v.clone())).unwrap();
    }
    r.end().unwrap();
    r
}

/// fixed<32,32> raw bits of an exact depth.
fn raw(z: f64) -> u32 {
    (z * 4294967296.0) as u32
}

#[test]
fn swizzles_read_and_write_the_components_they_name() {
    let (p0, c0) = ([0.125f64, 0.25, 0.375, 1.0], [0.5f64, 0.125, 0.75]);
    let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<_>>();
    let r = scene(
        ("swizzles.prim", SWIZZLE),
        "swizzles",
        16,
        4,
        &[("p0", f32s(&p0)), ("c0", f32s(&c0))],
    );
    support::assert_depth_in_every_jit(&r, "swizzles", |x, y| {
        let (px, py) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
        // p = (X, p0.y, p0.z, p0.w + 0.5); c = (c0.r, c0.g + Y, 2 c0.r).
        let s = [p0[2], p0[1], px];
        let v = [2.0 * c0[0], c0[1] + py, c0[0]];
        let two = [v[0], v[0]];
        let k = p0[3] + c0[1];
        let sum = s[0]
            + 2.0 * s[1]
            + 4.0 * s[2]
            + 8.0 * v[0]
            + 16.0 * v[1]
            + 32.0 * v[2]
            + 64.0 * two[1]
            + 128.0 * (p0[3] + 0.5)
            + 256.0 * k;
        raw(sum / 4096.0)
    });
}

/// Pixel (x, y) checks case `x` (varying, pixel code); the setup checks all 16 (uniform).
/// Z = 0.25, + 0.5 when the pixel's case is right, + 0.125 when every setup case is.
const OPTICS: &str = r#"
int off(vector got, vector want) {
    vector d = got - want;
    return abs(d.x) <= 1e-5 && abs(d.y) <= 1e-5 && abs(d.z) <= 1e-5 ? 0 : 1;
}

int wrong(vector I, vector N, vector R, float eta, vector r, vector t, vector f, vector g) {
    return off(reflect(I, N), r) + off(refract(I, N, eta), t) + off(faceforward(N, I), f)
           + off(faceforward(N, I, R), g);
}

int check(float cases[160], float want[192], int k) {
    int a = 10 * k, b = 12 * k;
    return wrong(vector(cases[a], cases[a + 1], cases[a + 2]), vector(cases[a + 3], cases[a + 4], cases[a + 5]),
                 vector(cases[a + 6], cases[a + 7], cases[a + 8]), cases[a + 9],
                 vector(want[b], want[b + 1], want[b + 2]), vector(want[b + 3], want[b + 4], want[b + 5]),
                 vector(want[b + 6], want[b + 7], want[b + 8]), vector(want[b + 9], want[b + 10], want[b + 11]));
}

primitive optics(float rect[4]; float cases[160]; float want[192]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    int bad = 0;
    for (int k = 0; k < 16; k++)
        bad += check(cases, want, k);
    int mine = check(cases, want, int(X));
    Z = 0.25 + (mine == 0 ? 0.5 : 0.0) + (bad == 0 ? 0.125 : 0.0);
}
"#;

type V = [f64; 3];

fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn unit(rng: &mut Lcg) -> V {
    loop {
        let v = [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)];
        let l = dot(v, v).sqrt();
        if l > 0.1 && l <= 1.0 {
            // Rounded to f32 first: the reference sees the kernel's operands.
            return v.map(|x| f64::from((x / l) as f32));
        }
    }
}

/// The f64 reference: reflect, refract, faceforward(N, I), faceforward(N, I, Nref).
fn optics_reference(i: V, n: V, nref: V, eta: f64) -> [V; 4] {
    let d = dot(n, i);
    let reflect = [0, 1, 2].map(|k| i[k] - 2.0 * d * n[k]);
    let k = 1.0 - eta * eta * (1.0 - d * d);
    let refract = if k < 0.0 {
        [0.0; 3]
    } else {
        [0, 1, 2].map(|j| eta * i[j] - (eta * d + k.sqrt()) * n[j])
    };
    let face = |r: V| if dot(r, i) < 0.0 { n } else { n.map(|x| -x) };
    [reflect, refract, face(n), face(nref)]
}

#[test]
fn reflect_refract_and_faceforward_match_an_f64_reference() {
    let mut rng = Lcg(36);
    let (mut cases, mut want) = (vec![], vec![]);
    let (mut total, mut flipped, mut kept) = (0, 0, 0);
    while cases.len() < 160 {
        let (i, n, nref) = (unit(&mut rng), unit(&mut rng), unit(&mut rng));
        let eta = f64::from(rng.range(0.5, 2.0) as f32);
        let d = dot(n, i);
        let k = 1.0 - eta * eta * (1.0 - d * d);
        // Away from the total-reflection edge and from faceforward's ties, where f32 and
        // f64 may round to different sides.
        if k.abs() < 0.05 || d.abs() < 0.01 || dot(nref, i).abs() < 0.01 {
            continue;
        }
        total += usize::from(k < 0.0);
        flipped += usize::from(d >= 0.0);
        kept += usize::from(d < 0.0);
        cases.extend(i.iter().chain(&n).chain(&nref).map(|&x| x as f32));
        cases.push(eta as f32);
        want.extend(optics_reference(i, n, nref, eta).iter().flatten().map(|&x| x as f32));
    }
    assert!(total >= 2 && flipped >= 2 && kept >= 2, "{total} {flipped} {kept}");
    let r = scene(
        ("optics.prim", OPTICS),
        "optics",
        16,
        2,
        &[("cases", cases), ("want", want)],
    );
    support::assert_depth_in_every_jit(&r, "optics", |_, _| raw(0.875));
}

/// Pixel (x, y) checks point `x` (pixel code), the setup all 16 (uniform); each against
/// the Rust definition's bits.
const NOISES: &str = r#"
int differ(float x, float y, float z, float w, float want[128], int k) {
    int d = 0, b = 8 * k;
    if (noise(x) != want[b]) d++;
    if (noise(x, y) != want[b + 1]) d++;
    if (noise(vector(x, y, z)) != want[b + 2]) d++;
    if (noise(point(x, y, z, w)) != want[b + 2]) d++;
    if (noise(vector(x, y, z), w) != want[b + 3]) d++;
    if (cellnoise(x) != want[b + 4]) d++;
    if (cellnoise(x, y) != want[b + 5]) d++;
    if (cellnoise(point(x, y, z)) != want[b + 6]) d++;
    if (cellnoise(vector(x, y, z), w) != want[b + 7]) d++;
    return d;
}

primitive noises(float rect[4]; float pts[64]; float want[128]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    int bad = 0;
    for (int k = 0; k < 16; k++)
        bad += differ(pts[4 * k], pts[4 * k + 1], pts[4 * k + 2], pts[4 * k + 3], want, k);
    int c = int(X);
    int mine = differ(pts[4 * c], pts[4 * c + 1], pts[4 * c + 2], pts[4 * c + 3], want, c);
    Z = 0.25 + (mine == 0 ? 0.5 : 0.0) + (bad == 0 ? 0.125 : 0.0);
}
"#;

#[test]
fn kernels_compute_the_noises_of_the_definition_bit_for_bit() {
    let mut rng = Lcg(7);
    let special = support::special_floats();
    let mut pts = vec![];
    for k in 0..16 {
        for j in 0..4 {
            pts.push(match k {
                // NaN, infinities, huge, subnormal and signed zero coordinates.
                0..=3 => special[(4 * k + j) % 16],
                // Lattice points.
                4..=5 => rng.range(-20.0, 20.0).floor() as f32,
                _ => rng.range(-50.0, 50.0) as f32,
            });
        }
    }
    let mut want = vec![];
    for p in pts.chunks(4) {
        for f in [noise, cellnoise] {
            for d in 1..=4 {
                want.push(f(&p[..d]));
            }
        }
    }
    let r = scene(
        ("noises.prim", NOISES),
        "noises",
        16,
        2,
        &[("pts", pts), ("want", want)],
    );
    support::assert_depth_in_every_jit(&r, "noises", |_, _| raw(0.875));
}

/// `n` random points of `d` coordinates in [-lo, lo).
fn points(seed: u64, n: usize, d: usize, lo: f64) -> Vec<Vec<f32>> {
    let mut rng = Lcg(seed);
    (0..n)
        .map(|_| (0..d).map(|_| rng.range(-lo, lo) as f32).collect())
        .collect()
}

#[test]
fn noise_values_are_pinned() {
    // The same on every run and machine: an integer hash, no tables, no state.
    let got = [
        noise(&[0.3]),
        noise(&[1.7, -2.2]),
        noise(&[0.5, 0.25, 0.125]),
        noise(&[3.1, -0.4, 9.9, 0.6]),
        cellnoise(&[0.3]),
        cellnoise(&[1.7, -2.2]),
        cellnoise(&[0.5, 0.25, 0.125]),
        cellnoise(&[3.1, -0.4, 9.9, 0.6]),
    ];
    let bits: Vec<u32> = got.iter().map(|x| x.to_bits()).collect();
    assert_eq!(bits, PINNED, "{got:?}");
    for p in points(1, 100, 3, 100.0) {
        assert_eq!(noise(&p).to_bits(), noise(&p).to_bits());
    }
}

/// 0.31820762, 0.20661992, 0.59685683, 0.48634568, then cellnoise 0.6006562, 0.42830235,
/// 0.35417366, 0.83710027.
const PINNED: [u32; 8] = [
    1050864668, 1045664812, 1058589596, 1056506445, 1058653339, 1054558834, 1052071488, 1062620212,
];

#[test]
fn noise_stays_within_its_bound_and_spans_the_range() {
    for d in 1..=4 {
        let bound = (d as f64).sqrt() / 2.0;
        let (mut lo, mut hi) = (1.0f32, 0.0f32);
        for p in points(d as u64, 100_000, d, 1000.0) {
            let q: Vec<f64> = p.iter().map(|&x| f64::from(x)).collect();
            let n = gradient_noise(&q);
            assert!(n.abs() <= bound, "{d}-D raw noise {n} at {p:?} past ±{bound}");
            let v = noise(&p);
            assert!((0.0..=1.0).contains(&v), "{d}-D noise {v} at {p:?}");
            lo = lo.min(v);
            hi = hi.max(v);
        }
        // Not a constant or a narrow band: the values reach well towards both ends.
        assert!(lo < 0.25 && hi > 0.75, "{d}-D noise spans only [{lo}, {hi}]");
    }
}

#[test]
fn noise_is_one_half_on_the_lattice() {
    let mut rng = Lcg(3);
    for d in 1..=4 {
        for _ in 0..1000 {
            let p: Vec<f32> = (0..d).map(|_| rng.range(-1e6, 1e6).round() as f32).collect();
            assert_eq!(noise(&p), 0.5, "{p:?}");
        }
    }
}

#[test]
fn noise_changes_by_less_than_four_times_the_step() {
    // Along axis j the raw noise's slope is at most 1 (the blend of gradients of length at
    // most 1) plus the fade's steepest slope, 1.875, times the largest difference of two
    // corner terms across the cell, |d0| + |d1| <= 2 √(D - 0.75); over √D that is below 3.9
    // per unit for D = 1 to 4.
    for d in 1..=4 {
        for p in points(10 + d as u64, 20_000, d, 30.0) {
            let v = noise(&p);
            for axis in 0..d {
                let mut q = p.clone();
                q[axis] += 1e-3;
                let step = f64::from(q[axis]) - f64::from(p[axis]);
                let change = f64::from((noise(&q) - v).abs());
                assert!(
                    change <= 3.9 * step + 1e-6,
                    "{d}-D at {p:?} axis {axis}: {change} for {step}"
                );
            }
        }
    }
}

#[test]
fn cellnoise_is_constant_on_each_cell_and_in_the_unit_interval() {
    for d in 1..=4 {
        let mut rng = Lcg(20 + d as u64);
        let (mut sum, mut differ) = (0.0, 0);
        let n = 5000;
        for _ in 0..n {
            let cell: Vec<f32> = (0..d).map(|_| rng.range(-3e4, 3e4).floor() as f32).collect();
            let v = cellnoise(&cell);
            assert!((0.0..1.0).contains(&v), "{v}");
            // Offsets exact in f32 below 2^16.
            for f in [0.25f32, 0.5, 0.9921875] {
                let inside: Vec<f32> = cell.iter().map(|&c| c + f).collect();
                assert_eq!(cellnoise(&inside), v, "{inside:?} in the cell of {cell:?}");
            }
            let mut next = cell.clone();
            next[0] += 1.0;
            differ += usize::from(cellnoise(&next) != v);
            sum += f64::from(v);
        }
        assert!(differ > n * 99 / 100, "{d}-D: {differ} of {n} neighbours differ");
        assert!((sum / n as f64 - 0.5).abs() < 0.02, "{d}-D mean {}", sum / n as f64);
    }
}

#[test]
fn nan_infinite_and_huge_coordinates_have_documented_values() {
    for d in 1..=4 {
        let zero = vec![0.0f32; d];
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let p = vec![bad; d];
            assert_eq!(noise(&p), 0.5, "noise of {bad} is noise of 0");
            assert_eq!(cellnoise(&p), cellnoise(&zero), "cellnoise of {bad} is cellnoise of 0");
        }
        for huge in [3e38f32, -3e38, 16_777_216.0, 1e30] {
            let p = vec![huge; d];
            let v = noise(&p);
            assert_eq!(v, 0.5, "{huge} is an integer");
            // Cells saturate at the i32 range.
            let c = cellnoise(&p);
            assert!((0.0..1.0).contains(&c));
        }
        assert_eq!(cellnoise(&vec![3e38; d]), cellnoise(&vec![f32::MAX; d]));
    }
    assert_eq!(noise(&[]), 0.5);
    assert_eq!(cellnoise(&[1.0; 5]), 0.0);
}
