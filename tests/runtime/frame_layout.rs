//! The frame's buffer layout (src/runtime/frame.rs): row strides and tile sides are whole
//! pixel groups, and planes lie a pitch apart that spreads their starts over cache sets.

use primflow::runtime::frame::{plane_pitch, row_stride, tile_side};

#[test]
fn strides_and_tile_sides_are_whole_groups() {
    assert_eq!(row_stride(64), 64);
    assert_eq!(row_stride(13), 16);
    assert_eq!(row_stride(1), 4);
    assert_eq!(row_stride(0), 0);
    assert_eq!(
        [0, 1, 4, 5, 16, 63, 4096, 5000].map(tile_side),
        [4, 4, 4, 8, 16, 64, 4096, 4096]
    );
}

/// Planes are whole lines apart, 17 lines modulo 64 (so plane `p` starts `17 p` cache
/// sets after plane 0 in any power-of-two set count up to 64 sets per 4 KiB), with
/// less than 64 lines of padding.
#[test]
fn plane_pitch_spreads_planes_over_cache_sets() {
    for len in [
        0usize,
        1,
        15,
        16,
        17,
        4096,
        64 * 64,
        500 * 500,
        512 * 512,
        520 * 517,
        16384 * 16384,
    ] {
        let pitch = plane_pitch(len);
        assert!(pitch >= len, "{len}");
        assert_eq!(pitch % 16, 0, "{len}");
        assert_eq!((pitch / 16) % 64, 17, "{len}");
        assert!(pitch - len < 64 * 16, "{len}");
        // The first 64 planes' starts fall in 64 different 4 KiB-cache sets.
        let mut sets: Vec<usize> = (0..64).map(|p| (p * pitch * 4 / 64) % 64).collect();
        sets.sort_unstable();
        sets.dedup();
        assert_eq!(sets.len(), 64, "{len}");
    }
    assert_eq!(plane_pitch(512 * 512), 512 * 512 + 17 * 16);
}
