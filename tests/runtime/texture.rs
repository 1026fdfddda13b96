//! Image textures (src/runtime/texture.rs): PNG loading against an f64 bilinear reference,
//! the wrap modes, the mip chain and its level of detail, trilinear mixing, load errors that
//! name the file, the memory limit checked before decoding, and the kernels' 4-lane entry.

use std::path::PathBuf;

use image::{ImageBuffer, Luma, Rgb, RgbImage, Rgba, RgbaImage};
use primflow::runtime::texture::{primflow_texture, TextureSet, Wrap, TEXTURE_MEMORY_LIMIT};

const WRAPS: [Wrap; 4] = [Wrap::Periodic, Wrap::Clamp, Wrap::Black, Wrap::Mirror];

/// A file under the temp directory, unique to this process and test.
fn temp_path(tag: &str) -> PathBuf {
    std::env::temp_dir().join(format!("primflow-texture-{tag}-{}.png", std::process::id()))
}

/// The 4x2 test image's 8-bit value of texel (i, j), channel c: all 24 distinct.
fn value(i: u32, j: u32, c: u32) -> u8 {
    (10 + 30 * i + 100 * j + 7 * c) as u8
}

fn write_4x2(tag: &str) -> PathBuf {
    let path = temp_path(tag);
    let image = RgbImage::from_fn(4, 2, |i, j| Rgb([value(i, j, 0), value(i, j, 1), value(i, j, 2)]));
    image.save(&path).expect("write the test PNG");
    path
}

/// The texel index `k` on an axis of `n` under `wrap`, independently of the module.
fn wrap_ref(wrap: Wrap, k: i64, n: i64) -> Option<i64> {
    match wrap {
        Wrap::Periodic => Some(((k % n) + n) % n),
        Wrap::Clamp => Some(k.max(0).min(n - 1)),
        Wrap::Black => (k >= 0 && k < n).then_some(k),
        Wrap::Mirror => {
            let m = ((k % (2 * n)) + 2 * n) % (2 * n);
            Some(if m < n { m } else { 2 * n - 1 - m })
        }
    }
}

/// Bilinear filtering in f64 over the 4x2 image's values / 255.
fn bilinear_ref(wrap: Wrap, s: f64, t: f64) -> [f64; 3] {
    let (w, h) = (4i64, 2i64);
    let (u, v) = (s * w as f64 - 0.5, t * h as f64 - 0.5);
    let (i0, j0) = (u.floor(), v.floor());
    let (fu, fv) = (u - i0, v - j0);
    let mut out = [0.0; 3];
    for (di, wu) in [(0, 1.0 - fu), (1, fu)] {
        for (dj, wv) in [(0, 1.0 - fv), (1, fv)] {
            let (Some(i), Some(j)) = (wrap_ref(wrap, i0 as i64 + di, w), wrap_ref(wrap, j0 as i64 + dj, h)) else {
                continue;
            };
            for (c, o) in out.iter_mut().enumerate() {
                *o += wu * wv * value(i as u32, j as u32, c as u32) as f64 / 255.0;
            }
        }
    }
    out
}

