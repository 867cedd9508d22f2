//! The built-in detail textures, made here at start from tileable value noise (no image files,
//! so no licence question): one grey layer per pattern, 0.5 meaning "leave the colour as it
//! is", with a full mip chain.

/// Side of every layer at mip 0 (a power of two).
pub const SIZE: usize = 128;

/// The patterns, in layer order: plain, clay, rock, grass, sand, snow.
pub const LAYERS: [&str; 6] = ["plain", "clay", "rock", "grass", "sand", "snow"];

/// A hash of a lattice point to `[0, 1)`.
fn lattice(x: i64, y: i64, seed: u64) -> f32 {
    let mut h = (x as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ (y as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f) ^ seed;
    h ^= h >> 31;
    h = h.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h ^= h >> 29;
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Value noise of period `period` lattice cells across the texture, at texel `(x, y)`, in
/// `[0, 1)`, tiling with the texture.
fn value_noise(x: f32, y: f32, period: i64, seed: u64) -> f32 {
    let s = period as f32 / SIZE as f32;
    let (fx, fy) = (x * s, y * s);
    let (x0, y0) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - x0, fy - y0);
    let smooth = |t: f32| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (smooth(tx), smooth(ty));
    let at = |i: i64, j: i64| lattice(i.rem_euclid(period), j.rem_euclid(period), seed);
    let (i, j) = (x0 as i64, y0 as i64);
    let a = at(i, j) + (at(i + 1, j) - at(i, j)) * sx;
    let b = at(i, j + 1) + (at(i + 1, j + 1) - at(i, j + 1)) * sx;
    a + (b - a) * sy
}

/// Fractal sum of `octaves` octaves from `period`, in `[0, 1)`.
fn fbm(x: f32, y: f32, period: i64, octaves: u32, seed: u64) -> f32 {
    let (mut sum, mut amp, mut norm, mut p) = (0.0, 1.0, 0.0, period);
    for o in 0..octaves {
        sum += value_noise(x, y, p, seed.wrapping_add(o as u64 * 7919)) * amp;
        norm += amp;
        amp *= 0.5;
        p *= 2;
    }
    sum / norm
}

/// Texel `(x, y)` of pattern `layer`, in `[0, 1]`.
fn texel(layer: usize, x: f32, y: f32) -> f32 {
    let v = match layer {
        0 => 0.5,
        // Clay: fine grain and soft smears.
        1 => 0.5 + 0.22 * (fbm(x, y, 16, 4, 11) - 0.5) + 0.12 * (value_noise(x, y * 0.25, 8, 5) - 0.5),
        // Rock: ridged noise over horizontal strata.
        2 => {
            let ridge = 1.0 - (2.0 * fbm(x, y, 8, 5, 23) - 1.0).abs();
            let strata = 0.5 + 0.5 * (y / SIZE as f32 * std::f32::consts::TAU * 6.0 + 3.0 * fbm(x, y, 4, 2, 3)).sin();
            0.25 + 0.45 * ridge + 0.2 * strata
        }
        // Grass: streaks along y with clumps.
        3 => 0.35 + 0.4 * value_noise(x, y * 0.125, 32, 41) + 0.25 * (fbm(x, y, 8, 3, 43) - 0.5),
        // Sand: speckle over ripples.
        4 => {
            let ripple = 0.5 + 0.5 * (x / SIZE as f32 * std::f32::consts::TAU * 10.0 + 2.0 * fbm(x, y, 4, 2, 7)).sin();
            0.42 + 0.16 * ripple + 0.22 * (lattice(x as i64, y as i64, 59) - 0.5)
        }
        // Snow: bright, soft drifts.
        _ => 0.62 + 0.16 * (fbm(x, y, 4, 3, 67) - 0.5),
    };
    v.clamp(0.0, 1.0)
}

/// Every mip level of every layer as R8 texels: `levels[mip]` holds the layers one after the
/// other, each `(SIZE >> mip)²` texels.
pub fn detail_mips() -> Vec<Vec<u8>> {
    let mut base = vec![0.0f32; LAYERS.len() * SIZE * SIZE];
    for (l, layer) in base.chunks_mut(SIZE * SIZE).enumerate() {
        for y in 0..SIZE {
            for x in 0..SIZE {
                layer[x + SIZE * y] = texel(l, x as f32, y as f32);
            }
        }
    }
    let mut levels = Vec::new();
    let mut size = SIZE;
    let mut current = base;
    loop {
        levels.push(current.iter().map(|v| (v * 255.0 + 0.5) as u8).collect());
        if size == 1 {
            break;
        }
        let half = size / 2;
        let mut next = vec![0.0f32; LAYERS.len() * half * half];
        for l in 0..LAYERS.len() {
            let (src, dst) = (&current[l * size * size..], &mut next[l * half * half..]);
            for y in 0..half {
                for x in 0..half {
                    let s = |dx: usize, dy: usize| src[(2 * x + dx) + size * (2 * y + dy)];
                    dst[x + half * y] = (s(0, 0) + s(1, 0) + s(0, 1) + s(1, 1)) * 0.25;
                }
            }
        }
        current = next;
        size = half;
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layers_tile_are_centred_on_one_half_and_differ() {
        let mips = detail_mips();
        assert_eq!(mips.len(), SIZE.trailing_zeros() as usize + 1);
        let base = &mips[0];
        for l in 0..LAYERS.len() {
            let layer = &base[l * SIZE * SIZE..(l + 1) * SIZE * SIZE];
            let mean = layer.iter().map(|&v| v as f64).sum::<f64>() / layer.len() as f64 / 255.0;
            assert!((0.3..0.75).contains(&mean), "{}: mean {mean}", LAYERS[l]);
            // Tiling: the noise wraps, so the last column continues into the first.
            let jump: f64 =
                (0..SIZE).map(|y| (layer[SIZE * y] as f64 - layer[SIZE * y + SIZE - 1] as f64).abs()).sum::<f64>()
                    / SIZE as f64;
            assert!(jump < 40.0, "{}: seam {jump}", LAYERS[l]);
        }
        assert!(base[SIZE * SIZE..2 * SIZE * SIZE] != base[2 * SIZE * SIZE..3 * SIZE * SIZE]);
        assert_eq!(mips.last().unwrap().len(), LAYERS.len());
    }
}
