//! Image textures for shaders: the language's `texture("file.png", s, t)`. A [`TextureSet`]
//! loads each image once (PNG, through the `image` crate), keeps it as RGB `f32` texels with
//! a mip chain, and filters lookups bilinearly in one level or trilinearly between two;
//! compiled kernels reach it through [`primflow_texture`], once per group of 4 lanes.
//!
//! Texel values: the image's red, green and blue channels scaled to [0, 1] (8-bit samples
//! divided by 255, 16-bit by 65535), as stored: no colour-space conversion (an sRGB image
//! is not linearised). A grey image gives three equal channels; alpha is ignored.
//! [`TextureSet::insert`] takes texels directly, finite and at most 1e30 in magnitude.
//!
//! Coordinates: `s` runs left to right, `t` top to bottom (t = 0 is the image's first row).
//! Texel (i, j) of a w x h level covers s in [i/w, (i+1)/w) and t in [j/h, (j+1)/h); its
//! centre is ((i + 0.5)/w, (j + 0.5)/h).
//!
//! Bilinear lookup in a level of size (w, h): u = s*w - 0.5 and v = t*h - 0.5 (f32),
//! i0 = floor(u), fu = u - i0, j0 = floor(v), fv = v - j0. The four texels (i0, j0),
//! (i0+1, j0), (i0, j0+1), (i0+1, j0+1) have their indices passed through the [`Wrap`] mode
//! (index arithmetic in i64, floor(u) clamped to +-2^62 first; an s*w that overflows to
//! infinity takes that clamp with fu = 0):
//! - `periodic`: index mod size (Euclidean, so -1 -> size-1);
//! - `clamp`: the index clamped to [0, size-1];
//! - `mirror`: the image reflected at its edges (period 2*size: -1 -> 0, size -> size-1);
//! - `black`: a texel outside [0, size) reads as black (0, 0, 0).
//!
//! With gu = 1 - fu and gv = 1 - fv, each channel is
//! `(c00*(gu*gv) + c10*(fu*gv)) + (c01*(gu*fv) + c11*(fu*fv))`, evaluated in that order in
//! f32. At a texel centre this is the texel exactly. An `s` or `t` that is NaN or infinite
//! gives (0, 0, 0).
//!
//! Mip chain: level 0 is the image; level k+1 has size (max(1, w/2), max(1, h/2)) (integer
//! division) down to 1 x 1, and its texel (i, j) averages the texels a = (2i, 2j),
//! b = (2i+1, 2j), c = (2i, 2j+1), d = (2i+1, 2j+1) of level k, each index clamped to level
//! k's size, as `((a + b) + (c + d)) * 0.25` per channel in f32. So on an axis of size 1 the
//! same texel is averaged twice, and on an odd axis the last column (row) does not reach the
//! next level (5 columns average in pairs to 2).
//!
//! Level of detail: with (w, h) the size of level 0, the footprint along x is
//! Lx = sqrt((dsdx*w)^2 + (dtdx*h)^2), along y Ly = sqrt((dsdy*w)^2 + (dtdy*h)^2), and
//! rho = max(Lx, Ly). lod = log2(rho) clamped to [0, levels-1]; rho <= 0 or any NaN
//! derivative gives 0, an infinite rho gives levels-1.
//!
//! Sampling ([`TextureSet::sample`]): an integral lod (0 included: zero derivatives) reads
//! that one level bilinearly, so with zero derivatives `sample` equals `bilinear` in level 0
//! bit for bit. Otherwise, with l0 = floor(lod) and f = lod - l0, the result mixes
//! a = bilinear(l0) and b = bilinear(min(l0+1, levels-1)) as `a + (b - a) * f` per channel.
//!
//! Invariants:
//! - Never panics on any input: an unknown texture id or level reads (0, 0, 0), and loading
//!   reports every failure as a [`TextureError`] naming the file. Finite arguments give
//!   finite colours.
//! - Deterministic f32 arithmetic: the same inputs give the same bits on every run (the
//!   operation order above; no fused multiply-add, no parallelism inside a lookup). `sqrt`
//!   is correctly rounded; `log2` is the platform's, so a lod may differ in its last bit
//!   between platforms (powers of two are exact).
//! - Memory bounded: the decoded texels of all textures, all levels together (12 bytes a
//!   texel), stay within the `limit` given to [`TextureSet::load`] / [`TextureSet::insert`]
//!   (normally [`TEXTURE_MEMORY_LIMIT`]). A PNG's declared size is checked from its header
//!   before any texel is decoded, and the decoder's own allocations are capped through
//!   `image::Limits` (the budget left plus 16 MiB); while a file loads, its image in the
//!   file's own sample format (at most 8 bytes a texel) is held beside its f32 texels.

