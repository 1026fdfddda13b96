//! Exact per-pixel area coverage: the f64 reference that antialiased (multisampled) images
//! are measured against.
//!
//! Pixel (px, py) is the unit square [px, px + 1] x [py, py + 1] (pixel centres at
//! half-integers, as everywhere in primflow), and its coverage by a shape is the area of the
//! shape inside that square, a value in [0, 1]. Nothing is sampled:
//! - a triangle (or any simple polygon) is clipped by the square's four sides
//!   (Sutherland–Hodgman: y >= py, y <= py + 1, then x >= px, x <= px + 1) and the clipped
//!   polygon's area taken by the shoelace formula in pixel-local coordinates (subtracting
//!   the integer corner is exact for points in the square, so every product is in [0, 1]).
//!   Either winding gives the positive area. An edge is always cut from the same
//!   endpoint whichever way it is traversed, so two triangles sharing an edge cut it at the
//!   same points and their areas add up to the quad's;
//! - a disc's area in the square is the integral over the square's x range of the chord
//!   clipped to the square's y range, split where the circle crosses y = py or y = py + 1,
//!   each piece a closed form of x, sqrt(r^2 - x^2) and an angle (`chord_integral`),
//!   arranged so that no term cancels catastrophically.
//!
//! A square that lies wholly inside the shape (all four corners inside: both shapes are
//! convex) has coverage exactly 1.0, and one wholly outside exactly 0.0. Elsewhere the error
//! is rounding only: for a triangle about one ulp of its largest coordinate (where the clip
//! points are rounded), for a disc about 1e-16 r (its square is taken relative to the
//! centre); both below 1e-12 for coordinates and radii up to 4096 px (measured:
//! docs/accuracy.md, "Exact area coverage"). Coordinates near the f64 limit give values in
//! [0, 1] but nothing exact. A shape with a non-finite coordinate or radius, a non-positive
//! radius, or a zero-area triangle covers nothing.
//!
//! The image functions visit only the pixels of the shape's bounding box clipped to the
//! image and return a row-major `w * h` vector, 0 elsewhere; `triangle_coverage` gives for
//! each pixel exactly (bit for bit) what `triangle_pixel_area` gives for it.

/// A point in pixel coordinates (x right, y down).
pub type Point = [f64; 2];

/// The area of `tri` inside pixel (px, py), in [0, 1].
pub fn triangle_pixel_area(tri: [Point; 3], px: u32, py: u32) -> f64 {
    let Some(orient) = triangle_orientation(&tri) else {
        return 0.0;
    };
    if square_inside_triangle(&tri, orient, px, py) {
        return 1.0;
    }
    let mut row = Vec::with_capacity(8);
    let mut scratch = Vec::with_capacity(8);
    clip_to_row(&tri, py, &mut row, &mut scratch);
    cell_area(&row, px, py, &mut scratch)
}

/// The fraction of each pixel of a `w` x `h` image that `tri` covers, row-major.
pub fn triangle_coverage(tri: [Point; 3], w: u32, h: u32) -> Vec<f64> {
    let mut out = vec![0.0; w as usize * h as usize];
    let Some(orient) = triangle_orientation(&tri) else {
        return out;
    };
    let (mut row, mut scratch) = (Vec::with_capacity(8), Vec::with_capacity(8));
    for py in pixel_span(tri.iter().map(|p| p[1]), h) {
        clip_to_row(&tri, py, &mut row, &mut scratch);
        // Only the columns the triangle reaches in this row.
        for px in pixel_span(row.iter().map(|p| p[0]), w) {
            out[py as usize * w as usize + px as usize] = if square_inside_triangle(&tri, orient, px, py) {
                1.0
            } else {
                cell_area(&row, px, py, &mut scratch)
            };
        }
    }
    out
}