#[test]
fn png_bilinear_matches_f64_reference() {
    let path = write_4x2("bilinear");
    let mut set = TextureSet::new();
    let id = set.load(&path, TEXTURE_MEMORY_LIMIT).expect("load the 4x2 PNG");
    let _ = std::fs::remove_file(&path);
    assert_eq!(id, 0);
    assert_eq!((set.len(), set.levels(id)), (1, 3));
    assert_eq!(set.level_size(id, 0), Some((4, 2)));

    // Texel centres give the texel exactly, in every wrap mode; row 0 is t in [0, 1/2).
    for wrap in WRAPS {
        for j in 0..2 {
            for i in 0..4 {
                let (s, t) = ((i as f32 + 0.5) / 4.0, (j as f32 + 0.5) / 2.0);
                let want: [f32; 3] = std::array::from_fn(|c| value(i, j, c as u32) as f32 / 255.0);
                assert_eq!(set.bilinear(id, 0, wrap, s, t), want, "{wrap:?} at texel ({i}, {j})");
            }
        }
    }

    // Off-centre points, inside and outside [0, 1], against the f64 reference.
    let points = [
        (0.1, 0.3),
        (0.37, 0.81),
        (0.0, 0.0),
        (0.99, 0.99),
        (1.0, 0.5),
        (0.5, 1.0),
        (-0.2, 0.4),
        (1.3, -0.6),
        (-1.7, 2.2),
        (2.05, 1.1),
        (5.6, -3.3),
        (-0.05, 0.7),
    ];
    for wrap in WRAPS {
        for (s, t) in points {
            let got = set.bilinear(id, 0, wrap, s, t);
            let want = bilinear_ref(wrap, s as f64, t as f64);
            for c in 0..3 {
                assert!(
                    (got[c] as f64 - want[c]).abs() < 1e-6,
                    "{wrap:?} at ({s}, {t}): {got:?} vs {want:?}"
                );
            }
        }
    }

    // The modes differ outside the image: left of texel 0's centre by a whole texel.
    let (s, t) = (-0.125, 0.25);
    let texel = |i: u32| -> [f32; 3] { std::array::from_fn(|c| value(i, 0, c as u32) as f32 / 255.0) };
    assert_eq!(set.bilinear(id, 0, Wrap::Periodic, s, t), texel(3));
    assert_eq!(set.bilinear(id, 0, Wrap::Clamp, s, t), texel(0));
    assert_eq!(set.bilinear(id, 0, Wrap::Mirror, s, t), texel(0));
    assert_eq!(set.bilinear(id, 0, Wrap::Black, s, t), [0.0; 3]);
    assert_eq!(set.bilinear(id, 0, Wrap::Mirror, -0.375, t), texel(1));
    assert_eq!(set.bilinear(id, 0, Wrap::Periodic, 1.125, t), texel(0));
    assert_eq!(set.bilinear(id, 0, Wrap::Mirror, 1.125, t), texel(3));
}

#[test]
fn non_finite_and_huge_coordinates() {
    let path = write_4x2("huge");
    let mut set = TextureSet::new();
    let id = set.load(&path, TEXTURE_MEMORY_LIMIT).expect("load the 4x2 PNG");
    let _ = std::fs::remove_file(&path);
    for wrap in WRAPS {
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(set.bilinear(id, 0, wrap, bad, 0.5), [0.0; 3]);
            assert_eq!(set.bilinear(id, 0, wrap, 0.5, bad), [0.0; 3]);
            assert_eq!(set.sample(id, wrap, bad, 0.5, 0.1, 0.0, 0.0, 0.1), [0.0; 3]);
        }
        let extremes = [0.0, 1e-45, -0.3, 1e7, -1e7, 1e30, -1e30, f32::MAX, f32::MIN];
        for &s in &extremes {
            for &t in &extremes {
                for &d in &extremes {
                    let c = set.sample(id, wrap, s, t, d, -d, d * 0.5, d);
                    assert!(c.iter().all(|v| v.is_finite()), "{wrap:?} ({s}, {t}) d {d}: {c:?}");
                }
            }
        }
    }
    // Unknown ids and levels read black.
    assert_eq!(set.bilinear(7, 0, Wrap::Clamp, 0.5, 0.5), [0.0; 3]);
    assert_eq!(set.bilinear(id, 3, Wrap::Clamp, 0.5, 0.5), [0.0; 3]);
    assert_eq!(set.sample(7, Wrap::Clamp, 0.5, 0.5, 0.0, 0.0, 0.0, 0.0), [0.0; 3]);
    assert_eq!(
        (set.levels(7), set.level_size(7, 0), set.lod(7, 1.0, 1.0, 1.0, 1.0)),
        (0, None, 0.0)
    );
}