use std::fmt;
use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageDecoder, ImageError, ImageReader};

/// Decoded texels of all loaded textures, all mip levels together, at most this many bytes.
pub const TEXTURE_MEMORY_LIMIT: usize = 256 << 20;

/// Bytes a texel takes: three `f32` channels.
const TEXEL_BYTES: u128 = 12;

/// What the PNG decoder may allocate beyond the texel budget left (its row buffers, the
/// inflate window, metadata chunks): it decodes into at most 8 bytes a pixel, fewer than the
/// 12 a texel takes once converted.
const DECODER_HEADROOM: u64 = 16 << 20;

/// Largest texel magnitude [`TextureSet::insert`] takes: four of them add up without
/// overflowing `f32`, so filtering stays finite.
const TEXEL_MAX: f32 = 1e30;

/// Bound on floor(u) before index arithmetic: i0 + 1 and the mirror period stay in i64.
const INDEX_LIMIT: i64 = 1 << 62;

const BLACK: [f32; 3] = [0.0; 3];

/// How a lookup treats texel indices outside the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum Wrap {
    /// The image repeats: index mod size.
    Periodic = 0,
    /// The edge texels extend outwards.
    Clamp = 1,
    /// Outside the image is black.
    Black = 2,
    /// The image repeats reflected: period twice its size.
    Mirror = 3,
}

impl Wrap {
    /// The language's names, in discriminant order.
    pub const NAMES: [&'static str; 4] = ["periodic", "clamp", "black", "mirror"];

    /// The mode of a language name (exact, lower case); None if unknown.
    pub fn from_name(name: &str) -> Option<Wrap> {
        match name {
            "periodic" => Some(Wrap::Periodic),
            "clamp" => Some(Wrap::Clamp),
            "black" => Some(Wrap::Black),
            "mirror" => Some(Wrap::Mirror),
            _ => None,
        }
    }

    /// The mode of a discriminant; anything unknown is `Periodic`.
    pub fn from_u32(v: u32) -> Wrap {
        match v {
            1 => Wrap::Clamp,
            2 => Wrap::Black,
            3 => Wrap::Mirror,
            _ => Wrap::Periodic,
        }
    }

    /// Index `k` on an axis of `n` texels (n >= 1), or None for black.
    fn index(self, k: i64, n: i64) -> Option<usize> {
        let k = match self {
            Wrap::Periodic => k.rem_euclid(n),
            Wrap::Clamp => k.clamp(0, n - 1),
            Wrap::Mirror => {
                let m = k.rem_euclid(2 * n);
                if m < n {
                    m
                } else {
                    2 * n - 1 - m
                }
            }
            Wrap::Black => {
                if (0..n).contains(&k) {
                    k
                } else {
                    return None;
                }
            }
        };
        usize::try_from(k).ok()
    }
}

/// A texture that could not be loaded or inserted, with the file (or name) it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureError {
    pub path: PathBuf,
    pub message: String,
}

impl fmt::Display for TextureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "texture `{}`: {}", self.path.display(), self.message)
    }
}

impl std::error::Error for TextureError {}

/// One mip level: `width * height` texels, row-major, three channels each.
struct Level {
    width: u32,
    height: u32,
    texels: Vec<f32>,
}

impl fmt::Debug for Level {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Level({}x{})", self.width, self.height)
    }
}

impl Level {
    /// Texel (i, j), or black for a missing index.
    fn texel(&self, i: Option<usize>, j: Option<usize>) -> [f32; 3] {
        let (Some(i), Some(j)) = (i, j) else { return BLACK };
        let at = (j * self.width as usize + i) * 3;
        match self.texels.get(at..at + 3) {
            Some(&[r, g, b]) => [r, g, b],
            _ => BLACK,
        }
    }

    fn bilinear(&self, wrap: Wrap, s: f32, t: f32) -> [f32; 3] {
        if !(s.is_finite() && t.is_finite()) {
            return BLACK;
        }
        let (i0, fu) = split(s * self.width as f32 - 0.5);
        let (j0, fv) = split(t * self.height as f32 - 0.5);
        let (w, h) = (i64::from(self.width), i64::from(self.height));
        let (x0, x1) = (wrap.index(i0, w), wrap.index(i0 + 1, w));
        let (y0, y1) = (wrap.index(j0, h), wrap.index(j0 + 1, h));
        let (c00, c10) = (self.texel(x0, y0), self.texel(x1, y0));
        let (c01, c11) = (self.texel(x0, y1), self.texel(x1, y1));
        let (gu, gv) = (1.0 - fu, 1.0 - fv);
        let (w00, w10, w01, w11) = (gu * gv, fu * gv, gu * fv, fu * fv);
        std::array::from_fn(|c| (c00[c] * w00 + c10[c] * w10) + (c01[c] * w01 + c11[c] * w11))
    }