/// The area of the simple polygon `poly` (either winding, convex or not) inside pixel
/// (px, py), in [0, 1]. For a triangle prefer [`triangle_pixel_area`], which also answers a
/// square wholly inside with exactly 1.
pub fn polygon_pixel_area(poly: &[Point], px: u32, py: u32) -> f64 {
    if poly.len() < 3 || poly.iter().flatten().any(|c| !c.is_finite()) {
        return 0.0;
    }
    let (mut row, mut scratch) = (Vec::with_capacity(poly.len() + 4), Vec::with_capacity(poly.len() + 4));
    clip_to_row(poly, py, &mut row, &mut scratch);
    cell_area(&row, px, py, &mut scratch)
}

/// The sign of the triangle's signed area (+1 or -1), or None if it covers nothing
/// (zero area, or a coordinate that is not finite).
fn triangle_orientation(tri: &[Point; 3]) -> Option<f64> {
    if tri.iter().flatten().any(|c| !c.is_finite()) {
        return None;
    }
    // The sign of the signed area, from the vertices scaled by a power of two (exact) when
    // the products of huge coordinates would overflow.
    let largest = tri.iter().flatten().fold(0.0f64, |m, c| m.max(c.abs()));
    let scale = if largest > 1e150 {
        2f64.powi(-(largest.log2().ceil() as i32))
    } else {
        1.0
    };
    let det = cross(
        tri[0].map(|c| c * scale),
        tri[1].map(|c| c * scale),
        tri[2].map(|c| c * scale),
    );
    (det != 0.0).then_some(det.signum())
}

/// (b - a) x (c - a): twice the signed area of the triangle a, b, c.
fn cross(a: Point, b: Point, c: Point) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
}

/// Whether all four corners of pixel (px, py) are inside the triangle (on an edge counts),
/// and so the whole square is.
fn square_inside_triangle(tri: &[Point; 3], orient: f64, px: u32, py: u32) -> bool {
    let (x, y) = (px as f64, py as f64);
    [[x, y], [x + 1.0, y], [x, y + 1.0], [x + 1.0, y + 1.0]]
        .into_iter()
        .all(|corner| (0..3).all(|i| orient * cross(tri[i], tri[(i + 1) % 3], corner) >= 0.0))
}

/// The pixels `lo..hi` (clipped to `0..size`) that the coordinate range of `coords` touches.
fn pixel_span(coords: impl Iterator<Item = f64> + Clone, size: u32) -> std::ops::Range<u32> {
    let lo = coords.clone().fold(f64::INFINITY, f64::min).floor().max(0.0);
    let hi = coords.fold(f64::NEG_INFINITY, f64::max).ceil().min(size as f64);
    // `as` saturates (an empty polygon gives lo = +inf, hi = -inf: an empty range).
    lo as u32..hi.max(lo) as u32
}

/// `row` := `poly` clipped to the strip py <= y <= py + 1.
fn clip_to_row(poly: &[Point], py: u32, row: &mut Vec<Point>, scratch: &mut Vec<Point>) {
    let y = py as f64;
    clip(poly, 1, y, true, scratch);
    clip(scratch, 1, y + 1.0, false, row);
}

/// The area of `row` (already clipped to pixel row py) inside pixel column px.
fn cell_area(row: &[Point], px: u32, py: u32, scratch: &mut Vec<Point>) -> f64 {
    let x = px as f64;
    let mut cell = Vec::with_capacity(row.len() + 2);
    clip(row, 0, x, true, scratch);
    clip(scratch, 0, x + 1.0, false, &mut cell);
    local_area(&cell, x, py as f64).min(1.0)
}

/// One Sutherland–Hodgman step: `out` := the part of `poly` where coordinate `axis` is
/// >= `c` (`keep_above`) or <= `c`.
fn clip(poly: &[Point], axis: usize, c: f64, keep_above: bool, out: &mut Vec<Point>) {
    out.clear();
    let inside = |p: &Point| if keep_above { p[axis] >= c } else { p[axis] <= c };
    let Some(mut prev) = poly.last() else { return };
    for cur in poly {
        match (inside(prev), inside(cur)) {
            (true, true) => out.push(*cur),
            (true, false) => out.push(crossing(*prev, *cur, axis, c)),
            (false, true) => {
                out.push(crossing(*prev, *cur, axis, c));
                out.push(*cur);
            }
            (false, false) => {}
        }
        prev = cur;
    }
}

