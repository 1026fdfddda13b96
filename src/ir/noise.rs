//! The `noise` and `cellnoise` built-ins, as the language defines them: the one
//! implementation that kernels call (through `jit::libm`, lane by lane) and the IR evaluator
//! calls, so the two agree bit for bit.
//!
//! Both take 1 to 4 coordinates. They compute in f64 from the f32 coordinates and round the
//! result to f32 once.
//!
//! - **Cells.** A coordinate `x` lies in the integer cell `floor(x)` (saturated to the i32
//!   range) at offset `x - floor(x)` in [0, 1]. A NaN or infinite coordinate is taken as 0.
//!   A finite f32 of magnitude 2^23 or more is an integer, so it sits on a lattice point.
//! - **Hash.** A cell's corner is hashed from its integer coordinates with wrapping u32
//!   arithmetic (a `lowbias32` mixer per coordinate, seeded per function and dimension):
//!   no table, no state; the same corner gives the same hash in every run and on every
//!   machine.
//! - **`cellnoise`** is `(hash >> 8) / 2^24`: a multiple of 2^-24 in [0, 1), exact in f32,
//!   constant on each cell `[i, i + 1)` of every axis.
//! - **`noise`** is gradient (Perlin) noise: each corner of the cell has a pseudo-random
//!   gradient of length at most 1 (1-D: a slope in [-1, 1); 2-D: one of 8 unit directions;
//!   3-D: one of the 12 unit edge directions of a cube; 4-D: one of 32 unit directions
//!   (±1, ±1, ±1, 0)/√3 and permutations); the corner's contribution is the gradient's dot
//!   product with the offset from the corner; the contributions are blended with the quintic
//!   fade `6t^5 - 15t^4 + 10t^3` per axis, so the noise is C2-continuous. The raw sum `n`
//!   is 0 at every lattice point and stays within ±√D/2 in D dimensions (the distance from
//!   a cell's centre to its corners; Perlin noise with unit gradients peaks there), and the
//!   result is `clamp(0.5 + n / √D, 0, 1)`: in [0, 1], exactly 0.5 at every integer point,
//!   the clamp only a guard against rounding.
//!
//! Invariant: no input panics or gives NaN; more or fewer than 1 to 4 coordinates (which the
//! checker never produces) give 0.5 and 0.

use std::f64::consts::FRAC_1_SQRT_2;

/// Seeds of the hash, so that `noise` and `cellnoise` and their dimensions are unrelated.
const NOISE_SEED: u32 = 0x9e37_79b9;
const CELL_SEED: u32 = 0x85eb_ca6b;