    /// The next level down: half the size (at least 1), 2x2 averages.
    fn reduce(&self) -> Level {
        let (w, h) = (self.width, self.height);
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let mut texels = Vec::with_capacity(nw as usize * nh as usize * 3);
        for j in 0..nh {
            let (ja, jb) = (Some((2 * j).min(h - 1) as usize), Some((2 * j + 1).min(h - 1) as usize));
            for i in 0..nw {
                let (ia, ib) = (Some((2 * i).min(w - 1) as usize), Some((2 * i + 1).min(w - 1) as usize));
                let (a, b) = (self.texel(ia, ja), self.texel(ib, ja));
                let (c, d) = (self.texel(ia, jb), self.texel(ib, jb));
                for k in 0..3 {
                    texels.push(((a[k] + b[k]) + (c[k] + d[k])) * 0.25);
                }
            }
        }
        Level {
            width: nw,
            height: nh,
            texels,
        }
    }
}

/// floor(u) as a bounded i64 and the fraction u - floor(u).
fn split(u: f32) -> (i64, f32) {
    if !u.is_finite() {
        return (if u > 0.0 { INDEX_LIMIT } else { -INDEX_LIMIT }, 0.0);
    }
    let floor = u.floor();
    ((floor as i64).clamp(-INDEX_LIMIT, INDEX_LIMIT), u - floor)
}

/// Texels in the whole chain of a `width` x `height` image.
fn chain_texels(width: u32, height: u32) -> u128 {
    let (mut w, mut h) = (width.max(1), height.max(1));
    let mut total = u128::from(w) * u128::from(h);
    while w > 1 || h > 1 {
        (w, h) = ((w / 2).max(1), (h / 2).max(1));
        total += u128::from(w) * u128::from(h);
    }
    total
}

/// A byte count for messages: whole MiB, MiB to two decimals, or bytes below 1 MiB.
fn describe_bytes(bytes: u128) -> String {
    const MIB: u128 = 1 << 20;
    if bytes > 0 && bytes.is_multiple_of(MIB) {
        format!("{} MiB", bytes / MIB)
    } else if bytes >= MIB {
        format!("{:.2} MiB", bytes as f64 / MIB as f64)
    } else {
        format!("{bytes} bytes")
    }
}

/// What went wrong decoding, in words.
fn describe_image_error(error: ImageError) -> String {
    match error {
        ImageError::Limits(e) => format!("decoding it would exceed the memory limit ({e})"),
        ImageError::IoError(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            format!("not a decodable image: the file ends early ({e})")
        }
        ImageError::IoError(e) => format!("cannot read the file: {e}"),
        e => format!("not a decodable image: {e}"),
    }
}

#[derive(Debug)]
struct Texture {
    /// The file it was loaded from, or the name it was inserted under.
    path: PathBuf,
    /// Loaded by [`TextureSet::load`] (so a later load of the same path reuses it).
    from_file: bool,
    /// Level 0 first, down to 1 x 1; never empty.
    levels: Vec<Level>,
}

/// The textures a render's shaders read, each with its mip chain, addressed by id (0, 1, ...
/// in the order they were first loaded or inserted).
#[derive(Default, Debug)]
pub struct TextureSet {
    textures: Vec<Texture>,
    /// Bytes of all levels of all textures.
    bytes: usize,
}

impl TextureSet {
    pub fn new() -> TextureSet {
        TextureSet::default()
    }

