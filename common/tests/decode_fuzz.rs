//! Property tests of the network decoders, binary and JSON ("network input never panics a
//! process"): arbitrary bytes, and valid messages with bytes flipped, cut or extended, either
//! decode to a value the validator can judge or give an error: never a panic, never an
//! unbounded allocation.
//! Inputs large enough to amplify (hundreds of thousands of empty trajectories,
//! episode lists, site vectors) are decoded under a counting allocator, and what decoding
//! allocates must stay within the budget derived from the configuration.

use dupac_common::compact::{CompactShape, CompactTrajectory, StateRow, TrunkRow};
use dupac_common::ids::ActorId;
use dupac_common::jsonmsg::{decode_json, encode_json};
use dupac_common::msg::{
    ActorRow, ActorState, ControlMsg, EpisodeSummary, Header, LearnerStats, MsgLimits, Outcome,
    StatsMsg, TrajectoryChunk, WeightsMsg, decode_msg, encode_msg,
};
use dupac_common::validate::{ChunkExpect, validate_compact};
use proptest::prelude::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::collections::BTreeMap;

/// Counts the bytes this thread holds allocated, and their peak.
struct Counting;

thread_local! {
    static HELD: Cell<usize> = const { Cell::new(0) };
    static PEAK: Cell<usize> = const { Cell::new(0) };
}

fn count(add: usize, sub: usize) {
    let _ = HELD.try_with(|h| {
        let now = h.get().saturating_add(add).saturating_sub(sub);
        h.set(now);
        let _ = PEAK.try_with(|p| p.set(p.get().max(now)));
    });
}

// SAFETY: every call forwards to the system allocator unchanged; the counters only observe.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        count(l.size(), 0);
        // SAFETY: same layout as asked.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        count(0, l.size());
        // SAFETY: `p` was allocated by `System` with `l`.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        count(new, l.size());
        // SAFETY: `p` was allocated by `System` with `l`.
        unsafe { System.realloc(p, l, new) }
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// Peak bytes allocated by `f` on this thread beyond what was held before it.
fn peak_of<R>(f: impl FnOnce() -> R) -> usize {
    let base = HELD.with(|h| h.get());
    PEAK.with(|p| p.set(base));
    let out = f();
    drop(out);
    PEAK.with(|p| p.get()) - base
}