#[test]
fn grey_sixteen_bit_and_alpha_pngs() {
    // 16-bit grey: equal channels, value / 65535.
    let grey_path = temp_path("grey16");
    let grey: ImageBuffer<Luma<u16>, Vec<u16>> = ImageBuffer::from_raw(2, 1, vec![0, 30000]).expect("2x1 grey");
    grey.save(&grey_path).expect("write the grey PNG");
    // RGBA: alpha ignored.
    let rgba_path = temp_path("rgba");
    RgbaImage::from_pixel(1, 1, Rgba([51, 102, 204, 0]))
        .save(&rgba_path)
        .expect("write the RGBA PNG");

    let mut set = TextureSet::new();
    let g = set.load(&grey_path, TEXTURE_MEMORY_LIMIT).expect("load the grey PNG");
    let a = set.load(&rgba_path, TEXTURE_MEMORY_LIMIT).expect("load the RGBA PNG");
    let _ = std::fs::remove_file(&grey_path);
    let _ = std::fs::remove_file(&rgba_path);
    assert_eq!((g, a), (0, 1));
    assert_eq!(set.bilinear(g, 0, Wrap::Clamp, 0.25, 0.5), [0.0; 3]);
    assert_eq!(set.bilinear(g, 0, Wrap::Clamp, 0.75, 0.5), [30000.0 / 65535.0; 3]);
    assert_eq!(
        set.bilinear(a, 0, Wrap::Clamp, 0.5, 0.5),
        [51.0 / 255.0, 102.0 / 255.0, 204.0 / 255.0]
    );
}

#[test]
fn mip_chain_sizes_and_averages() {
    // 5x3 texels of small integers, so every average below is exact in f32.
    let texel = |i: u32, j: u32| [(i + 10 * j) as f32, (2 * i * j) as f32, 50.0 - 3.0 * i as f32];
    let texels: Vec<[f32; 3]> = (0..3).flat_map(|j| (0..5).map(move |i| texel(i, j))).collect();
    let mut set = TextureSet::new();
    let id = set
        .insert("five-by-three", 5, 3, texels, TEXTURE_MEMORY_LIMIT)
        .expect("insert 5x3");
    assert_eq!(set.levels(id), 3);
    let sizes: Vec<_> = (0..4).map(|l| set.level_size(id, l)).collect();
    assert_eq!(sizes, [Some((5, 3)), Some((2, 1)), Some((1, 1)), None]);
    assert_eq!(set.bytes(), (15 + 2 + 1) * 12);

    // Level 1 texel (i, 0) averages texels (2i, 0), (2i+1, 0), (2i, 1), (2i+1, 1); column 4
    // and row 2 do not reach it. By hand:
    //   (0, 0): red (0 + 1 + 10 + 11) / 4 = 5.5, green (0 + 0 + 0 + 2) / 4 = 0.5,
    //           blue (50 + 47 + 50 + 47) / 4 = 48.5
    //   (1, 0): red (2 + 3 + 12 + 13) / 4 = 7.5, green (0 + 0 + 4 + 6) / 4 = 2.5,
    //           blue (44 + 41 + 44 + 41) / 4 = 42.5
    let level1 = [[5.5, 0.5, 48.5], [7.5, 2.5, 42.5]];
    for wrap in WRAPS {
        assert_eq!(set.bilinear(id, 1, wrap, 0.25, 0.5), level1[0]);
        assert_eq!(set.bilinear(id, 1, wrap, 0.75, 0.5), level1[1]);
        // Level 2 averages level 1's two texels, each twice (its one row clamped).
        assert_eq!(set.bilinear(id, 2, wrap, 0.5, 0.5), [6.5, 1.5, 45.5]);
    }
    // Halfway between level 1's texels (clamp: no wrap-around), the mean of the two.
    assert_eq!(set.bilinear(id, 1, Wrap::Clamp, 0.5, 0.5), [6.5, 1.5, 45.5]);
}

