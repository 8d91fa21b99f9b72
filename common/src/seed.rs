//! Seed streams: every random stream of a run (network init, each worker's RNG, minibatch
//! shuffles) derives from `train.seed` through [`stream_seed`], so one seed reproduces a
//! one-process run whatever the thread count.

/// Seed of stream `index` in round `round` of run `seed` (SplitMix64 of the three).
pub fn stream_seed(seed: u64, index: u64, round: u64) -> u64 {
    let mut z = seed
        ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ round.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}