    /// Load `path` unless a texture of the same path (as given, not canonicalised) is
    /// already loaded; its id (0, 1, ...). Errors, all naming the file: missing or
    /// unreadable, not a decodable image (corrupt, truncated, not PNG), zero-sized, and the
    /// set's total bytes (all levels, 12 bytes a texel) would exceed `limit`. The size is
    /// checked from the image header, before the texels are decoded.
    pub fn load(&mut self, path: &Path, limit: usize) -> Result<u32, TextureError> {
        if let Some(id) = self.textures.iter().position(|t| t.from_file && t.path == path) {
            return Ok(id as u32);
        }
        let error = |message: String| TextureError {
            path: path.to_path_buf(),
            message,
        };
        let mut limits = image::Limits::default();
        let left = limit.saturating_sub(self.bytes) as u64;
        limits.max_alloc = Some(left.saturating_add(DECODER_HEADROOM));
        let mut reader = ImageReader::open(path).map_err(|e| error(format!("cannot open the file: {e}")))?;
        reader.limits(limits);
        let reader = reader
            .with_guessed_format()
            .map_err(|e| error(format!("cannot read the file: {e}")))?;
        let decoder = reader.into_decoder().map_err(|e| error(describe_image_error(e)))?;
        let (width, height) = decoder.dimensions();
        self.check_room(width, height, limit).map_err(error)?;
        let image = DynamicImage::from_decoder(decoder).map_err(|e| error(describe_image_error(e)))?;
        let texels = image.into_rgb32f().into_raw();
        if texels.len() as u128 != u128::from(width) * u128::from(height) * 3 {
            return Err(error(format!(
                "the decoder gave {} values for {width}x{height} texels",
                texels.len()
            )));
        }
        Ok(self.push(path.to_path_buf(), true, Level { width, height, texels }))
    }

    /// A texture from texels given directly (row-major, row 0 = t in [0, 1/h)), for tests
    /// and generated images; same limit check. Always a new id, even for a name seen before.
    /// Errors: width or height 0, `texels.len() != width * height`, a texel channel not
    /// finite or above 1e30 in magnitude.
    pub fn insert(
        &mut self,
        name: &str,
        width: u32,
        height: u32,
        texels: Vec<[f32; 3]>,
        limit: usize,
    ) -> Result<u32, TextureError> {
        let error = |message: String| TextureError {
            path: PathBuf::from(name),
            message,
        };
        if texels.len() as u128 != u128::from(width) * u128::from(height) {
            return Err(error(format!("{} texels given for {width}x{height}", texels.len())));
        }
        self.check_room(width, height, limit).map_err(error)?;
        if let Some(at) = texels
            .iter()
            .position(|t| t.iter().any(|v| !v.is_finite() || v.abs() > TEXEL_MAX))
        {
            let (i, j) = (at % width as usize, at / width as usize);
            return Err(error(format!(
                "texel ({i}, {j}) is not finite or exceeds 1e30 in magnitude"
            )));
        }
        let texels = texels.into_flattened();
        Ok(self.push(PathBuf::from(name), false, Level { width, height, texels }))
    }

    /// A new texture of level 0 `width` x `height` fits: not zero-sized, within `limit`, an id
    /// left.
    fn check_room(&self, width: u32, height: u32, limit: usize) -> Result<(), String> {
        if width == 0 || height == 0 {
            return Err(format!("the image is zero-sized ({width}x{height})"));
        }
        if self.textures.len() >= u32::MAX as usize {
            return Err("too many textures".to_string());
        }
        let need = self.bytes as u128 + chain_texels(width, height) * TEXEL_BYTES;
        if need > limit as u128 {
            return Err(format!(
                "the textures would need {}, more than the limit of {}",
                describe_bytes(need),
                describe_bytes(limit as u128)
            ));
        }
        Ok(())
    }

    /// Adds a texture with its mip chain built from `base`; its id.
    fn push(&mut self, path: PathBuf, from_file: bool, base: Level) -> u32 {
        let mut levels = vec![base];
        while let Some(last) = levels.last().filter(|l| l.width > 1 || l.height > 1) {
            let next = last.reduce();
            levels.push(next);
        }
        self.bytes += levels.iter().map(|l| l.texels.len() * 4).sum::<usize>();
        self.textures.push(Texture {
            path,
            from_file,
            levels,
        });
        (self.textures.len() - 1) as u32
    }

    /// Textures held.
    pub fn len(&self) -> usize {
        self.textures.len()
    }

    pub fn is_empty(&self) -> bool {
        self.textures.is_empty()
    }

    /// Bytes held (all textures, all levels).
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    /// (width, height) of mip level `level` of texture `id`; None if out of range.
    pub fn level_size(&self, id: u32, level: usize) -> Option<(u32, u32)> {
        self.level(id, level).map(|l| (l.width, l.height))
    }

    /// Mip levels of texture `id` (level 0 included); 0 for an unknown id.
    pub fn levels(&self, id: u32) -> usize {
        self.texture(id).map_or(0, |t| t.levels.len())
    }

    fn texture(&self, id: u32) -> Option<&Texture> {
        self.textures.get(id as usize)
    }

    fn level(&self, id: u32, level: usize) -> Option<&Level> {
        self.texture(id)?.levels.get(level)
    }