/// A 16x16 texture of values in [0, 1] that differ from texel to texel.
fn sixteen(set: &mut TextureSet) -> u32 {
    let texels: Vec<[f32; 3]> = (0..16u32)
        .flat_map(|j| {
            (0..16u32).map(move |i| {
                let k = (i * 7 + j * 13) % 23;
                [k as f32 / 23.0, ((i ^ j) & 15) as f32 / 15.0, (i * j) as f32 / 225.0]
            })
        })
        .collect();
    set.insert("sixteen", 16, 16, texels, TEXTURE_MEMORY_LIMIT)
        .expect("insert 16x16")
}

#[test]
fn lod_and_trilinear_16x16() {
    let mut set = TextureSet::new();
    let id = sixteen(&mut set);
    assert_eq!(set.levels(id), 5);
    let d = |texels: f32| texels / 16.0;
    assert_eq!(set.lod(id, d(1.0), 0.0, 0.0, d(1.0)), 0.0);
    assert_eq!(set.lod(id, d(2.0), 0.0, 0.0, d(2.0)), 1.0);
    assert_eq!(set.lod(id, d(4.0), 0.0, 0.0, d(4.0)), 2.0);
    // The longer axis decides; signs do not matter; t derivatives count as much as s.
    assert_eq!(set.lod(id, d(2.0), 0.0, 0.0, d(1.0)), 1.0);
    assert_eq!(set.lod(id, 0.0, -d(4.0), d(1.0), 0.0), 2.0);
    // Clamped to [0, levels-1]; zero, NaN and infinite footprints.
    assert_eq!(set.lod(id, d(0.25), 0.0, 0.0, d(0.25)), 0.0);
    assert_eq!(set.lod(id, 1e3, 0.0, 0.0, 1e3), 4.0);
    assert_eq!(set.lod(id, 0.0, 0.0, 0.0, 0.0), 0.0);
    assert_eq!(set.lod(id, f32::NAN, 0.0, 0.0, d(4.0)), 0.0);
    assert_eq!(set.lod(id, f32::INFINITY, 0.0, 0.0, 0.0), 4.0);
    assert_eq!(set.lod(id, 1e30, 0.0, 0.0, 0.0), 4.0);

    let points = [(0.5, 0.5), (0.13, 0.77), (0.031, 0.96), (-0.4, 1.7), (0.999, 0.001)];
    for wrap in WRAPS {
        for (s, t) in points {
            // Zero derivatives: level 0 bilinear, bit for bit.
            let base = set.bilinear(id, 0, wrap, s, t);
            assert_eq!(
                set.sample(id, wrap, s, t, 0.0, 0.0, 0.0, 0.0).map(f32::to_bits),
                base.map(f32::to_bits)
            );
            // lod exactly 1: level 1 bilinear, bit for bit.
            let one = set.bilinear(id, 1, wrap, s, t);
            let got = set.sample(id, wrap, s, t, d(2.0), 0.0, 0.0, d(2.0));
            assert_eq!(got.map(f32::to_bits), one.map(f32::to_bits), "{wrap:?} ({s}, {t})");
            // lod 1.5: halfway between levels 1 and 2.
            let half = d(2f32.powf(1.5));
            assert!((set.lod(id, half, 0.0, 0.0, half) - 1.5).abs() < 1e-5);
            let two = set.bilinear(id, 2, wrap, s, t);
            let mixed = set.sample(id, wrap, s, t, half, 0.0, 0.0, half);
            for c in 0..3 {
                let want = 0.5 * (one[c] + two[c]);
                assert!(
                    (mixed[c] - want).abs() < 1e-5,
                    "{wrap:?} ({s}, {t}) channel {c}: {mixed:?}"
                );
            }
            // Past the last level: the 1x1 level alone.
            let last = set.bilinear(id, 4, wrap, s, t);
            assert_eq!(set.sample(id, wrap, s, t, 1e3, 0.0, 0.0, 1e3), last);
        }
    }
}