fn valid() -> Vec<u8> {
    let mut h = Header::new("r", 7, ActorId(1), 9);
    h.policy_version = 3;
    let t = 6;
    let shape = CompactShape {
        n_sites: 3,
        path_guide: true,
        path_offset: false,
        sensor_fan: true,
        learned: true,
        lookahead: 1,
        stay: false,
        true_rsrp_every_step: false,
    };
    let mut tr = CompactTrajectory {
        moves: vec![0.1; t * 3],
        sites: vec![1; t],
        logprobs: vec![-1.0; t],
        site_logprobs: vec![-0.5; t],
        values: vec![0.5; t],
        rewards: vec![1.0; t],
        terminated: vec![false; t],
        truncated: vec![false; t],
        next_values: vec![0.5; t],
        decision_steps: vec![2; t],
        crashed: vec![false; t],
        progress_m: vec![0.5; 2 * t],
        common_reward: vec![-0.1; 2 * t],
        reward_rsrp_codes: vec![120; 3 * t],
        ..CompactTrajectory::default()
    };
    let state = StateRow {
        position_m: [1.0, 2.0, 60.0],
        rsrp: vec![100, 0, 255],
        los: vec![5],
        lookahead: vec![1, 2, 3],
        choice: 3,
        ping_pong: 3,
        ..StateRow::default()
    };
    for _ in 0..=t {
        tr.push_trunk(&shape, &TrunkRow::default());
    }
    for _ in 0..=2 * t {
        tr.push_state(&shape, &state);
    }
    assert_eq!(tr.shape_error(&shape, 2), None);
    encode_msg(&TrajectoryChunk {
        header: h,
        trajectories: vec![tr],
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
        site_steps: None,
    }
}

fn lim(bytes: usize) -> MsgLimits {
    MsgLimits {
        bytes,
        budget_bytes: bytes,
    }
}

fn judge(bytes: &[u8]) {
    if let Ok(c) = decode_msg::<TrajectoryChunk>(bytes, lim(1 << 20), "fuzz") {
        let _ = validate_compact(&c, &expect());
    }
    let _ = decode_msg::<WeightsMsg>(bytes, lim(1 << 20), "fuzz");
    let _ = decode_json::<StatsMsg>(bytes, lim(1 << 20), "fuzz");
    let _ = decode_json::<ControlMsg>(bytes, lim(1 << 20), "fuzz");
}

/// A learner's stats message (JSON) with two actor rows, drops and metrics.
fn valid_stats() -> Vec<u8> {
    let row = |id: u32| ActorRow {
        actor: ActorId(id),
        state: ActorState::Alive,
        steps_per_s: 12.5,
        env_steps: 100,
        chunks: 3,
        policy_lag: 1,
        last_seen_s: Some(0.5),
    };
    encode_json(&StatsMsg::Learner(LearnerStats {
        header: Header::new("r", 7, ActorId::LEARNER, 9),
        update: 3,
        total_updates: 10,
        global_step: 768,
        updates_per_s: 0.5,
        env_steps_per_s: 128.0,
        accepted_chunks: 6,
        drops: BTreeMap::from([("garbage".to_string(), 1)]),
        actors: vec![row(0), row(1)],
        metrics: BTreeMap::from([("charts/episodic_return".to_string(), -2.5)]),
        done: false,
    }))
    .expect("encode")
}

fn summary() -> EpisodeSummary {
    EpisodeSummary {
        pair_id: 1,
        outcome: Outcome::Goal,
        episodic_return: 1.0,
        length: 1,
        distance_flown_m: 1.0,
        shortest_m: 1.0,
        remaining_m: 0.0,
        mean_rsrp_dbm: -70.0,
        frac_excellent: 1.0,
        frac_mediocre: 0.0,
        frac_poor: 0.0,
        handovers: 0,
        ping_pongs: 0,
        mean_site_regret_db: 0.0,
        frac_site_regret_high: 0.0,
        frac_class_regret: 0.0,
    }
}

/// A chunk built to amplify: `n` trajectories, each with `sites` sites and `episodes` episode
/// summaries (varint sites are 1 byte on the wire and 4 in memory; an empty trajectory 29
/// and ≈ 730).
fn amplifying(n: usize, sites: usize, episodes: usize) -> Vec<u8> {
    let tr = CompactTrajectory {
        sites: vec![0; sites],
        episodes: vec![summary(); episodes],
        ..CompactTrajectory::default()
    };
    encode_msg(&TrajectoryChunk {
        header: Header::new("r", 7, ActorId(1), 9),
        trajectories: vec![tr; n],
    })
    .expect("encode")
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

    #[test]
    fn mutated_json_stats_never_panic(
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..8),
        cut in any::<usize>(),
        tail in proptest::collection::vec(any::<u8>(), 0..16),
    ) {
        let mut bytes = valid_stats();
        for (at, x) in flips {
            let n = bytes.len();
            bytes[at % n] ^= x;
        }
        bytes.truncate(cut % (bytes.len() + 1));
        bytes.extend_from_slice(&tail);
        judge(&bytes);
    }
}

#[test]
fn a_huge_claimed_length_is_refused_without_allocating_it() {
    // The frame of a chunk, then a header whose run-id string claims 2^60 bytes.
    let mut bytes = valid()[..12].to_vec();
    bytes.extend_from_slice(&[1, 0xff, 0, 0, 0, 0, 0, 0, 0, 0x10]);
    assert!(decode_msg::<TrajectoryChunk>(&bytes, lim(1 << 20), "fuzz").is_err());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Checked to fail with the budget's charge made a no-op (peaks of 60–110 MB for a budget
    /// of 0.2 MB).
    #[test]
    fn decoding_allocates_within_the_configured_budget(
        n in 1usize..300_000,
        sites in 0usize..64,
        episodes in 0usize..3,
        flip in any::<(usize, u8)>(),
    ) {
        let mut bytes = amplifying(n, sites, episodes);
        if flip.1 != 0 {
            let at = 12 + flip.0 % (bytes.len() - 12);
            bytes[at] ^= flip.1;
        }
        let budget = expect().budget_bytes();
        let limits = MsgLimits { bytes: 64 << 20, budget_bytes: budget };
        let peak = peak_of(|| decode_msg::<TrajectoryChunk>(&bytes, limits, "fuzz"));
        // The budget, plus the error message and bincode's bookkeeping.
        prop_assert!(peak <= budget + (64 << 10), "peak {peak} B for a budget of {budget} B, {} B input", bytes.len());
    }
}