/// Where the segment a-b crosses coordinate `axis` = `c` (a and b strictly on either side
/// or one on the line, so the division is by a nonzero number). Computed from the smaller
/// endpoint, so a-b and b-a give the same point, bit for bit.
fn crossing(a: Point, b: Point, axis: usize, c: f64) -> Point {
    let (p, q) = if (a[0], a[1]) <= (b[0], b[1]) { (a, b) } else { (b, a) };
    let other = 1 - axis;
    let t = (c - p[axis]) / (q[axis] - p[axis]);
    let mut hit = [0.0; 2];
    hit[axis] = c;
    // Kept on the segment where rounding (huge coordinates) would put it beyond.
    hit[other] = (p[other] + t * (q[other] - p[other])).clamp(p[other].min(q[other]), p[other].max(q[other]));
    hit
}

/// The (unsigned) shoelace area of `poly` taken about the origin (ox, oy): exact
/// subtractions for points of the pixel whose corner that is.
fn local_area(poly: &[Point], ox: f64, oy: f64) -> f64 {
    let Some(last) = poly.last() else { return 0.0 };
    let mut prev = [last[0] - ox, last[1] - oy];
    let mut twice = 0.0;
    for p in poly {
        let cur = [p[0] - ox, p[1] - oy];
        twice += prev[0] * cur[1] - cur[0] * prev[1];
        prev = cur;
    }
    (0.5 * twice).abs()
}

/// The area of the disc of radius `r` about `centre` inside pixel (px, py), in [0, 1].
pub fn disc_pixel_area(centre: Point, r: f64, px: u32, py: u32) -> f64 {
    if !(r > 0.0 && r.is_finite() && centre[0].is_finite() && centre[1].is_finite()) {
        return 0.0;
    }
    // The square relative to the centre (exact when the centre is within a factor two of
    // the corner; otherwise one rounding of a coordinate, which is what the inputs carry).
    let (x0, x1) = (px as f64 - centre[0], (px as f64 + 1.0) - centre[0]);
    let (y0, y1) = (py as f64 - centre[1], (py as f64 + 1.0) - centre[1]);
    let r2 = r * r;
    if [x0, x1]
        .into_iter()
        .all(|x| [y0, y1].into_iter().all(|y| x * x + y * y <= r2))
    {
        return 1.0;
    }
    disc_rect_area(r, [x0, x1], [y0, y1]).clamp(0.0, 1.0)
}

/// The fraction of each pixel of a `w` x `h` image that the disc covers, row-major.
pub fn disc_coverage(centre: Point, r: f64, w: u32, h: u32) -> Vec<f64> {
    let mut out = vec![0.0; w as usize * h as usize];
    if !(r > 0.0 && r.is_finite() && centre[0].is_finite() && centre[1].is_finite()) {
        return out;
    }
    for py in pixel_span([centre[1] - r, centre[1] + r].into_iter(), h) {
        for px in pixel_span([centre[0] - r, centre[0] + r].into_iter(), w) {
            out[py as usize * w as usize + px as usize] = disc_pixel_area(centre, r, px, py);
        }
    }
    out
}