#[test]
fn insert_checks_its_texels() {
    let mut set = TextureSet::new();
    let err = set.insert("empty", 0, 4, vec![], TEXTURE_MEMORY_LIMIT).unwrap_err();
    assert_eq!(err.path, PathBuf::from("empty"));
    assert!(err.message.contains("zero-sized"), "{err}");
    let err = set
        .insert("short", 2, 2, vec![[0.0; 3]; 3], TEXTURE_MEMORY_LIMIT)
        .unwrap_err();
    assert!(err.to_string().starts_with("texture `short`: "), "{err}");
    let err = set
        .insert("nan", 2, 1, vec![[0.0; 3], [0.0, f32::NAN, 0.0]], TEXTURE_MEMORY_LIMIT)
        .unwrap_err();
    assert!(err.message.contains("texel (1, 0)"), "{err}");
    // A 2x1 chain is 2 + 1 texels: 36 bytes fit a limit of 36, not of 35.
    let err = set.insert("tight", 2, 1, vec![[0.5; 3]; 2], 35).unwrap_err();
    assert!(err.message.contains("the limit of 35 bytes"), "{err}");
    assert_eq!(set.insert("tight", 2, 1, vec![[0.5; 3]; 2], 36), Ok(0));
    assert_eq!((set.len(), set.bytes()), (1, 36));
}

/// One PNG chunk: length, type, data, CRC-32 of type and data.
fn chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in kind.iter().chain(data) {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    let mut out = (data.len() as u32).to_be_bytes().to_vec();
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    out.extend_from_slice(&(!crc).to_be_bytes());
    out
}

#[test]
fn load_errors_name_the_file() {
    let mut set = TextureSet::new();

    let missing = temp_path("missing");
    let err = set.load(&missing, TEXTURE_MEMORY_LIMIT).unwrap_err();
    assert_eq!(err.path, missing);
    assert!(
        err.to_string()
            .starts_with(&format!("texture `{}`: ", missing.display())),
        "{err}"
    );

    let corrupt = temp_path("corrupt");
    std::fs::write(&corrupt, b"this is not a PNG file, only some text").expect("write");
    let err = set.load(&corrupt, TEXTURE_MEMORY_LIMIT).unwrap_err();
    let _ = std::fs::remove_file(&corrupt);
    assert!(err.to_string().contains(&corrupt.display().to_string()), "{err}");
    assert!(err.message.contains("not a decodable image"), "{err}");

    // Another format than PNG (a BMP header under a .bmp name).
    let bmp = std::env::temp_dir().join(format!("primflow-texture-bmp-{}.bmp", std::process::id()));
    std::fs::write(&bmp, b"BM\x3a\0\0\0\0\0\0\0\x36\0\0\0\x28\0\0\0").expect("write");
    let err = set.load(&bmp, TEXTURE_MEMORY_LIMIT).unwrap_err();
    let _ = std::fs::remove_file(&bmp);
    assert_eq!(err.path, bmp);

    // A PNG cut in half.
    let whole = temp_path("whole");
    RgbImage::from_fn(32, 32, |i, j| Rgb([(i * 8) as u8, (j * 8) as u8, (i ^ j) as u8]))
        .save(&whole)
        .expect("write the PNG");
    let bytes = std::fs::read(&whole).expect("read the PNG back");
    let _ = std::fs::remove_file(&whole);
    let truncated = temp_path("truncated");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).expect("write");
    let err = set.load(&truncated, TEXTURE_MEMORY_LIMIT).unwrap_err();
    let _ = std::fs::remove_file(&truncated);
    assert_eq!(err.path, truncated);
    assert!(err.to_string().contains(&truncated.display().to_string()), "{err}");

    // A header that declares 100000 x 100000 texels is refused from the header alone.
    let huge = temp_path("huge-header");
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = 100_000u32.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&100_000u32.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    png.extend(chunk(b"IHDR", &ihdr));
    png.extend(chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]));
    png.extend(chunk(b"IEND", &[]));
    std::fs::write(&huge, &png).expect("write");
    let err = set.load(&huge, TEXTURE_MEMORY_LIMIT).unwrap_err();
    let _ = std::fs::remove_file(&huge);
    assert_eq!(err.path, huge);
    assert!(err.message.contains("more than the limit of 256 MiB"), "{err}");
    assert_eq!((set.len(), set.bytes()), (0, 0));
}

