//! Property tests of the network decoder (issue 5's "network input never panics a process"):
//! arbitrary bytes, and valid messages with bytes flipped, cut or extended, either decode to a
//! value the validator can judge or give an error: never a panic, never an unbounded allocation
//! (serde caps preallocation at 1 MiB; the codec caps the claimed size).

use dupac_common::ActorId;
use dupac_common::msg::{
    ChunkExpect, ControlMsg, EnvTrajectory, Header, StatsMsg, TrajectoryChunk, WeightsMsg,
    decode_msg, encode_msg, validate_chunk,
};
use proptest::prelude::*;

fn valid() -> Vec<u8> {
    let mut h = Header::new("r", 7, ActorId(1), 9);
    h.policy_version = 3;
    let t = 6;
    encode_msg(&TrajectoryChunk {
        header: h,
        trajectories: vec![EnvTrajectory {
            env: 0,
            obs_dim: 4,
            obs: (0..t * 4).map(|i| i as f32 * 0.5).collect(),
            moves: vec![0.1; t * 3],
            sites: vec![1; t],
            logprobs: vec![-1.0; t],
            site_logprobs: vec![-0.5; t],
            site_rewards: vec![],
            values: vec![0.5; t],
            rewards: vec![1.0; t],
            terminated: vec![false; t],
            truncated: vec![false; t],
            next_values: vec![0.5; t],
            bootstrap_obs: vec![0.0; 4],
            episodes: vec![],
        }],
    })
    .expect("encode")
}

fn expect() -> ChunkExpect {
    ChunkExpect {
        run_id: "r".into(),
        incarnation: 7,
        fingerprint: 9,
        obs_dim: 4,
        n_sites: 3,
        max_envs: 4,
        max_steps: 16,
    }
}

fn judge(bytes: &[u8]) {
    if let Ok(c) = decode_msg::<TrajectoryChunk>(bytes, 1 << 20, "fuzz") {
        let _ = validate_chunk(&c, &expect());
    }
    let _ = decode_msg::<WeightsMsg>(bytes, 1 << 20, "fuzz");
    let _ = decode_msg::<StatsMsg>(bytes, 1 << 20, "fuzz");
    let _ = decode_msg::<ControlMsg>(bytes, 1 << 20, "fuzz");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        judge(&bytes);
    }

    #[test]
    fn arbitrary_bodies_behind_a_valid_frame_never_panic(
        body in proptest::collection::vec(any::<u8>(), 0..512)
    ) {
        let mut bytes = valid()[..12].to_vec();
        bytes.extend_from_slice(&body);
        judge(&bytes);
    }

    #[test]
    fn mutated_valid_chunks_never_panic(
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..8),
        cut in any::<usize>(),
        tail in proptest::collection::vec(any::<u8>(), 0..16),
    ) {
        let mut bytes = valid();
        for (at, x) in flips {
            let n = bytes.len();
            bytes[at % n] ^= x;
        }
        bytes.truncate(12 + cut % (bytes.len() - 11));
        bytes.extend_from_slice(&tail);
        judge(&bytes);
    }
}

#[test]
fn a_huge_claimed_length_is_refused_without_allocating_it() {
    // The frame of a chunk, then a header whose run-id string claims 2^60 bytes.
    let mut bytes = valid()[..12].to_vec();
    bytes.extend_from_slice(&[1, 0xff, 0, 0, 0, 0, 0, 0, 0, 0x10]);
    assert!(decode_msg::<TrajectoryChunk>(&bytes, 1 << 20, "fuzz").is_err());
}