    /// The filtered colour at (s, t) for a footprint whose screen derivatives are
    /// (dsdx, dtdx) along x and (dsdy, dtdy) along y: bilinear in one level for an integral
    /// lod, else trilinear between two. (0, 0, 0) for an unknown id.
    #[allow(clippy::too_many_arguments)]
    pub fn sample(&self, id: u32, wrap: Wrap, s: f32, t: f32, dsdx: f32, dtdx: f32, dsdy: f32, dtdy: f32) -> [f32; 3] {
        let Some(texture) = self.texture(id) else { return BLACK };
        let lod = lod_of(texture, dsdx, dtdx, dsdy, dtdy);
        let floor = lod.floor();
        let (l0, f) = (floor as usize, lod - floor);
        let Some(level) = texture.levels.get(l0) else {
            return BLACK;
        };
        let a = level.bilinear(wrap, s, t);
        if f == 0.0 {
            return a;
        }
        let Some(next) = texture.levels.get(l0 + 1).or(texture.levels.last()) else {
            return a;
        };
        let b = next.bilinear(wrap, s, t);
        std::array::from_fn(|c| a[c] + (b[c] - a[c]) * f)
    }

    /// Bilinear lookup in one level (public for tests); (0, 0, 0) for an unknown id or level.
    pub fn bilinear(&self, id: u32, level: usize, wrap: Wrap, s: f32, t: f32) -> [f32; 3] {
        self.level(id, level).map_or(BLACK, |l| l.bilinear(wrap, s, t))
    }

    /// The level of detail `sample` uses for these derivatives (public for tests); 0 for an
    /// unknown id.
    pub fn lod(&self, id: u32, dsdx: f32, dtdx: f32, dsdy: f32, dtdy: f32) -> f32 {
        self.texture(id).map_or(0.0, |t| lod_of(t, dsdx, dtdx, dsdy, dtdy))
    }
}

/// log2 of the longer footprint axis in level-0 texels, clamped to the chain.
fn lod_of(texture: &Texture, dsdx: f32, dtdx: f32, dsdy: f32, dtdy: f32) -> f32 {
    let Some(base) = texture.levels.first() else { return 0.0 };
    let (w, h) = (base.width as f32, base.height as f32);
    let (ax, bx, ay, by) = (dsdx * w, dtdx * h, dsdy * w, dtdy * h);
    let lx = (ax * ax + bx * bx).sqrt();
    let ly = (ay * ay + by * by).sqrt();
    if lx.is_nan() || ly.is_nan() {
        return 0.0;
    }
    let top = texture.levels.len().saturating_sub(1) as f32;
    let rho = lx.max(ly);
    if rho <= 0.0 {
        0.0
    } else if rho.is_infinite() {
        top
    } else {
        rho.log2().clamp(0.0, top)
    }
}

/// What compiled kernels call, once per group of 4 lanes. `args` points at 24 f32: the 4
/// lanes of s, then of t, dsdx, dtdx, dsdy, dtdy; `out` at 12 f32: the 4 lanes of red, then
/// green, then blue. Each lane is [`TextureSet::sample`] with wrap [`Wrap::from_u32`]`(wrap)`.
/// A null `set` (or null `args`) or an unknown `id` writes 0s; a null `out` writes nothing.
///
/// # Safety
/// `set` is null or points at a live `TextureSet`; `args` and `out` are null or valid for
/// reading 24 / writing 12 `f32` (no alignment needed).
pub unsafe extern "C" fn primflow_texture(set: *const TextureSet, id: u32, wrap: u32, args: *const f32, out: *mut f32) {
    if out.is_null() {
        return;
    }
    let mut colours = [0.0f32; 12];
    // SAFETY: the caller passes null or a live set.
    if let (Some(set), false) = (unsafe { set.as_ref() }, args.is_null()) {
        let mut a = [0.0f32; 24];
        for (k, v) in a.iter_mut().enumerate() {
            // SAFETY: `args` is valid for 24 f32.
            *v = unsafe { args.add(k).read_unaligned() };
        }
        let wrap = Wrap::from_u32(wrap);
        for lane in 0..4 {
            let arg = |k: usize| a[4 * k + lane];
            let c = set.sample(id, wrap, arg(0), arg(1), arg(2), arg(3), arg(4), arg(5));
            (colours[lane], colours[4 + lane], colours[8 + lane]) = (c[0], c[1], c[2]);
        }
    }
    for (k, v) in colours.into_iter().enumerate() {
        // SAFETY: `out` is valid for 12 f32.
        unsafe { out.add(k).write_unaligned(v) };
    }
}