#[test]
fn memory_limit_and_reloading() {
    let path = write_4x2("limit");
    let mut set = TextureSet::new();
    // The 4x2 chain holds 8 + 2 + 1 texels: 132 bytes.
    let err = set.load(&path, 100).unwrap_err();
    assert_eq!(err.path, path);
    assert!(err.to_string().contains(&path.display().to_string()), "{err}");
    assert!(
        err.message
            .contains("the textures would need 132 bytes, more than the limit of 100 bytes"),
        "{err}"
    );
    assert!(set.load(&path, 131).is_err());
    assert_eq!((set.len(), set.bytes()), (0, 0));

    assert_eq!(set.load(&path, 132), Ok(0));
    assert_eq!(set.bytes(), 132);
    // The same path again: the same id, nothing more held (even under a tight limit).
    assert_eq!(set.load(&path, 132), Ok(0));
    assert_eq!((set.len(), set.bytes()), (1, 132));
    // A second texture counts the first one's bytes against the limit.
    let err = set.insert("more", 1, 1, vec![[0.0; 3]], 140).unwrap_err();
    assert!(err.message.contains("would need 144 bytes"), "{err}");
    assert_eq!(set.insert("more", 1, 1, vec![[0.0; 3]], 144), Ok(1));
    let _ = std::fs::remove_file(&path);
}

#[test]
fn wrap_names_and_numbers() {
    for (k, name) in Wrap::NAMES.iter().enumerate() {
        let wrap = Wrap::from_name(name).expect("a known name");
        assert_eq!(wrap as u32, k as u32);
        assert_eq!(Wrap::from_u32(k as u32), wrap);
    }
    assert_eq!(Wrap::from_name("Clamp"), None);
    assert_eq!(Wrap::from_name("repeat"), None);
    assert_eq!(Wrap::from_u32(4), Wrap::Periodic);
    assert_eq!(Wrap::from_u32(u32::MAX), Wrap::Periodic);
}

#[test]
fn kernel_entry_matches_sample_lane_by_lane() {
    let mut set = TextureSet::new();
    let id = sixteen(&mut set);
    // Lanes: a plain lookup, a trilinear one, one outside the image, one with a NaN s.
    let s = [0.3, 0.61, -1.37, f32::NAN];
    let t = [0.7, 0.22, 2.4, 0.5];
    let dsdx = [0.0, 0.11, 0.02, 0.1];
    let dtdx = [0.0, -0.03, 0.0, 0.0];
    let dsdy = [0.0, 0.01, 0.3, 0.0];
    let dtdy = [0.0, 0.09, 0.05, 0.1];
    let args: Vec<f32> = [s, t, dsdx, dtdx, dsdy, dtdy].concat();
    for wrap in [0, 1, 2, 3, 99] {
        let mut out = [7.0f32; 12];
        unsafe { primflow_texture(&set, id, wrap, args.as_ptr(), out.as_mut_ptr()) };
        for lane in 0..4 {
            let want = set.sample(
                id,
                Wrap::from_u32(wrap),
                s[lane],
                t[lane],
                dsdx[lane],
                dtdx[lane],
                dsdy[lane],
                dtdy[lane],
            );
            let got = [out[lane], out[4 + lane], out[8 + lane]];
            assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "wrap {wrap} lane {lane}");
        }
        assert_eq!([out[3], out[7], out[11]], [0.0; 3], "the NaN lane");
        assert!(out[..3].iter().any(|&v| v > 0.0), "a real lookup: {out:?}");
    }
    // A null set and an unknown id write zeros.
    let mut out = [7.0f32; 12];
    unsafe { primflow_texture(std::ptr::null(), id, 0, args.as_ptr(), out.as_mut_ptr()) };
    assert_eq!(out, [0.0; 12]);
    let mut out = [7.0f32; 12];
    unsafe { primflow_texture(&set, id + 1, 0, args.as_ptr(), out.as_mut_ptr()) };
    assert_eq!(out, [0.0; 12]);
}