/// The `lowbias32` integer mixer (Chris Wellons): a bijection of u32 with good avalanche.
fn mix(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// The hash of an integer point, for a function `seed`.
fn hash(cell: &[i32], seed: u32) -> u32 {
    let mut h = mix(seed.wrapping_add(cell.len() as u32));
    for &c in cell {
        h = mix(h ^ c as u32);
    }
    h
}

/// A coordinate as the noise functions read it: NaN and infinities are 0.
fn coord(x: f32) -> f64 {
    if x.is_finite() {
        f64::from(x)
    } else {
        0.0
    }
}

/// The cell of `x` (saturated) and the offset in it, in [0, 1].
fn split(x: f64) -> (i32, f64) {
    let f = x.floor();
    (f as i32, x - f)
}

/// The quintic fade curve: 0 at 0, 1 at 1, first and second derivatives 0 at both.
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// The gradient that hash `h` picks, dotted with offset `d` (1 to 4 components).
fn gradient_dot(h: u32, d: &[f64]) -> f64 {
    const S: f64 = FRAC_1_SQRT_2;
    match d {
        [x] => (f64::from(h >> 8) * (1.0 / 8_388_608.0) - 1.0) * x,
        [x, y] => {
            const DIRS: [(f64, f64); 8] = [
                (1.0, 0.0),
                (S, S),
                (0.0, 1.0),
                (-S, S),
                (-1.0, 0.0),
                (-S, -S),
                (0.0, -1.0),
                (S, -S),
            ];
            let (gx, gy) = DIRS[(h & 7) as usize];
            gx * x + gy * y
        }
        [x, y, z] => {
            // The 12 edge directions of a cube: two of the axes, with signs.
            let (a, b) = match (h >> 2) % 3 {
                0 => (x, y),
                1 => (x, z),
                _ => (y, z),
            };
            let sa = if h & 1 == 0 { *a } else { -a };
            let sb = if h & 2 == 0 { *b } else { -b };
            (sa + sb) * S
        }
        [x, y, z, w] => {
            // Three of the four axes, with signs, over √3.
            let all = [x, y, z, w];
            let skip = ((h >> 3) & 3) as usize;
            let mut sum = 0.0;
            let mut bit = 0;
            for (k, v) in all.iter().enumerate() {
                if k == skip {
                    continue;
                }
                sum += if h >> bit & 1 == 0 { **v } else { -**v };
                bit += 1;
            }
            sum * (1.0 / 3f64.sqrt())
        }
        _ => 0.0,
    }
}

/// Raw gradient noise of 1 to 4 coordinates: within ±√D/2, 0 at lattice points.
pub fn gradient_noise(p: &[f64]) -> f64 {
    let dims = p.len();
    if !(1..=4).contains(&dims) {
        return 0.0;
    }
    let mut cell = [0i32; 4];
    let mut frac = [0f64; 4];
    let mut weight = [0f64; 4];
    for k in 0..dims {
        (cell[k], frac[k]) = split(p[k]);
        weight[k] = fade(frac[k]);
    }
    let mut sum = 0.0;
    for corner in 0..1u32 << dims {
        let mut c = [0i32; 4];
        let mut d = [0f64; 4];
        let mut w = 1.0;
        for k in 0..dims {
            let bit = (corner >> k) & 1;
            c[k] = cell[k].wrapping_add(bit as i32);
            d[k] = frac[k] - f64::from(bit);
            w *= if bit == 1 { weight[k] } else { 1.0 - weight[k] };
        }
        if w != 0.0 {
            sum += w * gradient_dot(hash(&c[..dims], NOISE_SEED), &d[..dims]);
        }
    }
    sum
}

/// `noise(...)` of 1 to 4 coordinates: in [0, 1], 0.5 at integer points (see the module
/// doc).
pub fn noise(p: &[f32]) -> f32 {
    let mut q = [0f64; 4];
    let dims = p.len().min(4);
    for (k, &x) in p.iter().take(4).enumerate() {
        q[k] = coord(x);
    }
    if !(1..=4).contains(&p.len()) {
        return 0.5;
    }
    let n = gradient_noise(&q[..dims]);
    (0.5 + n / (dims as f64).sqrt()).clamp(0.0, 1.0) as f32
}

/// `cellnoise(...)` of 1 to 4 coordinates: a multiple of 2^-24 in [0, 1), the same on
/// each integer cell (see the module doc).
pub fn cellnoise(p: &[f32]) -> f32 {
    if !(1..=4).contains(&p.len()) {
        return 0.0;
    }
    let mut cell = [0i32; 4];
    for (k, &x) in p.iter().enumerate() {
        cell[k] = split(coord(x)).0;
    }
    (f64::from(hash(&cell[..p.len()], CELL_SEED) >> 8) * (1.0 / 16_777_216.0)) as f32
}

/// The number of coordinates of a `noise`/`cellnoise` call whose arguments have these
/// dimensions, or `None` when they do not fit one of its forms: `(x)`, `(x, y)`, `(p)` and
/// `(p, t)` with scalar `x`, `y`, `t` and a `p` of 3 or 4 components (a point's w is not a
/// coordinate).
pub fn noise_dims(shapes: &[&[u32]]) -> Option<usize> {
    let point = |d: &[u32]| matches!(d, [3] | [4]);
    match shapes {
        [[]] => Some(1),
        [[], []] => Some(2),
        [p] if point(p) => Some(3),
        [p, []] if point(p) => Some(4),
        _ => None,
    }
}