/// The area of the disc of radius `r` about the origin inside [x0, x1] x [y0, y1]: the
/// integral over x of the chord [-s, s] (s = sqrt(r^2 - x^2)) clipped to [y0, y1]. Between
/// the x where the circle crosses y = y0 or y = y1, the clipped chord's top is either s or
/// y1 and its bottom -s or y0 throughout (or it is empty throughout), so each piece is a
/// closed form; which one is read off the piece's midpoint.
fn disc_rect_area(r: f64, [x0, x1]: [f64; 2], [y0, y1]: [f64; 2]) -> f64 {
    let (a, b) = (x0.max(-r), x1.min(r));
    if a >= b || y0 >= r || y1 <= -r || y0 >= y1 {
        return 0.0;
    }
    let mut xs = vec![a, b];
    for y in [y0, y1] {
        let y = y.abs();
        if y < r {
            let t = ((r - y) * (r + y)).sqrt();
            xs.extend([-t, t].into_iter().filter(|x| a < *x && *x < b));
        }
    }
    xs.sort_by(f64::total_cmp);
    let mut area = 0.0;
    for pair in xs.windows(2) {
        let (u, v) = (pair[0], pair[1]);
        if v <= u {
            continue;
        }
        let s = half_chord(r, 0.5 * (u + v));
        let (top_is_arc, bottom_is_arc) = (s < y1, -s > y0);
        if s.min(y1) <= (-s).max(y0) {
            continue;
        }
        let width = v - u;
        area += match (top_is_arc, bottom_is_arc) {
            (true, true) => 2.0 * chord_integral(r, u, v),
            (true, false) => chord_integral(r, u, v) - y0 * width,
            (false, true) => chord_integral(r, u, v) + y1 * width,
            (false, false) => (y1 - y0) * width,
        };
    }
    area
}

/// sqrt(r^2 - x^2), as (r - x)(r + x) to keep its digits near the rim.
fn half_chord(r: f64, x: f64) -> f64 {
    ((r - x) * (r + x)).max(0.0).sqrt()
}

/// The integral of sqrt(r^2 - x^2) over [u, v], -r <= u < v <= r: the antiderivative
/// (x s(x) + r^2 asin(x / r)) / 2 differenced in closed form. Both differences
/// (v s(v) - u s(u), and the angle's sine v s(u) - u s(v)) are rewritten with
/// s(u) - s(v) = (v - u)(v + u) / (s(u) + s(v)) when u and v have the same sign, where
/// they would otherwise cancel; with opposite signs their two terms have the same sign. The
/// angle is an atan2 of its sine and cosine (it may exceed pi / 2).
fn chord_integral(r: f64, u: f64, v: f64) -> f64 {
    let (su, sv) = (half_chord(r, u), half_chord(r, v));
    let (xs, sine) = if u >= 0.0 || v <= 0.0 {
        let q = u * (u + v) / (su + sv);
        ((v - u) * (sv - q), (v - u) * (su + q))
    } else {
        (v * sv - u * su, v * su - u * sv)
    };
    let angle = sine.atan2(su * sv + u * v);
    0.5 * (xs + r * r * angle)
}

/// How far a measured per-pixel coverage is from the exact one, over all pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoverageError {
    /// The worst pixel's |measured - exact| (NaN if any measured value is NaN).
    pub max_abs: f64,
    pub mean_abs: f64,
    /// Root mean square of the differences.
    pub rms: f64,
}

/// Compare a renderer's resolved coverage (one value in [0, 1] per pixel, box filter: the
/// fraction of the pixel's samples covered) with the exact coverage of the same image.
/// All zeros for empty images.
///
/// # Panics
/// If the two slices have different lengths (both must be the same `w * h` image).
pub fn box_resolved_error(coverage_ref: &[f64], coverage_measured: &[f64]) -> CoverageError {
    assert_eq!(
        coverage_ref.len(),
        coverage_measured.len(),
        "box_resolved_error: the exact and the measured coverage must be the same image"
    );
    let n = coverage_ref.len();
    if n == 0 {
        return CoverageError {
            max_abs: 0.0,
            mean_abs: 0.0,
            rms: 0.0,
        };
    }
    let (mut max_abs, mut sum, mut sum_sq) = (0.0f64, 0.0, 0.0);
    for (exact, measured) in coverage_ref.iter().zip(coverage_measured) {
        let d = (measured - exact).abs();
        // f64::max would drop a NaN; a NaN pixel must show.
        max_abs = if d.is_nan() || max_abs.is_nan() {
            f64::NAN
        } else {
            max_abs.max(d)
        };
        sum += d;
        sum_sq += d * d;
    }
    CoverageError {
        max_abs,
        mean_abs: sum / n as f64,
        rms: (sum_sq / n as f64).sqrt(),
    }
}
